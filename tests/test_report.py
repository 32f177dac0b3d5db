"""The report: built on a tiny configuration, every section present, figures embedded, tables
saved; the study sweep definitions load and run; the study numbers and readings."""

import json
import re

import numpy as np
import pandas as pd
import pytest

from mjx_balance import report, studies
from mjx_balance.metrics import OUTCOMES
from mjx_balance.params import Config
from mjx_balance.sweep import load_sweep, parse_grid, run_sweep

from tiny_report import tiny_report


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tiny_report(tmp_path_factory)


def test_report_has_every_section_and_embedded_figures(out):
    page = (out / "report.html").read_text(encoding="utf-8")
    ids = [key for key, _ in report.sections(out)]
    expected = ["overview", "conventions"]
    for convention in ("paper", "joint"):
        expected += [f"timeseries-{convention}", f"weights-{convention}", f"table-{convention}",
                     f"region-{convention}"]
    expected += [f"study-{s.key}" for s in studies.STUDIES]
    assert sorted(ids) == sorted(expected)
    for key, heading in report.sections(out):
        assert f'<section id="{key}"><h2>' in page, key
        assert heading.replace("&", "&amp;") in page or heading in page
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    # 9 time-series, weights, table, 2 region figures per convention; 1 + 2 side by side;
    # one region map per study variant
    variants = sum(len(s.variants) for s in studies.STUDIES)
    assert len(images) == 2 * 13 + 3 + variants
    assert all(len(b) > 1000 for b in images)
    assert "http://" not in page and "https://" not in page  # self-contained
    assert page.count('class="reading"') == len(studies.STUDIES) + 1


def test_report_saves_its_tables(out):
    record = json.loads((out / "report.json").read_text())
    assert record["plan"]["name"] == "tiny" and record["backend"] == "reference"
    for convention in ("paper", "joint"):
        summary = pd.read_csv(out / convention / "summary.csv")
        assert list(summary.force) == [0, 50, 120]
        assert set(summary.outcome) <= set(OUTCOMES)
        weights = pd.read_csv(out / convention / "weights.csv")
        assert list(weights.weight) == ["Q"] * 3 + ["R"] * 3
        table = pd.read_csv(out / convention / "table" / "table.csv")
        assert list(table.force) == [20, 100]
        region = pd.read_parquet(out / convention / "region" / "region.parquet")
        assert len(region) == 3 * 2
        assert (region.convention == convention).all()
    delay = pd.read_csv(out / "studies" / "delay" / "numbers.csv")
    assert list(delay.variant) == ["delay_000ms", "delay_010ms", "delay_020ms", "delay_050ms",
                                   "delay_100ms", "delay_150ms"]
    signed = pd.read_parquet(out / "studies" / "backward" / "signed" / "region.parquet")
    assert signed.force.min() < 0 < signed.force.max()
    # the saved configurations of the variants are the study's
    variants = {e["key"]: e["variants"] for e in record["studies"]}
    assert variants["delay"][4]["config"]["scenario"]["controller_delay"] == 0.1
    assert variants["push_height"][1]["config"]["scenario"]["push_body"] == "hip"
    assert variants["ankle_only"][1]["config"]["controller"]["input2_bounds"] == [0.0, 0.0]


def test_html_is_rebuilt_from_saved_tables(out, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "report.html").unlink()
    shutil.rmtree(copy / "figures")
    from mjx_balance.cli import main

    assert main(["report", "--out", str(copy), "--html-only"]) == 0
    assert (copy / "report.html").stat().st_size > 100_000


def test_report_refuses_another_configuration(out):
    from mjx_balance.params import ParameterError

    with pytest.raises(ParameterError, match="another configuration"):
        report.run_report(out, Config().replace(body={"upper_mass": 40.0}), report.PLANS["tiny"],
                          study_list=[], quiet=True)


@pytest.mark.parametrize("path", studies.study_files(), ids=lambda p: p.stem)
def test_study_sweep_definition_loads_and_runs(path, tmp_path):
    definition = load_sweep(path, Config())
    forces = parse_grid(definition.forces, "forces")
    durations = parse_grid(definition.durations, "durations")
    assert forces.size >= 10 and durations.size >= 5
    config = definition.config.replace(scenario={"t_end": 0.5},
                                       controller={"osqp_max_iter": 200})
    tiny_f, tiny_d = forces[[0, -1]], durations[:1]
    result = run_sweep(tmp_path, config, tiny_f, tiny_d, run_batch=report.ReferenceBatch(config),
                       chunk_size=2, progress=False, log=None)
    assert len(result.region) == 2 and set(result.region.outcome) <= set(OUTCOMES)
    assert result.region.outcome.iloc[0] != "diverged"


def test_every_study_variant_changes_the_base_configuration():
    base = Config()
    for st in studies.STUDIES:
        configs = [studies.variant_definition(st, v, base).config for v in st.variants]
        for v, config in zip(st.variants, configs):
            assert (config == base) == (v.file is None or st.signed), (st.key, v.key)


def _region(cells):
    rows = [{"force": f, "duration": d, "outcome": o, "convention": "paper"}
            for (f, d), o in cells.items()]
    return pd.DataFrame(rows)


def test_region_area_and_reading():
    grid = {(f, d): "recovered" for f in (0.0, 10.0, 20.0) for d in (0.1, 0.2, 0.4)}
    base = _region(grid)
    numbers = studies.region_numbers(base)
    assert numbers["area"] == pytest.approx(20 * 0.3)  # the full grid hull
    assert numbers["fraction"] == pytest.approx(1.0)
    assert numbers["t_ref"] == 0.1 and numbers["f_max_ref"] == 20.0
    weaker = dict(grid)
    weaker[(20.0, 0.4)] = weaker[(20.0, 0.2)] = "fell"
    var = _region(weaker)
    # cell of (20, 0.4): 5 N x 0.1 s; (20, 0.2): 5 N x 0.15 s
    assert studies.region_numbers(var)["area"] == pytest.approx(6.0 - 0.5 - 0.75)
    table = studies.compare({"a": base, "b": var}, {"a": "ankle–hip (base)", "b": "ankle only"})
    assert list(table.lost_cells) == [0, 2]
    text = studies.reading(studies.study("ankle_only"), table, base)
    assert "Ankle only: 4.75 N·s, 1.25 N·s smaller (-1.25 N·s, -21%)" in text
    assert "The hip adds +1.25 N·s" in text and "2 lost" in text
    signed = _region({**{(-f, d): o for (f, d), o in weaker.items()}, **grid})
    halves = studies.signed_halves(signed)
    assert list(halves.variant) == ["backward", "forward"]
    assert halves.area.tolist() == pytest.approx([4.75, 6.0])
    assert "backward pushes recover 4.75 N·s" in studies.reading(studies.study("backward"),
                                                                 halves, signed)


def test_cell_widths():
    np.testing.assert_allclose(studies.cell_widths([0, 1, 3]), [0.5, 1.5, 1.0])
    np.testing.assert_allclose(studies.cell_widths([5]), [1.0])
