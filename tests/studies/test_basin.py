"""The recovery basin (studies/basin.py): initial states in both engines, the map's rules,
resuming."""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest
from margins import within
from support import ENGINE_SLOTS, AdmmMPC

from mjx_balance.measures import outcomes
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner
from mjx_balance.studies import basin as basin

CONFIG = Config().replace(scenario={"t_end": 3.0})


@pytest.fixture(scope="module")
def runner():
    with jax.enable_x64(False):  # built as it runs (the module's tests run under float32)
        return BatchRunner(CONFIG, devices=jax.local_devices()[:1], slots=ENGINE_SLOTS)


@pytest.fixture(scope="module")
def plane():
    return basin.Plane(CONFIG)


def test_the_posture_realises_the_cell(plane):
    """The lean found puts the CoM at x_com, and the rate gives v_com (finite difference)."""
    for posture in basin.POSTURES:
        init = plane.initial_state(posture, 0.06, -0.2)
        within(
            plane.com_x(posture, init[0]),
            0.06,
            atol=1e-10,
            why="brentq's xtol 1e-12 rad on the lean, x the CoM's ~1 m/rad",
        )
        h = 1e-5
        v = (
            plane.com_x(posture, init[0] + h * init[2])
            - plane.com_x(posture, init[0] - h * init[2])
        ) / (2 * h)
        within(
            v,
            -0.2,
            rtol=1e-6,
            why="central difference with h = 1e-5: error ~h^2 x the curvature (~1e-10)"
            " plus float64 cancellation eps/h ~ 2e-11",
        )
        assert init[1] == (0.0 if posture == "rigid" else -init[0])
    assert plane.heel == pytest.approx(-0.15) and plane.toe == pytest.approx(0.15)
    with pytest.raises(ParameterError, match="beyond any lean"):
        plane.initial_state("rigid", 3.0, 0.0)


INITS = np.array(
    [
        [0.0, 0, 0, 0],
        [0.03, 0, 0, 0],
        [0.05, 0, 0.3, 0],
        [-0.04, 0.04, -0.2, 0.2],
        [0.0, 0, -0.15, 0],
    ]
)


def test_an_all_zero_initial_state_is_upright_rest(runner):
    """An all-zero initial state runs the cell from upright rest, bit for bit, beside other
    initial states in the same call (the engine the sweeps run: float32, x64 off)."""
    zeros = np.zeros(len(INITS))
    with jax.enable_x64(False):
        frame = runner.run_frame(zeros, zeros, INITS)
        plain = runner.run_frame(zeros[:1], zeros[:1])
    numeric = [c for c in plain.columns if plain[c].dtype.kind == "f"]
    np.testing.assert_array_equal(frame.iloc[:1][numeric].to_numpy(), plain[numeric].to_numpy())


@pytest.mark.slow  # its own engine compile (x64 on); the default run has
# test_a_push_end_state_as_initial_state_ends_alike (reference push ends on the engine)
def test_initial_states_in_both_engines_alike():
    """The batched engine from initial states (leans, rates, both directions) against the
    reference with the same float32 ADMM: the same outcomes and fall samples; energies of
    recoveries to 1e-3 (falls' rounding grows, test_delay_compensation). Run with x64 on, in
    which MJX computes part of its float32 model in float64: the two loops then agree to
    5e-7 to 5e-5 in energy (measured), so this checks that the engine's initial-state logic is the
    reference's; the agreement at the sweeps' float32 is test_rollout's."""
    runner = BatchRunner(CONFIG, devices=jax.local_devices()[:1], slots=ENGINE_SLOTS)
    zeros = np.zeros(len(INITS))
    frame = runner.run_frame(zeros, zeros, INITS)
    mpc = AdmmMPC(runner)
    outcomes = []
    for b, init in enumerate(INITS):
        ref = reference.simulate_scenario(CONFIG, 0.0, 0.0, record=False, mpc=mpc, initial=init)[0]
        mine = frame.iloc[b]
        outcomes.append(ref["outcome"])
        assert mine.outcome == ref["outcome"], init
        within(
            mine.fall_time,
            ref["fall_time"],
            atol=1e-12,
            msg=init,
            why="the same fall sample (both compute its time as k dt)",
        )
        tol = 1e-2 if ref["outcome"] == "fell" else 1e-3
        within(
            mine.energy_total,
            ref["energy_total"],
            rtol=tol,
            atol=1e-6,
            msg=init,
            why="float32 MJX physics against float64 C; a fall's rounding grows "
            "(test_delay_compensation)",
        )
    assert {"recovered", "fell"} <= set(outcomes)


