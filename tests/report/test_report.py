"""The report: built on a tiny configuration through the command line; every section shows the
numbers of the saved tables, report.json records the plan and the timings, the HTML is rebuilt
from the tables alone; the study sweep definitions load and run; the study numbers and readings."""

import importlib
import dataclasses
import html
import json
import re
import shutil
import subprocess
import sys

import markupsafe
import numpy as np
import pandas as pd
import pytest
from margins import within
from support import fake_region, held_sweep
from tiny_report import ALL, SMALL, selected, tiny_report

import mjx_balance
from mjx_balance.cli import main
from mjx_balance.measures.outcomes import OUTCOMES
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.model.config_files import load_config
from mjx_balance.runs import load_sweep, parse_grid
from mjx_balance.studies import catalog as studies
from mjx_balance.runs.grid import Grid

# the subpackage (``mb.report`` is the API function)
report = importlib.import_module("mjx_balance.report")

CONVENTIONS = ("paper", "joint")


@pytest.fixture(
    scope="module",
    params=[SMALL, pytest.param(ALL, marks=pytest.mark.slow)],
    ids=["two_studies", "all_studies"],
)
def out(request, tmp_path_factory):
    """A tiny report: with two studies in the default run, with every study in the slow one
    (the same code; the other studies' sections)."""
    return tiny_report(tmp_path_factory, request.param)


def ran(out) -> list:
    """The studies the report in ``out`` ran (report.json)."""
    keys = [e["key"] for e in json.loads((out / "report.json").read_text())["studies"]]
    return [studies.study(k) for k in keys]


@pytest.fixture(scope="module")
def page(out):
    return (out / "report.html").read_text(encoding="utf-8")


def _section(page: str, key: str) -> str:
    match = re.search(rf'<section id="{re.escape(key)}">(.*?)</section>', page, re.S)
    assert match, f"no section {key}"
    return match.group(1)


def _tables(fragment: str) -> list[tuple[list[str], list[list[str]]]]:
    """(header, rows of cell texts) of every HTML table in ``fragment``."""
    tables = []
    for table in re.findall(r"<table[^>]*>(.*?)</table>", fragment, re.S):
        # a heading is the column's name and its unit in brackets, where it has one
        header = [
            re.sub(r" \[[^\]]+\]$", "", html.unescape(h))
            for h in re.findall(r"<th>(.*?)</th>", table)
        ]
        body = table.split("<tbody>", 1)[1]
        rows = [
            [html.unescape(c) for c in re.findall(r"<td>(.*?)</td>", row, re.S)]
            for row in re.findall(r"<tr>(.*?)</tr>", body, re.S)
        ]
        tables.append((header, rows))
    return tables


def _assert_shows(table: tuple[list[str], list[list[str]]], frame: pd.DataFrame) -> None:
    """The HTML table shows ``frame``: its columns, and every value to 4 significant digits."""
    header, rows = table
    assert header == list(frame.columns)
    assert len(rows) == len(frame)
    for row, (_, expected) in zip(rows, frame.iterrows()):
        for cell, column in zip(row, frame.columns):
            value = expected[column]
            if column == "note":  # long notes are footnotes: a marker [k] in the cell
                assert (
                    re.fullmatch(r"\[\d+\]", cell)
                    if isinstance(value, str) and value
                    else cell == ""
                ), (column, cell)
                continue
            # an energy of a run that did not recover is left out, its outcome shown: "– [fell]"
            marked = re.fullmatch(r"(.*) \[(?:not_settled|fell|diverged)\]", cell)
            if marked:
                assert marked.group(1) == "–", (column, cell)
                continue
            if isinstance(value, str):
                assert cell == value, column
            elif pd.isna(value):
                assert cell == "–", column
            elif cell == "0" and value != 0:
                # float noise shows as 0: under a millionth of the column's largest value
                top = np.nanmax(np.abs(frame[column].to_numpy(dtype=float)))
                assert abs(value) < top * report.html.NOISE_FRACTION, (column, value)
            else:
                within(
                    float(cell),
                    float(value),
                    rtol=1e-3,
                    msg=column,
                    why="shown to 4 significant digits: at most 5e-4 relative off",
                )


