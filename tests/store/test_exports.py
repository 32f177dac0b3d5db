"""Exports: every table also as CSV or parquet (``--format``, ``format=``),
every column's unit in one registry (``measures/units.py``) written into the parquet schema
and a CSV's ``NAME.units.csv``, CSVs in full precision, and grid values exact at the parser.

The commands run with the stand-in batch function of tests/support.py (nothing compiles);
``simulate`` runs the real scalar reference over a 0.5-s window (as tests/cli/test_cli_simulate.py)
and the basin a stand-in engine (its columns are the runner's stream's, listed in the fake)."""

import json
import re
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from support import DEFAULT_BATCH, REPO, FakeThresholdBatch

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.measures import units
from mjx_balance.measures.outcomes import SUMMARY_COLUMNS
from mjx_balance.runs.grid import parse_grid
from mjx_balance.store.files import UNITS_KEY, units_path

GRID = ["--forces", "0:40:10", "--durations", "0.1,0.3,0.7"]


def stand_in_fake(config):
    """The stand-in of a convention (conftest's ``stand_in`` makes one per configuration)."""
    return FakeThresholdBatch(c=30.0 if config.controller.convention == "paper" else 60.0)


class FakeBasinRunner:
    """FAKE ``rollout.runner.BatchRunner`` for the basin: ``stream`` yields what the real one
    yields (force, duration, the summary columns with integer codes, periods, certified)."""

    def __init__(self, config, **_options):
        self.config = config

    def stream(self, forces, durations, inits=None):
        out = FakeThresholdBatch()(np.asarray(forces), np.asarray(durations))
        out["fall_cause"] = np.zeros(len(forces), np.int32)
        out["periods"] = np.full(len(forces), 10)
        out["certified"] = np.ones(len(forces), bool)
        yield np.arange(len(forces)), out


def tables(folder: Path) -> list[Path]:
    """Every table under ``folder``: CSV and parquet files (chunks and parts too), not the
    units sidecars."""
    return sorted(
        p
        for p in folder.rglob("*")
        if p.suffix in (".csv", ".parquet") and not p.name.endswith(".units.csv")
    )


def columns(path: Path) -> list[str]:
    return (
        pq.read_schema(path).names
        if path.suffix == ".parquet"
        else list(pd.read_csv(path, nrows=0).columns)
    )


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """Every command that writes tables, run once with --format both into one tree."""
    root = tmp_path_factory.mktemp("exports")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(DEFAULT_BATCH, lambda config, **_e: stand_in_fake(config))
        mp.setattr("mjx_balance.studies.basin.BatchRunner", FakeBasinRunner)
        ref = root / "ref.csv"
        ref.write_text("force,max_acting_time,energy_total_01\n10,2.9,0.3\n20,1.4,0.6\n")
        sweep = root / "sweep"
        assert main(["sweep", *GRID, "--chunk", "8", "--format", "both", "--out", str(sweep)]) == 0
        assert (
            main(
                [
                    "table",
                    "--forces",
                    "10,20",
                    "--reference",
                    str(ref),
                    "--format",
                    "both",
                    "--out",
                    str(sweep),
                ]
            )
            == 0
        )
        (root / "a.toml").write_text('[controller]\nconvention = "paper"\n')
        (root / "b.toml").write_text('[controller]\nconvention = "joint"\n')
        assert (
            main(
                [
                    "compare",
                    str(root / "a.toml"),
                    str(root / "b.toml"),
                    *GRID,
                    "--table-forces",
                    "10,20",
                    "--format",
                    "both",
                    "--out",
                    str(root / "compare"),
                ]
            )
            == 0
        )
        assert (
            main(
                [
                    "landscape",
                    "--q-scales",
                    "1,10",
                    "--r-scales",
                    "1",
                    "--delays",
                    "0",
                    *GRID,
                    "--table-forces",
                    "10",
                    "--format",
                    "both",
                    "--out",
                    str(root / "landscape"),
                ]
            )
            == 0
        )
        assert (
            main(
                [
                    "sensitivity",
                    "--forces",
                    "10,20",
                    "--readings",
                    "paper_plain,joint_plain",
                    "--out",
                    str(root / "sensitivity"),
                ]
            )
            == 0
        )
        assert (
            main(
                [
                    "basin",
                    "--x-com=-0.02,0,0.02",
                    "--v-com",
                    "0,0.1",
                    "--push-forces",
                    "none",
                    "--format",
                    "both",
                    "--out",
                    str(root / "basin"),
                ]
            )
            == 0
        )
        short = root / "short.toml"
        short.write_text("[scenario]\nt_end = 0.5\n")
        assert (
            main(
                [
                    "simulate",
                    "--forces",
                    "0,30",
                    "--durations",
                    "0.1",
                    "--config",
                    str(short),
                    "--format",
                    "both",
                    "--out",
                    str(root / "simulate"),
                ]
            )
            == 0
        )
    return root


