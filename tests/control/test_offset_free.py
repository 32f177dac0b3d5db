"""The offset-free MPC (offset_free.py): the observer, the steady-state target, the closed loop
in the linear plant, the batched paths against the reference, and the sustained push."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import osqp
import pytest
import scipy.sparse as sp
from margins import within
from support import ENGINE_SLOTS, AdmmMPC, assert_cells_like_the_reference

from mjx_balance.control import offset_free as ofm
from mjx_balance.control.osqp_mpc import ReferenceMPC
from mjx_balance.control.qp import build_qp
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner

CONFIG = Config().replace(controller={"offset_free": True})


@pytest.fixture(scope="module", params=["paper", "joint"])
def built(request):
    config = CONFIG.replace(controller={"convention": request.param})
    qp = build_qp(config.controller, config.body, config.scenario.control_dt)
    return config, qp, ofm.build(qp, config.controller)


def random_disturbances(rng, n, scale):
    """Disturbances of the size of pushes of up to ``scale`` N at the upper body (d ~ F [L1, c2]
    in the paper convention), in random directions and sizes."""
    return rng.standard_normal((n, 2)) * scale * np.array([1.0, 0.3])


def osqp_target(of, d):
    """The target QP min yᵀWy s.t. a·y <= b(d) by OSQP at high accuracy: (y, solved)."""
    b = of.b0 + of.bd @ d
    solver = osqp.OSQP()
    solver.setup(
        P=sp.csc_matrix(2 * of.W),
        q=np.zeros(2),
        A=sp.csc_matrix(of.normals),
        l=np.full(len(b), -np.inf),
        u=b,
        eps_abs=1e-12,
        eps_rel=1e-12,
        max_iter=200000,
        polishing=True,
        verbose=False,
    )
    result = solver.solve(raise_error=False)
    return result.x, result.info.status_val == osqp.SolverStatus.OSQP_SOLVED


def test_the_target_is_the_qp_minimiser(built):
    """Against OSQP at 1e-12 on random disturbances from small (upright holds) to beyond what
    any posture holds; the float32 jax version (the kernel's) agrees too."""
    config, _, of = built
    rng = np.random.default_rng(0)
    ds = np.concatenate(
        [
            random_disturbances(rng, 40, 15.0),
            random_disturbances(rng, 80, 80.0),
            random_disturbances(rng, 40, 300.0),
        ]
    )
    of32 = ofm.cast(of, jnp, jnp.float32)
    target32 = jax.jit(lambda d: ofm.target(jnp, of32, d))
    kinds = {"upright": 0, "lean": 0, "not held": 0}
    for d in ds:
        y, u, held = ofm.target(np, of, d)
        np.testing.assert_allclose(u, -of.K @ y - d, atol=1e-12)  # an equilibrium
        y_ref, solved = osqp_target(of, d)
        assert bool(held) == solved, d
        if not held:
            kinds["not held"] += 1
            continue
        kinds["upright" if np.allclose(y, 0) else "lean"] += 1
        # 1e-7 rad: OSQP's 1e-12 tolerances in the bounds' units (N m, m), through the normals
        np.testing.assert_allclose(y, y_ref, atol=1e-7)
        y32, _, held32 = target32(jnp.asarray(d, jnp.float32))
        assert bool(held32)
        # float32: the candidates' rounding, relative to the bounds' sizes (~1 rad, 100 N m)
        np.testing.assert_allclose(np.asarray(y32), y, atol=2e-5)
    assert min(kinds.values()) >= 5, kinds  # every kind of answer was exercised


def test_the_target_holds_what_a_steady_posture_can(built):
    """Small disturbances keep upright with u_s = -d; larger ones lean, with an input at its
    bound less the target's margin, and the CoP of the steady lean inside the foot."""
    config, qp, of = built
    y, u, held = ofm.target(np, of, np.array([3.0, 1.0]))
    assert held
    # np.allclose's tolerances: the upright target is exact (no bound active), float64 round-off
    within(y, 0.0, rtol=1e-5, atol=1e-8, why="upright: y_s = 0 exactly, float64 round-off")
    within(u, [-3.0, -1.0], rtol=1e-5, atol=1e-8, why="u_s = -d exactly, float64 round-off")
    lo, hi = np.array(config.controller.input_bounds).T
    keep = config.controller.target_margin * (hi - lo) / 2
    lo, hi = lo + keep, hi - keep
    for sign in (1.0, -1.0):
        d = sign * np.array([60.0, 15.0])
        y, u, held = ofm.target(np, of, d)
        assert held and not np.allclose(y, 0)
        # one input at a bound (np.isclose's tolerances): the bound nearest in those terms
        bounds = np.concatenate([lo, hi])
        near = np.argmin(np.abs(np.concatenate([u, u]) - bounds) / (1e-8 + 1e-5 * np.abs(bounds)))
        within(
            np.concatenate([u, u])[near],
            bounds[near],
            rtol=1e-5,
            atol=1e-8,
            why="an input at its bound less the margin, to float64 round-off",
        )
        x_s = np.concatenate([y, np.zeros(2)])
        offsets = ofm.row_offsets(np, of, x_s, u, d)
        cop = offsets[qp.rows["cop"]][0]
        low, high = config.controller.cop_bounds
        assert low - 1e-9 <= cop <= high + 1e-9


def linear_loop(config, qp, of, disturbance, periods=2000):
    """The offset-free controller (OSQP) on the linear plant x+ = A x + B (u + d_k) from rest
    (``disturbance(k)``: d_k): the states, inputs and disturbance estimates of every period."""
    mpc = ReferenceMPC(qp, config.controller)
    lm = qp.linear
    x, d_hat, x_last, u_last = np.zeros(4), np.zeros(2), np.zeros(4), np.zeros(2)
    xs, us, ds = [], [], []
    for k in range(periods):
        d_hat = ofm.observe(np, of, d_hat, x_last, u_last, x)
        x_s, _, _, offset = ofm.steady_state(np, of, d_hat)
        u = mpc.solve(x - x_s, offset)[0]
        x_last, u_last = x, u
        x = lm.A @ x + lm.B @ (u + disturbance(k))
        xs.append(x)
        us.append(u)
        ds.append(d_hat)
    return np.array(xs), np.array(us), np.array(ds)


def settles_at_the_target(of, xs, us, d):
    y_s, u_s, held = ofm.target(np, of, d)
    assert held
    # 20 s of the closed loop (slowest pole ~1 s): at rest at the target to 1e-6
    np.testing.assert_allclose(xs[-1], np.concatenate([y_s, [0, 0]]), atol=1e-6)
    np.testing.assert_allclose(us[-1], u_s, atol=1e-4)
    return y_s


def test_the_observer_converges_and_the_loop_settles_upright(built):
    """In the linear plant with a constant disturbance that the inputs can cancel, the
    estimate's error shrinks exactly by the pole each period and the loop comes to rest
    upright, the input cancelling the disturbance."""
    config, qp, of = built
    d = np.array([12.0, 4.0])
    xs, us, ds = linear_loop(config, qp, of, lambda k: d)
    errors = np.abs(ds - d).max(axis=1)
    # from the second period on (the first sees rest: no innovation yet) the error's ratio is
    # the pole, to round-off (the model is exact here)
    ratios = errors[2:30] / errors[1:29]
    np.testing.assert_allclose(ratios, config.controller.observer_pole, rtol=1e-6)
    within(
        settles_at_the_target(of, xs, us, d),
        0.0,
        rtol=1e-5,
        atol=1e-8,
        why="the upright target is exact (np.allclose's tolerances)",
    )


def test_the_loop_settles_in_the_targets_lean(built):
    """A disturbance the ankle cannot cancel upright (here ~45 N m on the first coordinate
    against its 20 N m), reached as a slow ramp (15 s), then held for 15 s: the estimate
    converges to it and the loop comes to rest in the target's lean, with the target's input
    margin left free. (As a step, or a 2-s ramp, it cannot be caught in this plant: to reach
    the lean the body must move against the disturbance, which takes more than the bounded
    input: docs/model.md.)"""
    config, qp, of = built
    d = np.array([-45.0, -10.0])
    ramp = 1500  # periods
    xs, us, ds = linear_loop(config, qp, of, lambda k: d * min(k / ramp, 1.0), periods=3000)
    within(
        ds[-1],
        d,
        atol=1e-9,
        why="the estimate's error shrinks by the pole 0.8 each period: 0.8^1500 after the "
        "ramp, float64 round-off on ~45 N m",
    )
    assert np.abs(settles_at_the_target(of, xs, us, d)).max() > 1e-2  # a real lean


def test_without_the_observer_the_plain_mpc_keeps_an_offset(built):
    """The reason for all this: the plain MPC on the same plant and disturbance settles away
    from upright."""
    config, qp, _ = built
    mpc = ReferenceMPC(qp, config.controller)
    lm, x, d = qp.linear, np.zeros(4), np.array([12.0, 4.0])
    for _ in range(100):  # 1 s
        x = lm.A @ x + lm.B @ (mpc.solve(x)[0] + d)
    assert np.abs(x[:2]).max() > 1e-3


def test_configuration_is_validated():
    with pytest.raises(ParameterError, match="offset_free"):
        CONFIG.replace(scenario={"controller_delay": 0.01})
    with pytest.raises(ParameterError, match="observer_pole"):
        Config().replace(controller={"observer_pole": 1.0})
    with pytest.raises(ParameterError, match="target_margin"):
        Config().replace(controller={"target_margin": -0.1})


CELLS = [(0.0, 0.1), (15.0, 2.0), (25.0, 2.0), (100.0, 0.1), (-40.0, 0.3)]


# the offset-free controller's own compile; its linear-model tests stay in the default run
@pytest.mark.slow
def test_batched_and_reference_offset_free_alike():
    """The C path (the reference's physics) and the reference with the same float32 ADMM, both
    offset-free: the same outcomes and fall samples, energies as close as the plain controller's
    (tests/rollout/test_cpath.py). The C path runs the batched kernel's controller (kernel.prepare,
    solve and conclude: the observer, the target and the ADMM the MJX engine runs); the slow
    test_the_mjx_path_runs_offset_free_alike runs it with MJX physics too."""
    config = CONFIG.replace(scenario={"t_end": 2.0})
    runner = BatchRunner(
        config, physics="c", slots=4, early_stop=False, devices=jax.local_devices()[:1]
    )
    assert runner.static.offset_free
    forces, durations = np.array(CELLS).T
    frame = runner.run_frame(forces, durations)
    mpc = AdmmMPC(runner)
    # The energies' tolerance: the float32 controls' rounding (4 slots here, 1 in the
    # reference; other CPUs sum in other orders: 1.06e-4 relative on energy_ankle seen on an
    # Intel Xeon, 3.3e-5 on an AMD EPYC) through the stable loop, grown along the unstable
    # direction after an infeasible QP when it falls (margins.closed_loop_rounding, as in
    # test_cpath). The observer and the target, float32 here and float64 in the reference,
    # round within a few eps_float32 of their sizes and the observer's pole (0.8) lets that
    # build up at most fivefold: far below the ADMM's share.
    outcomes = assert_cells_like_the_reference(config, frame, CELLS, mpc)
    assert {"recovered", "fell"} <= set(outcomes)


@pytest.mark.slow  # its own engine compile (the offset-free controller is a static setting)
def test_the_mjx_path_runs_offset_free_alike():
    """The MJX path with the offset-free controller gives the reference's outcomes (the same
    float32 ADMM in the reference's loop)."""
    config = CONFIG.replace(scenario={"t_end": 2.0})
    forces, durations = np.array(CELLS).T
    with jax.enable_x64(False):  # as sweeps run
        mjx = BatchRunner(
            config, physics="mjx", slots=ENGINE_SLOTS, devices=jax.local_devices()[:1]
        )
        outcomes = list(mjx.run_frame(forces, durations).outcome)
        mpc = AdmmMPC(mjx)
    expected = [
        reference.simulate_scenario(config, f, d, record=False, mpc=mpc)[0]["outcome"]
        for f, d in CELLS
    ]
    assert outcomes == expected


def test_a_sustained_push_the_plain_mpc_cannot_hold():
    """15 N for the whole window: the plain MPC leans with it until the ankle saturates and
    falls (its limit is 10.5 N); the offset-free MPC holds it upright (docs/model.md)."""
    plain = reference.simulate_scenario(Config(), 15.0, 12.0, record=False)[0]
    free = reference.simulate_scenario(CONFIG, 15.0, 12.0, record=False)[0]
    assert plain["outcome"] == "fell"
    assert free["outcome"] == "recovered"
    assert free["peak_ankle"] < 0.01  # held near upright, not in a lean