def test_report_has_every_section_and_embedded_figures(out, page):
    ids = [key for key, _ in report.sections(out)]
    expected = ["overview", "conventions"]
    for convention in CONVENTIONS:
        expected += [
            f"timeseries-{convention}",
            f"weights-{convention}",
            f"table-{convention}",
            f"region-{convention}",
        ]
    expected += [f"study-{s.key}" for s in ran(out)] + ["sensitivity"]
    assert ids[0] == "scorecard"  # the tiny report ran with a reference table: it leads
    assert sorted(ids) == sorted(expected + ["scorecard"])
    for key, heading in report.sections(out):
        assert f'<section id="{key}"><h2>{html.escape(heading)}</h2>' in page, key
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    # 11 time-series (with states and inputs), 2 weights, table, 2 region and 2 strategy
    # figures and the scorecard per convention; 1 + 2 side by side; one region map per study
    # variant; the sensitivity
    variants = sum(len(s.variants) for s in ran(out))
    assert len(images) == 2 * 19 + 3 + variants + 1
    assert all(len(b) > 1000 for b in images)
    assert "http://" not in page and "https://" not in page  # self-contained
    # a reading per study, the sensitivity's, the side by side, the scorecard's summary and
    # the strategy reading per convention
    assert page.count('class="reading"') == len(ran(out)) + 2 + 1 + 2


def test_experiment_sections_show_the_saved_tables(out, page):
    for convention in CONVENTIONS:
        folder = out / convention
        summary = pd.read_csv(folder / "summary.csv")
        (shown,) = _tables(_section(page, f"timeseries-{convention}"))
        assert [float(r[0]) for r in shown[1]] == [0, 50, 120]  # the forces of the tiny plan
        _assert_shows(shown, summary[report.html.shown_columns("summary", convention)])

        weights = pd.read_csv(folder / "weights.csv")
        text = _section(page, f"weights-{convention}")
        recovered = int((weights.outcome == "recovered").sum())
        assert f"{recovered} of 6 settings recover" in text
        shown, recovering = _tables(text)  # the study's push, then one every setting recovers
        assert [r[:2] for r in shown[1]] == [
            ["Q", "1000"],
            ["Q", "1e+05"],
            ["Q", "1e+07"],
            ["R", "0.0001"],
            ["R", "1e-06"],
            ["R", "1e-08"],
        ]
        _assert_shows(shown, weights[report.html.shown_columns("weights", convention)])

        table = pd.read_csv(folder / "table" / "table.csv")
        (shown,) = _tables(_section(page, f"table-{convention}"))
        assert [float(r[0]) for r in shown[1]] == [20, 100]
        _assert_shows(shown, table[report.html.shown_columns("table", convention)])

        region = pd.read_parquet(folder / "region" / "region.parquet")
        n = studies.region_numbers(region)
        assert n["recovered_cells"] == (region.outcome == "recovered").sum()
        assert (
            f"<p>Recovered area {n['area']:.3g} N·s ({n['fraction']:.0%} of the grid, "
            f"{n['recovered_cells']} of 6 cells)"
        ) in _section(page, f"region-{convention}")


def test_side_by_side_shows_both_conventions(out, page):
    text = _section(page, "conventions")
    tables = {c: pd.read_csv(out / c / "table" / "table.csv") for c in CONVENTIONS}
    summaries = {c: pd.read_csv(out / c / "summary.csv") for c in CONVENTIONS}
    merged = tables["paper"][["force"]].copy()
    outcomes = summaries["paper"][["force"]].copy()
    for c in CONVENTIONS:
        for column in ("max_acting_time", "energy_total_01", "energy_total_max"):
            merged[f"{column} ({c})"] = tables[c][column]
        outcomes[f"outcome ({c})"] = summaries[c]["outcome"]
        outcomes[f"energy_total ({c})"] = summaries[c]["energy_total"]
    acting, pushes = _tables(text)
    _assert_shows(acting, merged)
    _assert_shows(pushes, outcomes)
    longer = int((tables["paper"].max_acting_time > tables["joint"].max_acting_time).sum())
    assert f"the paper convention has the longer max acting time for {longer} forces" in text