def test_every_column_of_every_table_has_a_unit(written):
    found = tables(written)
    names = {p.name for p in found}
    for name in (
        "region.parquet",
        "region.csv",
        "table.csv",
        "table.parquet",
        "table_runs.parquet",
        "table_runs.csv",
        "scorecard.csv",
        "compare.csv",
        "landscape.csv",
        "sensitivity.csv",
        "basin.parquet",
        "basin.csv",
        "summary.csv",
        "summary.parquet",
        "timeseries.parquet",
        "timeseries.csv",
    ):
        assert name in names, name
    missing = {
        str(p.relative_to(written)): units.unknown(columns(p)) for p in found if p.name != "ref.csv"
    }
    assert not {k: v for k, v in missing.items() if v}, (
        "columns without a unit in measures/units.py"
    )


def test_the_registry_fails_on_a_new_column():
    assert units.unknown(
        ["force", "max_acting_time_12.5N", "energy_study_01_paper_plain", "a_new_column"]
    ) == ["a_new_column"]
    with pytest.raises(KeyError, match="a_new_column"):
        units.unit("a_new_column")


def test_parquet_files_carry_their_units(written):
    for path in (
        written / "sweep" / "region.parquet",
        written / "simulate" / "timeseries.parquet",
        written / "sweep" / "table.parquet",
        next((written / "sweep" / "chunks").glob("*.parquet")),
    ):
        schema = pq.read_schema(path)
        table_units = json.loads(schema.metadata[UNITS_KEY])
        for field in schema:
            assert field.metadata[b"unit"].decode() == units.unit(field.name), (path, field)
            assert table_units[field.name] == units.unit(field.name)
    schema = pq.read_schema(written / "sweep" / "region.parquet")
    assert schema.field("force").metadata[b"unit"] == b"N"
    assert schema.field("energy_total").metadata[b"unit"] == b"J"


def test_every_csv_has_its_units_beside_it(written):
    for path in tables(written):
        if path.suffix != ".csv" or path.name == "ref.csv":
            continue
        sidecar = pd.read_csv(units_path(path), keep_default_na=False)
        assert list(sidecar.columns) == ["column", "unit", "description"]
        assert list(sidecar["column"]) == columns(path), path
        assert list(sidecar["unit"]) == [units.unit(c) for c in columns(path)], path


def _same_bits(a: pd.Series, b: pd.Series) -> bool:
    a, b = a.to_numpy(np.float64), b.to_numpy(np.float64)
    return bool(
        np.array_equal(np.isnan(a), np.isnan(b))
        and np.array_equal(a[~np.isnan(a)].view(np.int64), b[~np.isnan(b)].view(np.int64))
    )


@pytest.mark.parametrize(
    "folder,name",
    [("sweep", "region"), ("simulate", "timeseries"), ("sweep", "table_runs"), ("basin", "basin")],
)
def test_a_csv_reads_back_to_the_parquet_bit_for_bit(written, folder, name):
    parquet = pd.read_parquet(written / folder / f"{name}.parquet")
    csv = pd.read_csv(written / folder / f"{name}.csv")
    assert list(csv.columns) == list(parquet.columns)
    floats = [c for c in parquet if parquet[c].dtype.kind == "f"]
    assert floats
    for column in floats:
        # a float32 column (the stand-in's force and duration) is written as its shortest
        # float32 text: compared at that width
        width = parquet[column].dtype
        assert _same_bits(csv[column].astype(width), parquet[column]), column
    if name == "timeseries":  # real float64 physics, not round numbers
        assert any(len(repr(v)) > 15 for v in parquet["com"])


