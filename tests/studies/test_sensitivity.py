"""The sensitivity of the reproduction table to the reading of the study (sensitivity.py),
with stand-in batch functions (tests/support.py's FakeThresholdBatch: recovered iff
F T < c), so the spread and the conclusions are known in closed form."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from support import FakeThresholdBatch, expected_max_time

from mjx_balance.cli import main
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.studies import sensitivity

# the stand-in's threshold c [N s] per reading: recovered iff F T < c
# (no F T = c on the 0.01-s grid of the bisection, where the fake's rounding would decide)
C = {("paper", False): 30.7, ("joint", False): 20.3, ("paper", True): 45.3, ("joint", True): 40.7}
KEY_C = {
    "paper_plain": 30.7,
    "joint_plain": 20.3,
    "paper_offset_free": 45.3,
    "joint_offset_free": 40.7,
}
FORCES = "20,50,80"


def stand_in_fake(config):
    """The stand-in of a reading (conftest's ``stand_in`` makes one per configuration)."""
    return FakeThresholdBatch(c=C[(config.controller.convention, config.controller.offset_free)])


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
    forces = frame.force.to_numpy()
    for key, c in KEY_C.items():
        # the stand-in's motors' energy is 3 F T (float32), its study energy 0; the 0.1-s
        # push's energy is NaN where F 0.1 >= c (not recovered)
        np.testing.assert_allclose(
            frame[f"energy_motors_{key}"], 3 * forces * frame[f"max_acting_time_{key}"], rtol=1e-6
        )
        np.testing.assert_allclose(
            frame[f"energy_motors_01_{key}"],
            np.where(forces * 0.1 < c, 3 * forces * 0.1, np.nan),
            rtol=1e-6,
        )
        assert (frame[f"energy_study_{key}"] == 0).all()
    for name in ("study", "motors", "study_01", "motors_01"):
        energies = frame[[f"energy_{name}_{k}" for k in KEY_C]].to_numpy()
        np.testing.assert_array_equal(frame[f"energy_{name}_min"], np.nanmin(energies, axis=1))
        np.testing.assert_array_equal(frame[f"energy_{name}_max"], np.nanmax(energies, axis=1))
    # at 20 N the longest push is 1.53 s (45.3 N s, paper offset-free) vs 1.01 s (20.3, joint)
    assert frame.max_acting_time_ratio[0] == pytest.approx(2.26 / 1.01)
    text = (out / sensitivity.SENSITIVITY_TXT).read_text()
    # F T < c: the max acting time falls with F under every reading, and the offset-free
    # stand-ins (larger c) hold pushes longer in both conventions
    every = text.split("Under every reading: ")[1].split("Depending on the reading")[0]
    assert "the max acting time falls" in every
    assert "offset-free MPC's max acting time is at least" in every
    assert "the motors' energy of the 0.1-s push rises with the force" in every
    assert "the study's energy is at most the motors'" in every
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

    def table(times, study, motors, study_01, motors_01):
        return pd.DataFrame(
            {
                "force": [20.0, 50.0, 80.0],
                "max_acting_time": times,
                "study_energy_total_max": study,
                "energy_total_max": motors,
                "study_energy_total_01": study_01,
                "energy_total_01": motors_01,
            }
        )

    # the 0.1-s push: recovered at 20 and 50 N (the plain reading's study energy known at
    # 20 N only)
    tables = {
        "paper_plain": table(
            [1.0, 0.5, 0.5],
            [1.0, 2.0, 2.0],
            [1.0, 2.0, 3.0],
            [0.1, np.nan, np.nan],
            [0.2, 0.4, np.nan],
        ),
        "paper_offset_free": table(
            [2.0, 0.4, 0.6],
            [1.0, 0.5, 0.6],
            [1.0, 3.0, 2.0],
            [0.1, 0.3, np.nan],
            [0.2, 0.2, np.nan],
        ),
    }
    frame = sensitivity.spread(tables)
    assert list(frame.max_acting_time_ratio) == [2.0, 1.25, 1.2]
    assert list(frame.energy_motors_max) == [1.0, 3.0, 3.0]
    np.testing.assert_array_equal(frame.energy_study_01_min, [0.1, 0.3, np.nan])
    found = dict(sensitivity.conclusions(frame, ["paper_plain", "paper_offset_free"]))
    assert found["the max acting time falls (or stays) as the force grows"] == ["paper_plain"]
    assert found[
        "the study's energy (eq. 20) of the longest recovered push rises with the force"
    ] == ["paper_plain"]
    assert found["the motors' energy of the longest recovered push rises with the force"] == [
        "paper_plain"
    ]
    # one recovered 0.1-s push decides nothing: it needs two forces
    assert found[
        "the study's energy (eq. 20) of the 0.1-s push rises with the force (where it recovers)"
    ] == ["paper_offset_free"]
    # study 0.3 J > motors 0.2 J at 50 N (offset-free)
    assert found["the study's energy is at most the motors' (every force, both pushes)"] == [
        "paper_plain"
    ]
    assert (
        found[
            "the offset-free MPC's max acting time is at least the plain MPC's at every "
            "force (same convention)"
        ]
        == []
    )
    text = sensitivity.reading_text(frame, tables)
    assert "Under every reading: the motors' energy of the 0.1-s push rises" in text
    assert "the max acting time falls (or stays) as the force grows (only paper, plain MPC)" in text
    assert "not: the offset-free MPC's max acting time is at least" in text


def test_plain_readings_are_plain_on_an_offset_free_base(tmp_path, stand_in):
    """A plain reading turns the offset-free MPC off (the stand-in's c tells them apart)."""
    base = Config().replace(controller={"offset_free": True}, scenario={"t_end": 12.0})
    configs = sensitivity.reading_configs(base)
    assert [c.controller.offset_free for c in configs.values()] == [False, False, True, True]
    frame = sensitivity.run_sensitivity(tmp_path / "o", base, "20", say=lambda s: None)
    assert frame.max_acting_time_paper_plain[0] == expected_max_time(20, 30.7, 12.0)
    assert frame.max_acting_time_joint_offset_free[0] == expected_max_time(20, 40.7, 12.0)


def test_command_line_writes_says_and_resumes(tmp_path, stand_in, capsys):
    out = tmp_path / "cli"
    assert (
        main(
            [
                "sensitivity",
                "--forces",
                "20,50",
                "--readings",
                "paper_plain,paper_offset_free",
                "--set",
                "scenario.t_end=6",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    said = capsys.readouterr().out
    assert f"sensitivity: paper, offset-free MPC -> {out / 'paper_offset_free'}" in said
    assert "Under the 2 readings" in said and "xnan" not in said  # zero study energies
    for name in ("sensitivity.csv", "sensitivity.png", "sensitivity.txt"):
        assert (out / name).exists(), name
    assert not (out / "joint_plain").exists()
    frame = pd.read_csv(out / "sensitivity.csv")
    assert list(frame.max_acting_time_paper_plain) == [
        expected_max_time(f, 30.7, 6.0) for f in (20, 50)
    ]
    calls = sum(len(f.calls) for f in stand_in)
    assert (
        main(
            [
                "sensitivity",
                "--forces",
                "20,50",
                "--readings",
                "paper_plain,paper_offset_free",
                "--set",
                "scenario.t_end=6",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert sum(len(f.calls) for f in stand_in) == calls  # resumed: nothing run again
    # the folder holds another configuration's tables: refused, nothing changed
    before = (out / "sensitivity.csv").read_bytes()
    assert (
        main(["sensitivity", "--forces", "20,50", "--readings", "paper_plain", "--out", str(out)])
        == 2
    )
    assert (out / "sensitivity.csv").read_bytes() == before


def test_refused_readings(tmp_path, stand_in):
    """The offset-free MPC refuses a controller delay: the command names the reading and does
    nothing; the report runs the readings that the configuration admits."""
    from mjx_balance.studies.experiments import sensitivity_readings

    delayed = Config().replace(scenario={"controller_delay": 0.1})
    with pytest.raises(ParameterError, match="reading 'paper_offset_free'"):
        sensitivity.reading_configs(delayed)
    assert (
        main(
            ["sensitivity", "--set", "scenario.controller_delay=0.1", "--out", str(tmp_path / "d")]
        )
        == 2
    )
    assert not (tmp_path / "d").exists()
    assert list(sensitivity_readings(delayed, ("paper", "joint"))) == ["paper_plain", "joint_plain"]
    assert list(sensitivity_readings(Config(), ("joint",))) == ["joint_plain", "joint_offset_free"]
    with pytest.raises(ParameterError, match="unknown reading"):
        sensitivity.write_sensitivity(tmp_path, {"paper_bent": pd.DataFrame()})
    with pytest.raises(ParameterError, match="share no force"):
        sensitivity.write_sensitivity(
            tmp_path,
            {
                "paper_plain": pd.DataFrame({"force": [20.0]}),
                "joint_plain": pd.DataFrame({"force": [50.0]}),
            },
        )
    assert not stand_in


def test_bad_input_is_refused_before_any_work(tmp_path, stand_in):
    with pytest.raises(ParameterError, match="unknown reading"):
        sensitivity.run_sensitivity(tmp_path / "x", Config(), FORCES, readings=["paper_bent"])
    assert (
        main(["sensitivity", "--readings", "paper_plain,nope", "--out", str(tmp_path / "y")]) == 2
    )
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
    frame = sensitivity.run_sensitivity(
        report / "sensitivity", Config(), FORCES, say=lambda s: None
    )
    (section,) = extra_sections(report)
    assert section["id"] == "sensitivity"
    table = next(b for b in section["blocks"] if b["kind"] == "table")
    assert [row[0] for row in table["rows"]] == ["20", "50", "80"]
    assert table["rows"][1][1] == f"{frame['max_acting_time_paper_plain'][1]:.2f}"
    assert any(b["kind"] == "figure" for b in section["blocks"])
    assert section["blocks"][-1]["text"].startswith("Under the 4 readings")