def test_overview_states_the_run_and_the_key_numbers(out, page):
    text = _section(page, "overview")
    config = load_config(out / "config.toml")
    assert "plan <b>tiny</b>, batch backend <b>reference</b>" in text
    assert "recovery within t_end = 2 s" in text
    scenario = config.scenario
    assert (
        f"every angle within {scenario.settle_angle_tol:g} rad and rate within "
        f"{scenario.settle_rate_tol:g} rad/s"
    ) in text
    keys = [html.unescape(k) for k in re.findall(r"<li>([^<]*)</li>", text)]
    parts = []
    for convention in CONVENTIONS:
        table = pd.read_csv(out / convention / "table" / "table.csv")
        parts.append(
            f"{convention}: "
            + ", ".join(f"{f:g} N: {m:g} s" for f, m in zip(table.force, table.max_acting_time))
        )
    assert keys[0] == (
        "Max acting time (table forces 20, 100 N, bisected to 0.01 s within "
        "t_end = 2 s) — " + "; ".join(parts) + "."
    )
    # the tiny plan does not measure it (report.PLANS["tiny"].sustained)
    assert pd.read_csv(out / "paper" / "table" / "table.csv").sustained_push_limit.isna().all()
    limits = [f"{c}: not measured" for c in CONVENTIONS]
    assert keys[1] == (
        "Sustained-push limit (the largest force held for the whole window, to "
        "0.1 N) — " + "; ".join(limits) + "."
    )
    for key in keys[2:]:  # every key number names the grid it came from
        assert re.search(r"\(grid \d+ forces \(.* N\) x \d+ durations \(.* s\)\)", key), key
    backward = pd.read_csv(out / "studies" / "backward" / "numbers.csv")
    signed = pd.read_parquet(out / "studies" / "backward" / "signed" / "region.parquet")
    assert (
        f"Backward vs forward pushes: {backward.area[0]:.3g} vs {backward.area[1]:.3g} N·s "
        f"(grid {studies.grid_text(signed)})." in keys
    )
    delays = [k for k in keys if k.startswith("Delay changes the area by")]
    if (out / "studies" / "delay").exists():  # ALL (the slow run)
        delay = pd.read_csv(out / "studies" / "delay" / "numbers.csv")
        assert (
            f"{delay.area_change[1]:+.3g} N·s ({delay.relative_change[1]:+.0%}) at 10 ms"
            in (delays[0])
        )
    else:
        assert not delays
    links = re.findall(r'<li><a href="#([^"]+)">', text)
    assert links == [key for key, _ in report.sections(out) if key != "overview"]


def test_study_sections_show_numbers_and_readings(out, page):
    record = json.loads((out / "report.json").read_text())
    for entry in record["studies"]:
        st = studies.study(entry["key"])
        folder = out / "studies" / st.key
        numbers = pd.read_csv(folder / "numbers.csv")
        first = pd.read_parquet(folder / entry["variants"][0]["key"] / "region.parquet")
        text = _section(page, f"study-{st.key}")
        (shown,) = _tables(text)
        _assert_shows(shown, numbers[report.html.STUDY_SHOWN])
        reading = studies.reading(st, numbers, first)
        assert f'<p class="reading">{markupsafe.escape(reading)}</p>' in text
        captions = re.findall(r"<figcaption>([^<]*)</figcaption>", text)
        assert captions == [str(markupsafe.escape(v.label)) for v in st.variants]


