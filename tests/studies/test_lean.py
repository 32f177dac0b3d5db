"""Lean and release (studies/lean.py): the static limit by hand, the dynamic limit on the batched
engine against the scalar reference, and the people reference's rows beside them."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest
from margins import within
from support import ENGINE_SLOTS

from mjx_balance.model.params import Config, ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner
from mjx_balance.studies import lean
from mjx_balance.studies.references import read_people

# test_basin's configuration and slots: the engine compiled there serves here (support.GROUPS)
CONFIG = Config().replace(scenario={"t_end": 3.0})


@pytest.fixture(scope="module")
def limits():
    with jax.enable_x64(False):  # built as it runs (the batched engine runs in float32)
        runner = BatchRunner(CONFIG, devices=jax.local_devices()[:1], slots=ENGINE_SLOTS)
        return lean.lean_limits(CONFIG, resolution=0.05, runner=runner)


def _hold(body, g, convention):
    """The rigid lean's static torque limit by hand: the gravity torques of the two segments
    (point masses at their CoMs, hip straight) at lean a are tau_ankle = g (m_l c_l + m_u (L_l +
    c_u)) sin a and tau_hip = g m_u c_u sin a; in ``paper`` tau1 = tau_ankle - tau_hip and
    tau2 = tau_hip (tau = Sᵀ u), in ``joint`` u = tau."""
    ankle = g * (
        body.lower_mass * body.lower_com + body.upper_mass * (body.lower_length + body.upper_com)
    )
    hip = g * body.upper_mass * body.upper_com
    per_sin = np.array([ankle - hip, hip]) if convention == "paper" else np.array([ankle, hip])
    return per_sin


@pytest.mark.parametrize("convention", ["paper", "joint"])
def test_the_static_limit_is_the_gravity_torque_at_the_input_bound(convention):
    config = CONFIG.replace(controller={"convention": convention})
    torque_deg, foot_deg = lean.static_limits(config)
    per_sin = _hold(config.body, config.body.gravity, convention)
    highs = np.array([config.controller.input1_bounds[1], config.controller.input2_bounds[1]])
    expected = math.degrees(math.asin(min(highs / per_sin)))
    within(
        torque_deg,
        expected,
        atol=1e-6,
        why="brentq's xtol 1e-10 rad; MuJoCo's gravity torques of the same point masses",
    )
    # the foot-limited lean: the CoM over the toe (x = toe, at the CoM's height)
    assert foot_deg > torque_deg  # the study's body: the ankle bound decides, not the foot


def test_the_dynamic_limit_is_bracketed_and_the_reference_agrees(limits):
    """Every lean up to the limit recovers on the batched path and the one a bracket above
    does not; the scalar reference (OSQP, MuJoCo C) gives the same outcome one degree either
    side (the ADMM's eps 1e-4 moves the boundary by far less than a degree in the push map:
    docs/model.md, "Agreement")."""
    # (not below the static limit: released, the controller bends the hip, which the static
    # lean, hip straight, does not; docs/people.md, "People")
    assert 0 < limits.dynamic_deg < lean.MAX_LEAN_DEG
    assert limits.resolution_deg <= 0.05
    assert limits.peak_ankle_torque > 0 and limits.scenarios > 0
    for lean_deg, expect in (
        (limits.dynamic_deg - 1.0, "recovered"),
        (limits.dynamic_deg + 1.0, "fell"),
    ):
        state = np.array([math.radians(lean_deg), 0.0, 0.0, 0.0])
        summary = reference.simulate_scenario(CONFIG, 0.0, 0.0, initial=state)[0]
        assert summary["outcome"] == expect, (lean_deg, summary["outcome"])


def test_the_people_rows_sit_beside_the_prediction(limits):
    frame = lean.against_people(limits, read_people())
    assert list(frame["measure"]) == list(lean.PREDICTS)
    row = frame.set_index("measure").loc["lean_release_max_angle_young"]
    assert row["published_mean"] == 5.9 and row["ours"] == limits.dynamic_deg
    assert row["agrees"] == (5.9 - 2 * 1.1 <= limits.dynamic_deg <= 5.9 + 2 * 1.1)


def test_bad_resolution_is_refused():
    with pytest.raises(ParameterError, match="resolution"):
        lean.lean_limits(CONFIG, resolution=0.0, runner=object())


def test_the_lean_folder_holds_the_limits_and_refuses_another_configuration(tmp_path, limits):
    """``mb.lean_release(out=)`` (``mjx-balance lean``): lean.csv is the people rows beside the
    limits of lean_limits.csv, every column with a unit; the folder refuses a configuration
    other than its own before any work, and takes the same one again."""
    import pandas as pd

    import mjx_balance as mb
    from mjx_balance.measures import units

    out = tmp_path / "lean"
    with jax.enable_x64(False):
        frame = mb.lean_release(CONFIG, out=out, resolution=1.0, slots=ENGINE_SLOTS)
    written = pd.read_csv(out / lean.LEAN_CSV)
    limits_row = frame.attrs["limits"]
    assert set(limits_row) == set(lean.LeanLimits.__dataclass_fields__)
    assert 0 < limits_row["resolution_deg"] <= 1.0
    # the same engine and lean scan as the fixture's, only a coarser last bracket
    assert abs(limits_row["dynamic_deg"] - limits.dynamic_deg) <= 1.0
    assert list(written["measure"]) == list(lean.PREDICTS)
    assert (
        written.set_index("measure").loc["lean_release_max_angle_young", "ours"]
        == (limits_row["dynamic_deg"])
    )
    for name in (lean.LEAN_CSV, lean.LIMITS_CSV):
        assert units.unknown(pd.read_csv(out / name).columns) == [], name
    with pytest.raises(ParameterError, match="different configuration"):
        mb.lean_release(CONFIG.replace(scenario={"t_end": 4.0}), out=out, resolution=1.0)
    with pytest.raises(ParameterError, match="resolution"):
        mb.lean_release(CONFIG, out=tmp_path / "bad", resolution=2.0)
    assert not (tmp_path / "bad").exists()  # refused before the folder was made
