"""controller.infeasible = "exact_penalty": the state, CoP and CoM rows get an exact l1 penalty.

What must hold: a solvable QP keeps its hard solution (the weights are above
its multipliers), an infeasible QP gets a least-violation solution that the ADMM reaches by
convergence instead of at its cap, the batched ADMM and the OSQP reference (slack variables)
agree on it, and "capped" (the default) is untouched."""

import math

import numpy as np
import pytest
from margins import within

from mjx_balance.bench.states import (
    admm_along_trajectories,
    closed_loop_states,
    truth_solutions,
)
from mjx_balance.control import admm
from mjx_balance.control.osqp_mpc import PenaltyOSQP, ReferenceMPC
from mjx_balance.control.qp import build_qp
from mjx_balance.model.params import Config, ParameterError

# Every 20 N from 40 to 120 N, three durations: trajectories with saturated inputs and
# infeasible QPs (bench.states)
FORCES = (40.0, 60.0, 80.0, 100.0, 120.0)


@pytest.fixture(scope="module")
def case():
    config = Config().replace(controller={"infeasible": "exact_penalty"})
    qp = build_qp(config.controller, config.body, config.scenario.control_dt)
    trajectories = closed_loop_states(qp, config.body, forces=FORCES)
    truth = truth_solutions(qp, np.concatenate(trajectories))
    return config, qp, trajectories, truth


def test_the_default_is_capped_and_unchanged():
    assert Config().controller.infeasible == "capped"
    assert admm.settings_from_controller(Config().controller).penalty is None
    assert admm.ADMMSettings().penalty is None


@pytest.mark.parametrize(
    "change,words",
    [
        ({"infeasible": "soft"}, "infeasible"),
        ({"penalty_weights": (1.0, 0.0, 1.0)}, "penalty_weights"),
        ({"penalty_weights": (1.0, 1.0)}, "penalty_weights"),
    ],
)
def test_bad_settings_are_refused(change, words):
    with pytest.raises(ParameterError, match=words):
        Config().replace(controller=change)


def test_solvable_qps_keep_their_hard_solution(case):
    config, qp, trajectories, truth = case
    settings = admm.settings_from_controller(config.controller)
    assert settings.penalty == (math.inf, 1e5, 1e5, 1e5)
    capped = admm_along_trajectories(qp, trajectories)
    soft = admm_along_trajectories(qp, trajectories, settings)
    span = qp.input_upper - qp.input_lower
    ok = truth.solved
    assert ok.sum() > 100 and truth.infeasible.sum() > 10
    error = np.abs(soft["u0"][ok] - truth.u0[ok]) / span
    # the ADMM's accuracy on solvable states (admm.py: 1e-3 of each input's range against
    # OSQP at 1e-9), the same bound the capped solver is held to
    within(
        error.max(),
        0.0,
        atol=1e-3,
        why="the ADMM's accuracy target (admm.py): 1e-3 of each input's range",
    )
    assert not (soft["status"][ok] == admm.PRIMAL_INFEASIBLE).any()
    # and no solvable state takes more iterations than it did capped, in the mean
    assert soft["iters"][ok].mean() <= capped["iters"][ok].mean() + 1


@pytest.mark.slow  # OSQP on every infeasible case; the solvable cases stay in the default run
def test_infeasible_qps_converge_before_the_cap_and_match_the_reference(case):
    config, qp, trajectories, truth = case
    settings = admm.settings_from_controller(config.controller)
    capped = admm_along_trajectories(qp, trajectories)
    soft = admm_along_trajectories(qp, trajectories, settings)
    bad = truth.infeasible
    cap = settings.iteration_cap
    assert (capped["iters"][bad] == cap).all()  # the capped solver always runs to the cap
    converged = soft["iters"][bad] < cap
    assert converged.mean() > 0.3 and soft["iters"][bad].mean() < cap
    # a converged penalised solve of an infeasible QP reports it infeasible
    assert (soft["status"][bad][converged] == admm.PRIMAL_INFEASIBLE).all()
    # the OSQP slack formulation solves the same penalised QP: first inputs agree where the
    # ADMM converged (the same 1e-3 of the range as on solvable states)
    reference = PenaltyOSQP(qp, config.controller)
    states = np.concatenate(trajectories)[bad][converged]
    span = qp.input_upper - qp.input_lower
    errors = []
    for x0, u0 in zip(states, soft["u0"][bad][converged]):
        z, ok, _, violation = reference.solve(x0, None)
        assert violation > 1e-4  # the hard QP has no solution: some row stays violated
        if ok:
            errors.append(np.abs(qp.clip_input(z[:2]) - u0) / span)
    assert len(errors) > 5
    within(np.max(errors), 0.0, atol=1e-3, why="the ADMM's accuracy target (admm.py)")


def test_the_reference_keeps_the_hard_solution_of_a_solvable_qp(case):
    """The reference solves the hard QP first: a solved one is its penalised solution as is
    (the weights exceed its multipliers), so it is the capped reference's bit for bit; only an
    unsolved, LP-infeasible QP goes to the slack QP."""
    config, qp, trajectories, truth = case
    capped = ReferenceMPC(qp, Config().controller)
    soft = ReferenceMPC(qp, config.controller)
    states = np.concatenate(trajectories)
    for i in np.flatnonzero(truth.solved)[::97]:
        capped.reset()
        soft.reset()
        u_hard, z_hard, ok_hard, _ = capped.solve(states[i])
        u_soft, z_soft, ok_soft, _ = soft.solve(states[i])
        assert ok_hard and ok_soft and soft.hard_infeasible is None
        assert np.array_equal(z_hard, z_soft) and np.array_equal(u_hard, u_soft)
    # a QP the exact LP test finds infeasible (OSQP's certificate also flags a few that are
    # barely feasible)
    i = next(int(j) for j in np.flatnonzero(truth.infeasible) if not qp.feasible(states[j]))
    soft.reset()
    soft.solve(states[i])
    assert soft.hard_infeasible and soft.violation > 1e-4