def test_report_saves_its_tables(out):
    for convention in CONVENTIONS:
        summary = pd.read_csv(out / convention / "summary.csv")
        assert list(summary.force) == [0, 50, 120]
        assert set(summary.outcome) <= set(OUTCOMES)
        weights = pd.read_csv(out / convention / "weights.csv")
        assert list(weights.weight) == ["Q"] * 3 + ["R"] * 3
        assert (weights.force == 100).all() and (weights.duration == 0.1).all()
        table = pd.read_csv(out / convention / "table" / "table.csv")
        assert list(table.force) == [20, 100]
        region = pd.read_parquet(out / convention / "region" / "region.parquet")
        assert len(region) == 3 * 2
        assert (region.convention == convention).all()
    record = json.loads((out / "report.json").read_text())
    for entry in record["studies"]:  # every variant of every study the report ran
        keys = [v.key for v in studies.study(entry["key"]).variants]
        assert [v["key"] for v in entry["variants"]] == keys
        for key in keys:
            assert (out / "studies" / entry["key"] / key / "region.parquet").exists()
    ankle = pd.read_csv(out / "studies" / "ankle_only" / "numbers.csv")
    assert list(ankle.variant) == ["ankle_hip", "ankle_only"]
    if (out / "studies" / "delay").exists():  # ALL (the slow run)
        delay = pd.read_csv(out / "studies" / "delay" / "numbers.csv")
        assert list(delay.variant) == [
            "delay_000ms",
            "delay_010ms",
            "delay_020ms",
            "delay_050ms",
            "delay_100ms",
            "delay_150ms",
            "delay_comp_050ms",
            "delay_comp_100ms",
            "delay_comp_150ms",
        ]
    signed = pd.read_parquet(out / "studies" / "backward" / "signed" / "region.parquet")
    assert signed.force.min() < 0 < signed.force.max()


@pytest.fixture
def report_work(monkeypatch) -> dict:
    """mb.report's work and page replaced by stand-ins: what it handed the work (``progress``)
    is recorded in the dict returned; the page is ``out/report.html``, unwritten."""
    from mjx_balance import api

    seen: dict = {}

    def work(out, *args, progress=None, **kwargs):
        seen["progress"] = progress
        return {"seconds": 1.0}

    monkeypatch.setattr(api, "run_report", work)
    monkeypatch.setattr(api, "build_report", lambda out: out / "report.html")
    return seen


@pytest.mark.parametrize("quiet", [True, False])
def test_a_quiet_report_prints_its_page_alone(tmp_path, capsys, report_work, quiet):
    """``-q``, only warnings and errors: the report's work runs quiet (no numbered stages, no
    maps' lines, no bars) and the command prints the page's path alone (was: the stages on
    stdout and "tables saved in ..." on stderr whatever -q said, so a failed write at the last
    stage ended in two lines). The work and the page are stand-ins: this is the wiring."""
    out = tmp_path / "report"
    argv = ["report", "--scale", "tiny", "--studies", "none", "--out", str(out)]
    assert main((["-q"] if quiet else []) + argv) == 0
    captured = capsys.readouterr()
    assert report_work == {"progress": False if quiet else None}
    assert captured.out == f"wrote {out / 'report.html'}\n"
    assert (captured.err == "") if quiet else (f"tables saved in {out}" in captured.err)


@pytest.mark.parametrize("progress", [None, True, False])
def test_the_reports_progress_reaches_its_work_as_given(tmp_path, report_work, progress):
    """``mb.report(progress=...)`` means what it means on every API function (None where
    someone watches, True always, False never) and reaches the work as given (was: True read
    as None, the bars only on a terminal). The work and the page are stand-ins."""
    from mjx_balance import api

    api.report(out=tmp_path / "report", scale="tiny", studies="none", progress=progress, say=print)
    assert report_work == {"progress": progress}


def test_sensitivity_section_runs_every_reading_and_reuses_the_experiments_tables(out, page):
    """The report's sensitivity stage: the plan's table forces under the four readings; the
    plain readings' tables are the experiments' (copied, not recomputed: the same scenarios),
    the offset-free ones its own; the section shows sensitivity.csv."""
    folder = out / "sensitivity"
    frame = pd.read_csv(folder / "sensitivity.csv")
    assert list(frame.force) == [20.0, 100.0]  # the tiny plan's table forces
    for convention in CONVENTIONS:
        plain = pd.read_csv(folder / f"{convention}_plain" / "table.csv")
        pd.testing.assert_frame_equal(plain, pd.read_csv(out / convention / "table" / "table.csv"))
        for name in ("table.csv", "table_runs.parquet"):  # copied (times kept), not rewritten
            assert (folder / f"{convention}_plain" / name).stat().st_mtime_ns == (
                out / convention / "table" / name
            ).stat().st_mtime_ns, name
        free = pd.read_csv(folder / f"{convention}_offset_free" / "table.csv")
        assert list(free.force) == [20.0, 100.0] and free.sustained_push_limit.isna().all()
        assert list(frame[f"max_acting_time_{convention}_offset_free"]) == list(
            free.max_acting_time
        )
    (shown,) = _tables(_section(page, "sensitivity"))
    assert [row[0] for row in shown[1]] == ["20", "100"]
    within(
        [float(row[1]) for row in shown[1]],
        list(frame.max_acting_time_paper_plain),
        atol=5e-3,
        why="shown with 2 decimals: at most 5e-3 off",
    )


