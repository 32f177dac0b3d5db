"""The batched ADMM (admm.py) against OSQP at eps 1e-9 on closed-loop states.

States: closed-loop trajectories of the linear model under the OSQP MPC after pushes of
20..120 N for 0.1 and 0.2 s (bench.states.closed_loop_states, 0.6 s each): about 1,300 per
convention, including saturated first inputs and infeasible QPs. Each ADMM solve is
warm-started from the previous state's shifted solution, as in the closed loop.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from margins import admm_rounding, within

from mjx_balance.bench.states import (
    ACCURACY,
    admm_along_trajectories,
    closed_loop_states,
    first_control_error,
    misses,
    truth_solutions,
)
from mjx_balance.control import admm
from mjx_balance.control.osqp_mpc import osqp_solve, osqp_solver
from mjx_balance.control.qp import build_qp
from mjx_balance.model.params import BodyParams, ControllerParams

FORCES = tuple(np.arange(20.0, 121.0, 10.0))
DURATIONS = (0.1, 0.2)


@pytest.fixture(scope="module", params=["paper", "joint"])
def case(request):
    controller = ControllerParams(convention=request.param)
    body = BodyParams()
    qp = build_qp(controller, body, 0.01)
    trajectories = closed_loop_states(qp, body, FORCES, DURATIONS, steps=60)
    states = np.concatenate(trajectories)
    truth = truth_solutions(qp, states, eps=1e-9)
    settings = admm.settings_from_controller(controller)
    seq32 = admm_along_trajectories(qp, trajectories, settings, jnp.float32)
    return dict(
        convention=request.param,
        controller=controller,
        qp=qp,
        settings=settings,
        trajectories=trajectories,
        states=states,
        truth=truth,
        seq32=seq32,
    )


def test_states_include_saturated_and_infeasible(case):
    truth = case["truth"]
    print(
        f"\n{case['convention']}: {len(case['states'])} states, {truth.solved.sum()} solved, "
        f"{truth.infeasible.sum()} infeasible, {truth.saturated.sum()} saturated first input"
    )
    assert len(case["states"]) >= 1000
    assert truth.saturated.sum() > 0
    assert truth.infeasible.sum() > 0


def test_first_control_matches_osqp(case):
    qp, truth, seq = case["qp"], case["truth"], case["seq32"]
    err = first_control_error(qp, seq["u0"], truth)
    both = truth.solved & (seq["status"] == admm.SOLVED)
    n_miss = misses(err, truth)
    print(
        f"\n{case['convention']} float32, cap {case['settings'].iteration_cap}: "
        f"{n_miss}/{truth.solved.sum()} misses ({100 * n_miss / truth.solved.sum():.2f}%), "
        f"max error {np.max(err[truth.solved]):.2e} (both solved: {np.max(err[both]):.2e}, "
        f"{both.sum()} solves), mean iterations {seq['iters'].mean():.1f}"
    )
    within(
        err[both],
        0.0,
        atol=ACCURACY,
        why="the batched controller's accuracy requirement: 1e-3 of each input's range of "
        "OSQP at 1e-9 (bench.states.ACCURACY)",
    )
    assert n_miss < 0.01 * truth.solved.sum()
    assert np.all(np.isfinite(seq["z"])) and np.all(np.isfinite(seq["u0"]))


def test_float32_agrees_with_float64(case):
    """float32 and float64 run the same iterations with the same stopping rule; float32's
    rounding moves each iterate by at most margins.admm_rounding (1.9e-3 of the input, no credit
    for the ADMM's contraction), i.e. half that of the range (|u0| <= half the range). Where the
    rounding moves a stopping check by one chunk the two stop 10 iterations apart, both within
    the residual tolerance (eps 1e-7 abs, 3e-6 rel). Measured on a 2-core AMD EPYC: 3.7e-5 of
    the range (0.37 of the former, measured tolerance 1e-4)."""
    seq32 = case["seq32"]
    seq64 = admm_along_trajectories(case["qp"], case["trajectories"], case["settings"], jnp.float64)
    both = (seq32["status"] == admm.SOLVED) & (seq64["status"] == admm.SOLVED)
    span = case["qp"].input_upper - case["qp"].input_lower
    diff = np.max(np.abs(seq32["u0"] - seq64["u0"]) / span, axis=-1)
    print(
        f"\n{case['convention']}: float32 vs float64 max |du0| {diff[both].max():.2e} of range "
        f"over {both.sum()} solves both solved"
    )
    assert both.sum() >= 0.95 * np.sum(seq64["status"] == admm.SOLVED)
    within(
        diff[both],
        0.0,
        atol=admm_rounding(case["controller"]) / 2,
        why="float32 rounding of the ADMM's iterations (margins.admm_rounding) on inputs "
        "of at most half their range",
    )


def test_warm_start_reduces_iterations(case):
    cold = admm_along_trajectories(
        case["qp"], case["trajectories"], case["settings"], jnp.float32, warm=False
    )
    # Infeasible states run to the cap either way; compare on the feasible (OSQP-solved) ones.
    feasible = case["truth"].solved
    warm_total = case["seq32"]["iters"][feasible].sum()
    cold_total = cold["iters"][feasible].sum()
    print(
        f"\n{case['convention']}: iterations over the {feasible.sum()} feasible states along "
        f"the trajectories: warm {warm_total}, cold {cold_total} "
        f"({100 * (1 - warm_total / cold_total):.0f}% fewer)"
    )
    assert warm_total < 0.95 * cold_total


def test_vmap_equals_loop(case):
    """Batched solve == Python loop of single solves (float64: the same arithmetic up to the
    summation order of the products)."""
    qp, settings, states = case["qp"], case["settings"], case["states"]
    data = admm.build_admm(qp, settings, jnp.float64)
    idx = np.linspace(0, len(states) - 1, 24).astype(int)
    infeasible = np.flatnonzero(case["truth"].infeasible)[:8]
    idx = np.concatenate([idx, infeasible])
    x0 = jnp.asarray(states[idx], jnp.float64)
    warm = admm.ADMMWarm(
        z=jnp.asarray(case["seq32"]["warm_z"][idx], jnp.float64),
        y=jnp.asarray(case["seq32"]["warm_y"][idx], jnp.float64),
    )
    batched = jax.jit(admm.admm_solve_batch, static_argnums=(3, 4))(data, x0, warm, settings, 8)
    single = jax.jit(admm.admm_solve, static_argnums=3)
    for i in range(len(idx)):
        r = single(data, x0[i], admm.ADMMWarm(warm.z[i], warm.y[i]), settings)
        assert int(r.status) == int(batched.status[i])
        assert int(r.iters) == int(batched.iters[i])
        np.testing.assert_allclose(r.z, batched.z[i], rtol=1e-7, atol=1e-7)
        np.testing.assert_allclose(r.u0, batched.u0[i], rtol=1e-7, atol=1e-7)
        np.testing.assert_allclose(r.warm_next.y, batched.warm_next.y[i], rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("tile", [None, 8, 16])
def test_tiles_and_offsets_solve_each_lane_as_alone(case, tile):
    """Tiled batches (the engine's ADMM on a CPU) with per-lane row offsets (the offset-free
    QP) == single solves (float64, as above: the same arithmetic up to the products' summation
    order): a lane's iterations do not depend on its tile's other lanes."""
    qp, settings, states = case["qp"], case["settings"], case["states"]
    data = admm.build_admm(qp, settings, jnp.float64)
    idx = np.concatenate(
        [
            np.linspace(0, len(states) - 1, 24).astype(int),
            np.flatnonzero(case["truth"].infeasible)[:8],
        ]
    )[:32]
    x0 = jnp.asarray(states[idx], jnp.float64)
    warm = admm.ADMMWarm(
        z=jnp.asarray(case["seq32"]["warm_z"][idx], jnp.float64),
        y=jnp.asarray(case["seq32"]["warm_y"][idx], jnp.float64),
    )
    m = data.l0.shape[0]
    offset = jnp.asarray(np.random.default_rng(5).normal(0, 1e-3, (idx.size, m)), jnp.float64)
    batched = jax.jit(admm.admm_solve_batch, static_argnums=(3, 4))(
        data, x0, warm, settings, tile, offset
    )
    single = jax.jit(admm.admm_solve, static_argnums=3)
    for i in range(idx.size):
        r = single(data, x0[i], admm.ADMMWarm(warm.z[i], warm.y[i]), settings, offset[i])
        assert int(r.status) == int(batched.status[i])
        assert int(r.iters) == int(batched.iters[i])
        np.testing.assert_allclose(r.z, batched.z[i], rtol=1e-7, atol=1e-7)
        np.testing.assert_allclose(r.u0, batched.u0[i], rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("dtype", [jnp.float32, jnp.float64])
def test_infeasible_states_report_status_and_stay_finite(dtype):
    controller = ControllerParams()
    qp = build_qp(controller, BodyParams(), 0.01)
    settings = admm.settings_from_controller(controller)
    data = admm.build_admm(qp, settings, dtype)
    # Far beyond the state bounds and moving away: no input sequence within the torque limits
    # can bring the tilts back inside, so the QP is infeasible.
    x0 = np.array(
        [
            [0.7, 0.7, 2.0, 2.0],
            [-0.5, -0.6, -3.0, -3.0],
            [0.45, 1.5, 1.0, 4.0],
            [0.0, 0.0, 10.0, -10.0],
        ]
    )
    solver = osqp_solver(qp, 1e-6, detect_infeasible=True)
    for x in x0:
        assert "infeasible" in osqp_solve(solver, qp, x).info.status
    res = admm.admm_solve_batch(
        data,
        jnp.asarray(x0, dtype),
        admm.ADMMWarm(z=jnp.zeros((4, qp.n), dtype), y=jnp.zeros((4, qp.m), dtype)),
        settings,
    )
    status = np.asarray(res.status)
    print(f"\ninfeasible states ({jnp.dtype(dtype).name}): status {status.tolist()}")
    assert np.all((status == admm.PRIMAL_INFEASIBLE) | (status == admm.MAX_ITER))
    assert np.all(np.asarray(res.iters) == settings.iteration_cap)
    for leaf in jax.tree.leaves(res):
        assert np.all(np.isfinite(np.asarray(leaf)))
    u0 = np.asarray(res.u0)
    assert np.all(u0 >= qp.input_lower) and np.all(u0 <= qp.input_upper)


def test_settings_are_static_and_follow_the_controller():
    controller = ControllerParams(admm_rho=0.2, admm_max_iter=35, admm_check_every=5)
    settings = admm.settings_from_controller(controller)
    assert hash(settings) == hash(admm.settings_from_controller(controller))
    assert (settings.rho, settings.max_iter, settings.check_every) == (0.2, 35, 5)
    assert settings.iteration_cap == 35
    assert admm.ADMMSettings(max_iter=55, check_every=10).iteration_cap == 60


def test_shift_moves_each_row_group_one_step():
    qp = build_qp(ControllerParams(horizon=4), BodyParams(), 0.01)
    z_idx, y_idx = admm.shift_index(qp.rows, qp.n, qp.m, qp.horizon)
    assert z_idx.tolist() == [2, 3, 4, 5, 6, 7, 6, 7]
    assert y_idx[qp.rows["cop"]].tolist() == [17, 18, 19, 19]
    assert y_idx[qp.rows["states"]].tolist() == [10, 11, 12, 13, 14, 15, 14, 15]