def test_default_format_writes_no_copies_but_every_csv_gets_its_units(tmp_path, stand_in):
    out = tmp_path / "plain"
    assert main(["sweep", *GRID, "--out", str(out)]) == 0
    assert main(["table", "--forces", "10", "--out", str(out)]) == 0
    assert not (out / "region.csv").exists() and not (out / "table.parquet").exists()
    assert (out / "table.units.csv").exists()
    assert main(["sweep", *GRID, "--format", "csv", "--out", str(out)]) == 0  # a finished folder
    assert (out / "region.csv").exists() and (out / "table_runs.csv").exists()
    assert not (out / "table.parquet").exists()
    with pytest.raises(SystemExit) as exit_:
        main(["sweep", *GRID, "--format", "xlsx", "--out", str(out)])
    assert exit_.value.code == 2


def test_the_api_takes_format(tmp_path, stand_in):
    with pytest.raises(ValueError, match="'xlsx'"):
        mb.table("10", out=tmp_path / "bad", format="xlsx")
    assert not (tmp_path / "bad").exists() and not stand_in  # refused before any work
    mb.table("10", out=tmp_path / "t", format="parquet")
    assert (tmp_path / "t" / "table.parquet").exists()
    assert not (tmp_path / "t" / "table_runs.csv").exists()
    frame = mb.sweep("0:40:10", "0.1,0.3", out=tmp_path / "s", format="csv")
    back = pd.read_csv(tmp_path / "s" / "region.csv")
    width = frame["energy_total"].dtype  # the stand-in's float32, written as float32 text
    assert _same_bits(back["energy_total"].astype(width), frame["energy_total"])


def _strip_units(path: Path) -> None:
    """Rewrite a parquet file as one written before units: no field or table metadata."""
    table = pq.read_table(path)
    meta = {k: v for k, v in table.schema.metadata.items() if k != UNITS_KEY}
    schema = pa.schema([f.remove_metadata() for f in table.schema], metadata=meta)
    pq.write_table(table.cast(schema), path)
    assert UNITS_KEY not in pq.read_schema(path).metadata


def test_chunks_from_before_units_resume_and_merge_unchanged(tmp_path, stand_in):
    out = tmp_path / "old"
    assert main(["sweep", *GRID, "--chunk", "4", "--out", str(out)]) == 0
    before = pd.read_parquet(out / "region.parquet")
    chunks = sorted((out / "chunks").glob("*.parquet"))
    assert len(chunks) == 4
    for chunk in chunks[::2]:  # old and new chunks side by side
        _strip_units(chunk)
    (out / "region.parquet").unlink()
    calls = sum(len(f.calls) for f in stand_in)
    assert main(["sweep", *GRID, "--chunk", "4", "--out", str(out)]) == 0
    assert sum(len(f.calls) for f in stand_in) == calls  # no chunk computed again
    pd.testing.assert_frame_equal(pd.read_parquet(out / "region.parquet"), before)
    assert pq.read_schema(out / "region.parquet").field("force").metadata[b"unit"] == b"N"


# -- grid values exact at the parser ---------------------------------------------------------


