"""Controllers of control/law.py on the batched path (MJX physics, the law vmapped) against the
same law in the scalar reference (MuJoCo C, the law jitted once, unbatched): the built-in LQR
and PD, a user's law that carries state, and a law whose input is NaN (a diverged status for
every scenario, never an exception). Slow: each law is its own compiled program."""

from __future__ import annotations

import numpy as np
import pytest
from margins import within

from mjx_balance import rollout
from mjx_balance.measures.outcomes import OUTCOMES
from mjx_balance.model.mjcf import indices
from mjx_balance.model.params import Config
from mjx_balance.reference import loop as reference

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("float32_module")]

# 0 N (rest), 50 N (recovers), 120 N (falls) for 0.1 s, in a 3-s window
FORCES = np.array([0.0, 50.0, 120.0])
T_END = 3.0
# The agreement of the two paths' joint angles. The law is one function in both, evaluated in
# float32 on the state each path measures, so no solver difference enters (unlike the MPC's
# ADMM against OSQP): what remains is MJX's float32 physics with its capped contact solver
# against MuJoCo C in float64, through a stable loop, which the MPC's tolerance already bounds
# (tests/rollout/test_rollout.py, ANGLE_TOL, 5e-3 rad, derived there). Measured on a 2-core AMD
# EPYC over the windows of :func:`compared`: at most 5.8e-4 rad (the PD at rest, its stiff gains
# on the foot's settling), 12 % of it; the others 5e-4 rad or less.
ANGLE_TOL = 5e-3  # rad
# A fall is decided at a sample where the body crosses a threshold fast: the same fall sample
# within a few physics steps (the angles agree to ANGLE_TOL; the pitch rate at the fall is
# about 1 rad/s, so 5e-3 rad is 5 ms, 2.5 steps): 0.01 s.
FALL_TOL = 0.01  # s


def compared(config: Config, ref: dict, series) -> int:
    """How many samples the angles are compared over: a recovery's whole run, a fall's up to
    its decision instant (``decision_time``, docs/model.md "Stepping: capturability"): from
    there the feet in place cannot hold the body, the inputs sit at their bounds and the loop
    no longer feeds the state back, so float32 rounding grows as in the open-loop unstable
    body (test_rollout.py, PHYSICS_TOL's comment), no longer bounded by the stable loop's
    ANGLE_TOL. (The MPC's own test stops at its first infeasible QP for the same reason.)"""
    if ref["outcome"] != "fell":
        return len(series)
    return int(round(ref["decision_time"] / config.scenario.physics_dt))


@pytest.mark.parametrize(
    "kind, options",
    [
        ("lqr", {}),
        ("pd", {}),
        ("law_examples:integral_lqr", {"ki": 200.0}),
        ("mjx_balance.control.policy:mlp", {}),
    ],
)
def test_a_law_on_the_batched_path_matches_it_in_the_reference(kind, options):
    """Also the law's own state: with ki = 200 the integral law settles at 50 N in 0.55 s
    where the LQR takes 1.12 s (the reference, measured), so a batched path that lost the
    state between periods would miss the settle time's 0.1-s tolerance."""
    controller = {"kind": kind, "options": options}
    config = Config().replace(controller=controller, scenario={"t_end": T_END})
    runner = rollout.BatchRunner(config, trajectories=True)
    summary = runner.run(FORCES, np.full(3, 0.1))
    series = runner.last_trajectories
    assert series is not None
    ix = indices(runner.model)
    outcomes = []
    for b, force in enumerate(FORCES):
        ref, ref_series = reference.simulate_scenario(config, force, 0.1, record=True)
        outcomes.append(ref["outcome"])
        assert OUTCOMES[summary["outcome"][b]] == ref["outcome"], (kind, force)
        n = compared(config, ref, ref_series)
        assert n * config.scenario.physics_dt > 0.2  # (a window that tests something)
        q = series["qpos"][b, :n][:, [ix.ankle_qpos, ix.hip_qpos]]
        diff = np.abs(q - ref_series[["q_a", "q_h"]].to_numpy()[:n])
        print(
            f"\n{kind} {force:5.1f} N: {ref['outcome']}, max |angle diff| "
            f"{np.nanmax(diff):.2e} over {n * config.scenario.physics_dt:.3f} s"
        )
        within(np.nanmax(diff), 0.0, atol=ANGLE_TOL, msg=(kind, force), why="ANGLE_TOL (comment)")
        within(
            summary["fall_time"][b],
            ref["fall_time"],
            atol=FALL_TOL,
            msg=(kind, force),
            why="FALL_TOL (comment)",
        )
        assert summary["nonconverged_solves"][b] == ref["nonconverged_solves"] == 0
        if ref["outcome"] == "recovered":
            within(
                summary["settle_time"][b],
                ref["settle_time"],
                atol=0.1,
                msg=(kind, force),
                why="the settle band is crossed at a shallow slope (test_rollout.py): 0.1 s",
            )
    # the cases are what they claim: the window's rest, a recovery and a fall
    assert outcomes == ["recovered", "recovered", "fell"], outcomes


def test_a_law_whose_input_is_not_finite_diverges_each_scenario_and_keeps_the_batch():
    config = Config().replace(
        controller={"kind": "law_examples:diverging"}, scenario={"t_end": 0.5}
    )
    summary = rollout.BatchRunner(config).run([0.0, 50.0], [0.1, 0.1])
    assert [OUTCOMES[o] for o in summary["outcome"]] == ["diverged", "diverged"]
    ref = reference.simulate_scenario(config, 50.0, 0.1, record=False)[0]
    assert ref["outcome"] == "diverged"
