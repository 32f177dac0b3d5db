"""The sensitivity of the reproduction table to the reading of the study (sensitivity.py),
with stand-in batch functions (tests/test_sweep.py's FakeThresholdBatch: recovered iff
F T < c), so the spread and the conclusions are known in closed form."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mjx_balance import sensitivity
from mjx_balance.cli import main
from mjx_balance.params import Config, ParameterError
from test_sweep import DEFAULT_BATCH, FakeThresholdBatch, expected_max_time

# the stand-in's threshold c [N s] per reading: recovered iff F T < c
# (no F T = c on the 0.01-s grid of the bisection, where the fake's rounding would decide)
C = {("paper", False): 30.7, ("joint", False): 20.3, ("paper", True): 45.3,
     ("joint", True): 40.7}
KEY_C = {"paper_plain": 30.7, "joint_plain": 20.3, "paper_offset_free": 45.3,
         "joint_offset_free": 40.7}
FORCES = "20,50,80"


@pytest.fixture
def stand_in(monkeypatch):
    made = []

    def make(config, **_engine):
        c = C[(config.controller.convention, config.controller.offset_free)]
        made.append(FakeThresholdBatch(c=c))
        return made[-1]
    monkeypatch.setattr(DEFAULT_BATCH, make)
    return made


def test_the_spread_and_what_holds(tmp_path, stand_in):
    out = tmp_path / "out"
    base = Config().replace(scenario={"t_end": 12.0})
    frame = sensitivity.run_sensitivity(out, base, FORCES, say=lambda s: None)
    assert list(frame.force) == [20.0, 50.0, 80.0]
    for key, c in KEY_C.items():
        expected = [expected_max_time(f, c, 12.0) for f in (20, 50, 80)]
        assert list(frame[f"max_acting_time_{key}"]) == expected, key
    times = frame[[f"max_acting_time_{k}" for k in KEY_C]].to_numpy()
    np.testing.assert_array_equal(frame.max_acting_time_min, times.min(axis=1))
    np.testing.assert_array_equal(frame.max_acting_time_max, times.max(axis=1))
    np.testing.assert_allclose(frame.max_acting_time_ratio, times.max(axis=1) / times.min(axis=1))
    for name in ("study", "motors"):
        energies = frame[[f"energy_{name}_{k}" for k in KEY_C]].to_numpy()
        np.testing.assert_array_equal(frame[f"energy_{name}_max"], energies.max(axis=1))
    text = (out / sensitivity.SENSITIVITY_TXT).read_text()
    # F T < c: the max acting time falls with F under every reading, and the offset-free
    # stand-ins (larger c) hold pushes longer in both conventions
    every = text.split("Under every reading: ")[1].split("Depending on the reading")[0]
    assert "the max acting time falls" in every
    assert "offset-free MPC's max acting time is at least" in every
    assert (out / sensitivity.SENSITIVITY_PNG).stat().st_size > 10_000
    for key in KEY_C:
        assert (out / key / "table.csv").exists()
    # resumable: a rerun calls no batch function
    calls = sum(len(f.calls) for f in stand_in)
    again = sensitivity.run_sensitivity(out, base, FORCES, say=lambda s: None)
    assert sum(len(f.calls) for f in stand_in) == calls
    pd.testing.assert_frame_equal(again, frame)


def test_a_conclusion_that_depends_on_the_reading_is_named():
    """An offset-free reading shorter than its plain one at some force: the conclusion is
    reported as holding only where it does."""
    frame = pd.DataFrame({"force": [20.0, 50.0],
                          "max_acting_time_paper_plain": [1.0, 0.5],
                          "max_acting_time_paper_offset_free": [2.0, 0.4],
                          "energy_study_paper_plain": [1.0, 2.0],
                          "energy_study_paper_offset_free": [1.0, 0.5],
                          "energy_motors_paper_plain": [1.0, 2.0],
                          "energy_motors_paper_offset_free": [1.0, 3.0]})
    found = dict(sensitivity.conclusions(frame, ["paper_plain", "paper_offset_free"]))
    assert found["the max acting time falls (or stays) as the force grows"] == [
        "paper_plain", "paper_offset_free"]
    assert found["the study's energy (eq. 20) of the longest recovered push rises with the "
                 "force"] == ["paper_plain"]
    assert found["the offset-free MPC's max acting time is at least the plain MPC's at every "
                 "force (same convention)"] == []


def test_bad_input_is_refused_before_any_work(tmp_path, stand_in):
    with pytest.raises(ParameterError, match="unknown reading"):
        sensitivity.run_sensitivity(tmp_path / "x", Config(), FORCES, readings=["paper_bent"])
    assert main(["sensitivity", "--readings", "paper_plain,nope", "--out",
                 str(tmp_path / "y")]) == 2
    assert main(["sensitivity", "--forces", "a,b", "--out", str(tmp_path / "z")]) == 2
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
    assert not (tmp_path / "z").exists()
    assert not stand_in  # no batch function was even made


def test_the_report_shows_a_sensitivity_folder_inside_it(tmp_path, stand_in):
    """report/extra.py: DIR/sensitivity's results become a section (the numbers of
    sensitivity.csv, the figure, the reading); without the folder there is none."""
    from mjx_balance.report.extra import extra_sections

    report = tmp_path / "report"
    assert extra_sections(report) == []
    frame = sensitivity.run_sensitivity(report / "sensitivity", Config(), FORCES,
                                        say=lambda s: None)
    (section,) = extra_sections(report)
    assert section["id"] == "sensitivity"
    table = next(b for b in section["blocks"] if b["kind"] == "table")
    assert [row[0] for row in table["rows"]] == ["20", "50", "80"]
    assert table["rows"][1][1] == f"{frame['max_acting_time_paper_plain'][1]:.2f}"
    assert any(b["kind"] == "figure" for b in section["blocks"])
    assert section["blocks"][-1]["text"].startswith("Under the 4 readings")