def test_the_map_rest_recovers_beyond_the_capture_point_falls(tmp_path, plane, float32):
    """Upright rest recovers; a state whose capture point lies beyond the toe, moving that
    way, falls; the map is resumable and refuses another grid with nothing lost."""
    out = tmp_path / "basin"
    frame = basin.run_basin(
        out,
        CONFIG,
        "0,0.1",
        "0,0.5",
        progress=False,
        say=lambda s: None,
        devices=jax.local_devices()[:1],
        slots=ENGINE_SLOTS,
    )
    cell = frame.set_index(["x_com", "v_com"])
    assert cell.loc[(0.0, 0.0), "outcome"] == "recovered"
    assert cell.loc[(0.0, 0.0), "capture_inside"]
    assert not cell.loc[(0.1, 0.5), "capture_inside"]  # 0.1 + 0.5 / 3.2 > 0.15
    assert cell.loc[(0.1, 0.5), "outcome"] == "fell"
    assert cell.loc[(0.1, 0.5), "fall_cause"] in outcomes.FALL_CAUSES[1:]  # a name, not a code
    assert (out / basin.BASIN_PNG).stat().st_size > 10_000
    k = int((frame.outcome == "recovered").sum())
    assert (out / basin.BASIN_TXT).read_text().startswith(f"{k} of 4 initial states recover")
    from mjx_balance.report.extra import (
        basin_section,  # the report's section of this folder
    )

    section = basin_section(out)
    assert section["id"] == "basin" and [b["kind"] for b in section["blocks"]] == [
        "paragraph",
        "figure",
        "paragraph",
    ]
    parts = sorted((out / basin.CELLS_DIR).iterdir())
    said = []
    again = basin.run_basin(out, CONFIG, "0,0.1", "0,0.5", progress=False, say=said.append)
    assert said[0] == "basin: all 4 cells done"
    assert sorted((out / basin.CELLS_DIR).iterdir()) == parts
    pd.testing.assert_frame_equal(again, frame)
    import mjx_balance as mb  # the Python API on the same folder: nothing to run either

    pd.testing.assert_frame_equal(mb.basin(CONFIG, out=out, x_com="0,0.1", v_com="0,0.5"), frame)
    with pytest.raises(ParameterError, match="another --out folder"):
        basin.run_basin(out, CONFIG, "0,0.1", "0,0.4", progress=False, say=lambda s: None)
    with pytest.raises(ParameterError, match="posture"):
        basin.run_basin(out, CONFIG, "0,0.1", "0,0.5", "bent", progress=False)
    assert sorted((out / basin.CELLS_DIR).iterdir()) == parts  # nothing lost


def test_a_push_end_state_as_initial_state_ends_alike(runner, plane):
    """The joint state at the end of a push, run as an initial state with no push, ends as
    the push run did (a recovery and a fall after the push; the foot and the controller's warm
    start are those of a fresh start, so cells near the boundary are not asked)."""
    ends = basin.push_ends(CONFIG, plane, "20,60", "0.1,0.3")
    ends = ends[np.isfinite(ends.x_com)]
    assert set(ends.outcome) == {"recovered", "fell"}
    inits = ends[["q_a", "q_h", "dq_a", "dq_h"]].to_numpy()
    zeros = np.zeros(len(inits))
    with jax.enable_x64(False):
        frame = runner.run_frame(zeros, zeros, inits)
    assert list(frame.outcome) == list(ends.outcome)