def test_report_json_records_plan_configuration_and_timings(out):
    record = json.loads((out / "report.json").read_text())
    assert record["version"] == mjx_balance.__version__
    assert record["plan"] == json.loads(json.dumps(dataclasses.asdict(report.PLANS["tiny"])))
    assert record["backend"] == "reference" and record["conventions"] == list(CONVENTIONS)
    assert record["config"] == load_config(out / "config.toml").to_dict()
    assert record["config"]["scenario"]["t_end"] == 2.0  # the plan's override
    stages = record["stages"]
    assert set(stages) == {
        f"{c}/{s}" for c in CONVENTIONS for s in ("timeseries", "weights", "weights_recovering")
    }
    assert stages["paper/timeseries"]["params"] == {"forces": [0, 50, 120], "duration": 0.1}
    assert stages["joint/weights"]["params"] == {
        "force": 100.0,
        "q": [1e3, 1e5, 1e7],
        "r": [1e-4, 1e-6, 1e-8],
    }
    seconds = [s["seconds"] for s in stages.values()]
    assert all(s > 0 for s in seconds)
    assert record["seconds"] >= sum(seconds)
    asked = SMALL if len(record["studies"]) < len(studies.STUDIES) else ALL
    assert [e["key"] for e in record["studies"]] == [s.key for s in selected(asked)]
    # the saved configurations of the variants are the study's
    variants = {e["key"]: e["variants"] for e in record["studies"]}
    assert variants["ankle_only"][1]["config"]["controller"]["input2_bounds"] == [0.0, 0.0]
    if asked == ALL:
        assert variants["push_height"][1]["config"]["scenario"]["push_body"] == "hip"
        assert variants["delay"][4]["config"]["scenario"]["controller_delay"] == 0.1


@pytest.mark.slow  # draws every figure of the report again
def test_html_is_rebuilt_from_saved_tables(out, page, tmp_path, capsys):
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (copy / "report.html").unlink()
    shutil.rmtree(copy / "figures")
    assert main(["report", "--out", str(copy), "--html-only"]) == 0
    assert capsys.readouterr().out == f"wrote {copy / 'report.html'}\n"
    rebuilt = (copy / "report.html").read_text(encoding="utf-8")
    no_images = re.compile(r"base64,[A-Za-z0-9+/=]+")
    assert no_images.sub("", rebuilt) == no_images.sub("", page)
    assert len(no_images.findall(rebuilt)) == len(no_images.findall(page))
    assert sorted(p.relative_to(copy) for p in (copy / "figures").rglob("*.png")) == sorted(
        p.relative_to(out) for p in (out / "figures").rglob("*.png")
    )


def test_report_command_errors(tmp_path, capsys):
    target = tmp_path / "never"
    with pytest.raises(SystemExit) as exited:  # checked when parsed, as every option's type
        main(["report", "--scale", "tiny", "--conventions", "paper,sideways", "--out", str(target)])
    assert exited.value.code == 2
    assert "--conventions: unknown sideways" in capsys.readouterr().err
    assert not target.exists()  # checked before any work
    assert main(["report", "--out", str(target), "--html-only"]) == 2
    assert "report.json not found (run the report first)" in capsys.readouterr().err


def test_report_refuses_another_configuration(out):
    with pytest.raises(ParameterError, match="another configuration"):
        report.run_report(
            out,
            Config().replace(body={"upper_mass": 40.0}),
            report.PLANS["tiny"],
            study_list=[],
            progress=False,
        )


