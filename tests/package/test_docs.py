"""docs/outputs.md names every column the writers produce.

The column lists are taken from the code, not from a copy: the summary schema
(``outcomes.SUMMARY_COLUMNS``, used by summary.csv and region.parquet), the time series of a
tiny scalar reference run (``reference.timeseries_frame`` through ``simulate_scenario``), the
robustness table as ``max_acting_time`` builds it with a stand-in batch function, the keys
``report.run.open_record`` writes into report.json (plus the ones the report adds later, read
from the source) and the manifest records of a sweep folder. A name counts as documented when
it appears in docs/outputs.md in backticks.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support import REPO

from mjx_balance.measures import outcomes
from mjx_balance.model.params import CONVENTIONS, Config

OUTPUTS = REPO / "docs" / "outputs.md"
MODEL = REPO / "docs" / "model.md"


def documented() -> set[str]:
    """Every `name` in backticks in docs/outputs.md."""
    return set(re.findall(r"`([^`\n]+)`", OUTPUTS.read_text(encoding="utf-8")))


def missing(columns) -> list[str]:
    names = documented()
    return [c for c in columns if c not in names]


def standin_batch(forces, durations):
    """A stand-in for the rollout: recovered iff F * T < 5 N s, else fell (summary columns with
    integer outcome codes, as the batched runner returns them)."""
    forces = np.asarray(forces, float)
    durations = np.asarray(durations, float)
    ok = forces * durations < 5.0
    out = {c: np.zeros(forces.size) for c in outcomes.SUMMARY_COLUMNS if c != "convention"}
    out["force"], out["duration"] = forces, durations
    out["outcome"] = np.where(ok, outcomes.RECOVERED, outcomes.FELL).astype(np.int32)
    out["settle_time"] = np.where(ok, 1.0, np.nan)
    out["fall_time"] = np.where(ok, np.nan, durations)
    return out


def test_summary_columns_are_documented():
    assert missing(outcomes.SUMMARY_COLUMNS) == []


def test_table_columns_are_documented():
    from mjx_balance.runs.acting_time import TABLE_COLUMNS, max_acting_time

    config = Config().replace(scenario={"t_end": 1.0})
    result = max_acting_time([20.0, 100.0], config, run_batch=standin_batch, progress=False,
                             log=None)
    columns = list(result.table.columns)
    assert columns == list(TABLE_COLUMNS)
    assert missing(columns) == []
    # the suffixed energies of the table
    assert {"energy_total_01", "energy_total_max", "ending_outcome", "monotone",
            "evaluations"} <= set(columns)
    # the table's kept scenarios are summary rows
    assert missing(result.runs.columns) == []


def test_timeseries_columns_are_documented():
    from mjx_balance.reference import loop as reference

    config = Config().replace(scenario={"t_end": 0.05, "duration": 0.02})
    summary, frame = reference.simulate_scenario(config, 10.0, 0.02)
    assert isinstance(frame, pd.DataFrame) and len(frame) > 0
    assert list(frame.columns) == list(reference.TIMESERIES_COLUMNS)
    assert missing(frame.columns) == []
    assert missing(summary) == []


def test_report_json_keys_are_documented(tmp_path):
    from mjx_balance.studies import experiments as run

    plan = run.PLANS["tiny"]
    record = run.open_record(tmp_path, run.plan_config(Config(), plan), plan, "reference",
                             CONVENTIONS)
    keys = set(record)
    # keys the report adds to the record after it is opened (run_report, run_stage, run_study)
    source = Path(run.__file__).read_text(encoding="utf-8")
    keys |= set(re.findall(r"record\[\"(\w+)\"\]", source))
    keys |= set(re.findall(r"record\.setdefault\(\"(\w+)\"", source))
    assert {"config", "conventions", "plan", "stages", "seconds"} <= keys
    assert missing(sorted(keys)) == []
    assert missing(f.name for f in dataclasses.fields(run.Plan)) == []


def test_manifest_records_are_documented():
    from mjx_balance.store import files
    from mjx_balance.store import folder as store

    names = {key for keys in store.MANIFEST_KEYS.values() for key in keys}
    names |= set(store.MANIFEST_KEYS) | {"region.engine", "table_engine", "slots", "early_stop"}
    names |= {files.MANIFEST, files.CONFIG, files.REGION, files.TABLE, files.TABLE_RUNS,
              files.LOCK}
    assert missing(sorted(names)) == []


@pytest.mark.parametrize("doc", [OUTPUTS, MODEL])
def test_docs_link_each_other_and_the_engine(doc):
    text = doc.read_text(encoding="utf-8")
    assert "engine.md" in text or doc == OUTPUTS
    assert ("outputs.md" if doc == MODEL else "model.md") in text


def test_model_doc_cites_the_study_and_names_the_outcomes():
    text = MODEL.read_text(encoding="utf-8")
    assert "Human-like Balance Recovery Based on Numerical Model Predictive Control" in text
    for name in (*outcomes.OUTCOMES, *CONVENTIONS):
        assert f"`{name}`" in text
    for name in ("energy_ankle", "energy_hip", "work_ankle", "work_hip", "energy_u1",
                 "energy_u2"):
        assert f"`{name}`" in text


def test_readme_points_inside_the_repository():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert "../shared" not in text
    assert "docs/model.md" in text and "docs/outputs.md" in text


def test_every_test_docs_reliability_names_exists():
    """Each ``tests/PATH.py::test_name`` in docs/reliability.md (and each ``::test_name`` after
    it in the same cell, which names a test of the same file) is a test of that file."""
    named, missing = 0, []
    for line in (REPO / "docs" / "reliability.md").read_text().splitlines():
        for cell in line.split("|"):
            path = None
            for match in re.finditer(r"`(tests/[\w/]+\.py)?(?:::(\w+))?`", cell):
                path = match.group(1) or path
                if path is None:
                    continue
                source = REPO / path
                if not source.exists():
                    missing.append(path)
                elif match.group(2):
                    named += 1
                    if not re.search(rf"^def {match.group(2)}\(", source.read_text(), re.M):
                        missing.append(f"{path}::{match.group(2)}")
    assert named > 40 and not missing, missing