@pytest.mark.parametrize(
    "text",
    [
        "0.05:1.5:0.05",
        "0.002:1.5:0.002",
        "-100:100:0.1",
        "0:300:2.5",
        "1e-3:2e-2:1e-3",
        "1e-15:1e-14:1e-15",
        "123456789.123456:123456789.2:0.000001",
    ],
)
def test_a_range_gives_the_decimal_values_as_written(text):
    start, stop, step = (Decimal(p) for p in text.split(":"))
    values = parse_grid(text)
    expected = [float(start + k * step) for k in range(len(values))]
    assert values.tolist() == expected
    assert expected[-1] <= float(stop) and float(start + len(values) * step) > float(stop)
    decimals = max(0, -start.as_tuple().exponent, -step.as_tuple().exponent)
    # each value prints with no more digits than the text's decimals (no 0.30000000000000004)
    for value in values:
        digits = re.sub(r"e[-+]\d+$", "", repr(float(value))).lstrip("-").replace(".", "")
        assert len(digits.lstrip("0")) <= len(str(int(abs(value)))) + decimals + 1, value


def test_point_three_is_point_three():
    assert 0.3 in parse_grid("0.05:1.5:0.05").tolist()
    assert parse_grid("0.1:0.3:0.1").tolist() == [0.1, 0.2, 0.3]


# -- docs ------------------------------------------------------------------------------------


def test_the_units_table_in_the_docs_is_the_registry():
    text = (REPO / "docs" / "outputs.md").read_text()
    section = text.split("## Units and exports")[1].split("\n## ")[0]
    rows = re.findall(r"^\| `([^`]+)` \| ([^|]*) \|", section, flags=re.M)
    documented = {name: unit.strip() for name, unit in rows}
    shown = {"(label)": ""}
    registry = {name: shown.get(unit, unit) for name, (unit, _) in units.UNITS.items()}
    registry.update(
        {
            "max_acting_time_<F>N": "s",
            "max_acting_time_<reading>": "s",
            "energy_study_<reading>": "J",
            "energy_motors_<reading>": "J",
            "energy_study_01_<reading>": "J",
            "energy_motors_01_<reading>": "J",
            "energy_<definition>_min": "J",
            "energy_<definition>_max": "J",
        }
    )
    documented = {k: ("" if v == "–" else v) for k, v in documented.items()}
    assert documented == registry
    for name in documented:  # every documented pattern is one the registry matches
        example = (
            name.replace("<F>", "50")
            .replace("<reading>", "paper_plain")
            .replace("<definition>", "study")
        )
        assert units.describe(example) is not None, name


def test_the_declared_columns_are_in_the_registry():
    from mjx_balance.reference.loop import TIMESERIES_COLUMNS
    from mjx_balance.runs.acting_time import TABLE_COLUMNS
    from mjx_balance.studies.landscape import COLUMNS
    from mjx_balance.studies.scorecard import SCORECARD_COLUMNS

    for declared in (
        SUMMARY_COLUMNS,
        TIMESERIES_COLUMNS,
        TABLE_COLUMNS,
        COLUMNS,
        SCORECARD_COLUMNS,
    ):
        assert units.unknown(declared) == []
    assert units.unit("outcome") == "" and units.unit("energy_total") == "J"


def test_the_docs_pandas_lines_run(written):
    text = (REPO / "docs" / "outputs.md").read_text()
    section = text.split("## Units and exports")[1].split("\n## ")[0]
    code = section.split("```python\n")[1].split("```")[0]
    scope: dict = {}
    exec(code.replace('"out/', f'"{written / "sweep"}/'), scope)
    assert scope["units"]["force"] == "N" and len(scope["region"]) == 15


def test_a_copy_never_disagrees_with_its_table(tmp_path, stand_in):
    """A --format copy left by an earlier run is written again when a later run (any format)
    rewrites its table: the parquet copy holds the new forces, as the CSV does."""
    out = tmp_path / "t"
    assert main(["-q", "table", "--forces", "20", "--format", "parquet", "--out", str(out)]) == 0
    assert pd.read_parquet(out / "table.parquet")["force"].tolist() == [20]
    assert main(["-q", "table", "--forces", "20,50", "--out", str(out)]) == 0
    assert pd.read_csv(out / "table.csv")["force"].tolist() == [20, 50]
    assert pd.read_parquet(out / "table.parquet")["force"].tolist() == [20, 50]
    mb.table("20,50,80", out=out)  # the API alike
    assert pd.read_parquet(out / "table.parquet")["force"].tolist() == [20, 50, 80]