def test_library_does_not_import_the_command_line():
    code = (
        "import sys, mjx_balance.report, mjx_balance.studies.catalog; "
        "print(sorted(m for m in sys.modules if m.startswith('mjx_balance.cli')))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


@pytest.mark.parametrize("path", studies.study_files(), ids=lambda p: p.stem)
def test_study_sweep_definition_loads_and_runs(path, tmp_path):
    definition = load_sweep(path, Config())
    forces = parse_grid(definition.forces, "forces")
    durations = parse_grid(definition.durations, "durations")
    assert forces.size >= 10 and durations.size >= 5
    config = definition.config.replace(scenario={"t_end": 0.5}, controller={"osqp_max_iter": 200})
    tiny_f, tiny_d = forces[[0, -1]], durations[:1]
    result = held_sweep(
        tmp_path,
        config,
        Grid.of(tiny_f, tiny_d, config),
        run_batch=report.ReferenceBatch(config),
        chunk=2,
        progress=False,
        say=None,
    )
    assert len(result.region) == 2 and set(result.region.outcome) <= set(OUTCOMES)
    assert result.region.outcome.iloc[0] != "diverged"


def test_every_study_variant_changes_the_base_configuration():
    base = Config()
    for st in studies.STUDIES:
        configs = [studies.variant_definition(st, v, base).config for v in st.variants]
        for v, config in zip(st.variants, configs):
            assert (config == base) == (v.file is None or st.signed), (st.key, v.key)


def test_region_area_and_reading():
    grid = {(f, d): "recovered" for f in (0.0, 10.0, 20.0) for d in (0.1, 0.2, 0.4)}
    base = fake_region(grid, energy_total=None)
    numbers = studies.region_numbers(base)
    assert numbers["area"] == pytest.approx(20 * 0.3)  # the full grid hull
    assert numbers["fraction"] == pytest.approx(1.0)
    assert numbers["t_ref"] == 0.1 and numbers["f_max_ref"] == 20.0
    weaker = dict(grid)
    weaker[(20.0, 0.4)] = weaker[(20.0, 0.2)] = "fell"
    var = fake_region(weaker, energy_total=None)
    # cell of (20, 0.4): 5 N x 0.1 s; (20, 0.2): 5 N x 0.15 s
    assert studies.region_numbers(var)["area"] == pytest.approx(6.0 - 0.5 - 0.75)
    table = studies.compare({"a": base, "b": var}, {"a": "ankle–hip (base)", "b": "ankle only"})
    assert list(table.lost_cells) == [0, 2]
    text = studies.reading(studies.study("ankle_only"), table, base)
    assert "Ankle only: 4.75 N·s, 1.25 N·s smaller (-1.25 N·s, -21%)" in text
    assert "The hip adds +1.25 N·s" in text and "2 lost" in text
    signed = fake_region(
        {**{(-f, d): o for (f, d), o in weaker.items()}, **grid}, energy_total=None
    )
    halves = studies.signed_halves(signed)
    assert list(halves.variant) == ["backward", "forward"]
    assert halves.area.tolist() == pytest.approx([4.75, 6.0])
    assert "backward pushes recover 4.75 N·s" in studies.reading(
        studies.study("backward"), halves, signed
    )


def test_cell_widths():
    np.testing.assert_allclose(studies.cell_widths([0, 1, 3]), [0.5, 1.5, 1.0])
    np.testing.assert_allclose(studies.cell_widths([5]), [1.0])


def test_tiny_report_carries_a_banner(out, page):
    match = re.search(r'<div class="banner" role="alert">(.*?)</div>', page, re.S)
    assert match, "no banner on a tiny report"
    assert "numbers are NOT meaningful" in match.group(1)
    assert page.index('class="banner"') < page.index('<section id="overview">')
    record = json.loads((out / "report.json").read_text())
    config = load_config(out / "config.toml")
    assert report.html.banner(record, config) is not None
    default = dict(record, plan=dataclasses.asdict(report.PLANS["default"]))
    assert report.html.banner(default, config) is None


def test_page_is_rendered_from_the_template_with_autoescaping(out):
    sections_ = [
        {
            "id": "overview",
            "heading": "A <b>heading</b>",
            "blocks": [
                {"kind": "paragraph", "text": "x < y & <script>", "cls": ""},
                report.html._table(
                    pd.DataFrame({"a<": ["<i>"], "note": ["n"]}), note_column="note"
                ),
            ],
        }
    ]
    text = report.html.page_html(sections_, "banner <b>")
    assert "<script>" not in text and "&lt;script&gt;" in text
    assert "A &lt;b&gt;heading&lt;/b&gt;" in text and "banner &lt;b&gt;" in text
    assert "<th>a&lt;</th>" in text and "<td>&lt;i&gt;</td>" in text
    assert '<ol class="notes"><li>n</li></ol>' in text and "<td>[1]</td>" in text


def test_energies_in_report_tables_carry_their_outcome(out, page):
    for convention in CONVENTIONS:
        tables = _tables(_section(page, f"weights-{convention}"))
        for (header, rows), name in zip(tables, ("weights.csv", "weights_recovering.csv")):
            weights = pd.read_csv(out / convention / name)
            column = header.index("energy_total")
            for row, (_, expected) in zip(rows, weights.iterrows()):
                # a run that did not recover shows its outcome, never its energy
                fell = expected.outcome != "recovered"
                assert (row[column] == f"– [{expected.outcome}]") == fell, row


def test_infeasibility_numbers_count_falls_after_an_infeasible_qp():
    """Three falls, two after an infeasible QP (30 and 50 ms before); a recovered run with an
    infeasible QP and a fall without one are not counted as preceded."""
    from mjx_balance.studies import catalog as studies

    region = pd.DataFrame(
        {
            "outcome": ["fell", "fell", "fell", "recovered"],
            "fall_time": [1.0, 2.0, 0.5, np.nan],
            "first_infeasible_time": [0.97, 1.95, np.nan, 0.3],
        }
    )
    n = studies.infeasibility_numbers(region)
    assert (n["falls"], n["preceded"]) == (3, 2)
    assert n["lead_min"] == pytest.approx(0.03) and n["lead_max"] == pytest.approx(0.05)
    assert "2 of 3 falls" in studies.infeasibility_text(region)
    assert "predates" in studies.infeasibility_text(region.drop(columns="first_infeasible_time"))


def test_scorecard_section_leads_and_carries_the_reasons(out, page):
    text = _section(page, "scorecard")
    card = pd.read_csv(out / "scorecard.csv", keep_default_na=False)
    assert set(card["convention"]) == set(CONVENTIONS)
    assert (out / "references" / "made_up_reference.csv").exists()
    for convention in CONVENTIONS:
        for source in ("made_up_reference", "study"):
            mine = card[(card["convention"] == convention) & (card["source"] == source)]
            if source == "study" and convention != "paper":
                assert mine.empty  # the study's table is scored in its own convention only
                continue
            assert len(mine)
            agree = int((mine["status"] == "agrees").sum())
            compared = int(mine["status"].isin(["agrees", "differs"]).sum())
            assert f"{convention} convention, {source}: {agree} of {compared}" in text
    # the study's Table 2 is scored without being asked, and only where our table has the
    # force (the tiny plan's 20 and 100 N; the others are "not computed")
    assert not (out / "references" / "study.csv").exists()
    study = card[card["source"] == "study"]
    assert set(study.loc[~study["status"].str.startswith("not computed"), "force"]) == {20, 100}
    # a differing row shows the file's reason, or points to the measured causes: never made up
    for row in card[card["status"] == "differs"].itertuples():
        assert (row.reason or "no reason in the reference file") in html.unescape(text)
    assert page.index('id="scorecard"') < page.index('id="overview"')


def test_table_headings_carry_units_and_noise_shows_as_zero():
    from mjx_balance.report.html import _table

    frame = pd.DataFrame(
        {
            "force": [0.0, 50.0],
            "outcome": ["recovered", "recovered"],
            "fraction": [0.5, 0.25],
            "energy_total": [1.6e-11, 0.31],
            "max_acting_time": [0.35, 5e-7],
        }
    )
    block = _table(frame)
    assert block["header"] == [
        "force [N]",
        "outcome",
        "fraction",
        "energy_total [J]",
        "max_acting_time [s]",
    ]
    # 1.6e-11 J beside 0.31 J is under a millionth of the column: float noise, shown as 0;
    # 5e-7 s beside 0.35 s is above it (3.5e-7) and shown
    assert [row[3] for row in block["rows"]] == ["0", "0.31"]
    assert [row[4] for row in block["rows"]] == ["0.35", "5e-07"]
