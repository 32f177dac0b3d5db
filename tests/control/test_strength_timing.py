"""The input rate limit (``controller.input_rates``, docs/model.md "Strength and timing"): a
bound on the applied input's change per control period, in the QP (the first input's rows) and
on the actuator, on the batched kernel and the scalar reference alike."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from margins import within
from support import AdmmMPC, assert_cells_like_the_reference

from mjx_balance.control import admm as admm_mod
from mjx_balance.control import certificate
from mjx_balance.control.osqp_mpc import ReferenceMPC
from mjx_balance.control.qp import build_qp
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.model.subject import Subject
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner

# N m/s: binds (without it the same push moves the input over twice as fast: asserted below)
RATES = [100.0, 100.0]
CONFIG = Config().replace(controller={"input_rates": RATES}, scenario={"t_end": 2.0})


def test_the_limit_is_checked_and_left_out_when_none():
    assert "input_rates" not in Config().to_dict()["controller"]  # the study's files unchanged
    assert CONFIG.to_dict()["controller"]["input_rates"] == RATES
    assert CONFIG.controller.rate_steps(0.01) == (1.0, 1.0)
    assert Config().controller.rate_steps(0.01) == (np.inf, np.inf)
    for bad, why in (([0, 1], "positive"), ([1], "positive"), ("fast", "list of numbers")):
        with pytest.raises(ParameterError, match=f"input_rates.*{why}"):
            Config().replace(controller={"input_rates": bad})
    with pytest.raises(ParameterError, match="finite"):
        Config().replace(controller={"input_rates": [np.inf, 1.0]})


def test_a_subject_scales_its_rates_as_its_bounds():
    subject = Subject(height=1.8, mass=80.0, ankle_strength=2.0)
    config = subject.config(CONFIG)
    factor = 80.0 / 66.3
    within(config.controller.input_rates[0], 100.0 * factor * 2.0, rtol=1e-15, why="float")
    within(config.controller.input_rates[1], 100.0 * factor, rtol=1e-15, why="float")
    assert subject.config(Config()).controller.input_rates is None


def test_no_certificate_under_a_rate_limit():
    """The certificate's argument is the LQR law, which may change faster than the limit."""
    assert certificate.applies(Config())
    assert not certificate.applies(CONFIG)


@pytest.fixture(scope="module")
def qp():
    return build_qp(CONFIG.controller, CONFIG.body, CONFIG.scenario.control_dt)


def test_the_first_inputs_rows_alone_are_tightened(qp):
    x0 = np.array([0.02, -0.01, 0.1, 0.05])
    first = np.array([[-3.0, -50.0], [5.0, 2.0]])
    lower, upper = qp.bounds(x0)
    tight_lower, tight_upper = qp.bounds(x0, first=first)
    assert np.array_equal(tight_lower[2:], lower[2:]) and np.array_equal(tight_upper[2:], upper[2:])
    assert np.array_equal(tight_lower[:2], np.maximum(lower[:2], first[0]))
    assert np.array_equal(tight_upper[:2], np.minimum(upper[:2], first[1]))


def test_admm_without_a_binding_limit_is_the_plain_qp_bit_for_bit(qp):
    """The kernel always passes the first input's bounds; at [-inf, inf] (no limit) every
    number of the solve is the plain QP's (max / min with an infinity is exact)."""
    settings = admm_mod.settings_from_controller(CONFIG.controller)
    data = admm_mod.build_admm(qp, settings)
    warm = admm_mod.initial_warm(data)
    xs = jnp.asarray(np.random.default_rng(0).normal(scale=0.05, size=(16, 4)), jnp.float32)
    free = jnp.asarray([[-np.inf] * 2, [np.inf] * 2], jnp.float32)
    plain = jax.jit(jax.vmap(lambda x: admm_mod.admm_solve(data, x, warm, settings)))(xs)
    limited = jax.jit(jax.vmap(lambda x: admm_mod.admm_solve(data, x, warm, settings, None, free)))(
        xs
    )
    for a, b in zip(jax.tree.leaves(plain), jax.tree.leaves(limited)):
        assert np.array_equal(np.asarray(a), np.asarray(b))


def test_admm_and_osqp_agree_on_the_tightened_qp(qp):
    """A binding limit: the ADMM's first input lies within it and is OSQP's (1e-8) to the
    ADMM's accuracy (1e-3 of the torque range, docs/model.md "Solvers")."""
    settings = admm_mod.settings_from_controller(CONFIG.controller)
    data = admm_mod.build_admm(qp, settings)
    osqp = ReferenceMPC(qp, CONFIG.controller)
    solve = jax.jit(  # one compile for the 12 states
        lambda x, f: admm_mod.admm_solve(data, x, admm_mod.initial_warm(data), settings, None, f)
    )
    rng = np.random.default_rng(1)
    bound = 0
    for _ in range(12):
        x0 = rng.normal(scale=0.03, size=4)
        last = rng.uniform(-10.0, 10.0, size=2)
        first = np.stack([last - 1.0, last + 1.0])
        osqp.reset()
        u_ref = osqp.solve(x0, first=first)[0]
        res = solve(jnp.asarray(x0, jnp.float32), jnp.asarray(first, jnp.float32))
        u = np.asarray(res.u0, float)
        assert (u >= first[0] - 1e-6).all() and (u <= first[1] + 1e-6).all()
        within(u, u_ref, atol=1e-3 * 40.0, why="ADMM's accuracy, 1e-3 of the ankle input's range")
        bound += int(np.any(np.isclose(u_ref, first[0]) | np.isclose(u_ref, first[1])))
    assert bound >= 6  # the limit binds in most of these states (the check can fail)


def test_the_reference_applies_no_faster_change_than_the_limit():
    """Every control period's applied input moves at most rate x control_dt from the last,
    from rest (u = 0) on; without the limit the same push moves it far faster."""
    config = CONFIG.replace(scenario={"t_end": 1.0})
    step = config.controller.rate_steps(config.scenario.control_dt)
    series = reference.simulate_scenario(config, 60.0, 0.2)[1]
    free_series = reference.simulate_scenario(
        config.replace(controller={"input_rates": None}), 60.0, 0.2
    )[1]
    for s in (series, free_series):
        assert s is not None
    u = series[["u1", "u2"]].to_numpy()[:: CONFIG.scenario.substeps]
    change = np.abs(np.diff(np.vstack([np.zeros(2), u]), axis=0))
    assert (change <= np.array(step) * (1 + 1e-12)).all()
    u_free = free_series[["u1", "u2"]].to_numpy()[:: CONFIG.scenario.substeps]
    # unlimited, the same push moves the input by more than twice the limit in a period (3.8 N m
    # against 1 N m, measured): the limit acts
    assert np.abs(np.diff(u_free, axis=0)).max() > 2 * max(step)


CELLS = [(0.0, 0.1), (60.0, 0.2), (-40.0, 0.3)]


# -- the relaxed start: the onset latency of a release -------------------------------------------

LEAN = np.array([np.radians(3.0), 0.0, 0.0, 0.0])  # a rigid forward lean, at rest
DELAYED = CONFIG.replace(scenario={"controller_delay": 0.1, "t_end": 1.0})


def test_a_relaxed_start_acts_one_delay_after_release():
    """With the measurements before t = 0 at rest, the reference's controller commands exactly
    0 until its delayed measurement reaches t = 0 (10 periods at 0.1 s), then torque, no faster
    than the rate limit; seeing the lean all along, it acts from the first period."""
    relaxed = DELAYED.replace(scenario={"relaxed_start": True})
    late = reference.simulate_scenario(relaxed, 0.0, 0.0, initial=LEAN)[1]
    early = reference.simulate_scenario(DELAYED, 0.0, 0.0, initial=LEAN)[1]
    substeps = DELAYED.scenario.substeps
    u_late = late[["u1", "u2"]].to_numpy()[::substeps]
    u_early = early[["u1", "u2"]].to_numpy()[::substeps]
    assert (u_late[:10] == 0).all() and np.abs(u_late[10]).max() > 0
    assert np.abs(u_early[0]).max() > 0
    step = np.array(DELAYED.controller.rate_steps(DELAYED.scenario.control_dt))
    assert (np.abs(np.diff(u_late, axis=0)) <= step * (1 + 1e-12)).all()


def test_a_relaxed_start_without_delay_is_the_plain_start():
    """At no delay the controller's first measurement is the state at t = 0 either way."""
    config = CONFIG.replace(scenario={"t_end": 0.5})
    a = reference.simulate_scenario(config, 0.0, 0.0, initial=LEAN)[0]
    b = reference.simulate_scenario(
        config.replace(scenario={"relaxed_start": True}), 0.0, 0.0, initial=LEAN
    )[0]
    assert a == b


def test_the_kernel_start_sees_rest_before_a_relaxed_release():
    """kernel.start: the measurement buffer (newest first) holds the initial state at t = 0
    and upright rest before it when relaxed; the initial state throughout when not."""
    from mjx_balance.rollout import kernel

    for relaxed in (False, True):
        config = DELAYED.replace(scenario={"relaxed_start": relaxed})
        runner = BatchRunner(config, physics="c", slots=4, devices=jax.local_devices()[:1])
        arrays = runner.arrays
        rest = kernel.initial_carry(arrays, runner.sensors, runner.static)
        carry = kernel.start(arrays, runner.sensors, rest, jnp.asarray(LEAN, jnp.float32))
        history = np.asarray(carry.history)
        assert history.shape[0] == config.scenario.delay_steps + 1
        assert np.array_equal(history[0], LEAN.astype(np.float32))
        before = (
            np.asarray(rest.history)[1:]
            if relaxed
            else np.tile(LEAN.astype(np.float32), (history.shape[0] - 1, 1))
        )
        assert np.array_equal(history[1:], before)
        assert not np.asarray(rest.history).any()  # rest: upright, still, exactly
        # what the controller measures at the first instant: rest when relaxed, else the lean
        pre = kernel.prepare(arrays, runner.static, carry)
        seen = not relaxed
        assert np.asarray(pre.x_meas).any() == seen


@pytest.mark.slow  # an MJX engine of its own (the delay is a static setting): ~25 s of compile
def test_batched_and_reference_relaxed_starts_alike():
    """Leans released with relaxed muscles, a 0.1-s onset and the rate limit: the MJX path (the
    kernel's start and controller; the C path starts at rest only) and the reference loop with
    the same float32 ADMM give the same outcomes and fall samples; the not-relaxed start
    recovers from leans the relaxed one cannot (the latency costs something, so the check can
    fail)."""
    leans = np.radians([1.0, 1.5, 2.5, 3.0])
    inits = np.zeros((leans.size, 4))
    inits[:, 0] = leans
    zeros = np.zeros(leans.size)
    relaxed = Config().replace(
        controller={"input_rates": [372.0, 372.0], "delay_compensation": True},
        scenario={"controller_delay": 0.1, "relaxed_start": True, "t_end": 2.0},
    )
    outcomes = {}
    for name, config in (
        ("relaxed", relaxed),
        ("seen", relaxed.replace(scenario={"relaxed_start": False})),
    ):
        runner = BatchRunner(
            config, physics="mjx", slots=4, early_stop=False, devices=jax.local_devices()[:1]
        )
        out = runner.run_frame(zeros, zeros, inits)
        outcomes[name] = list(out["outcome"])
        if name == "relaxed":
            mpc = AdmmMPC(runner)
            for b, init in enumerate(inits):
                ref = reference.simulate_scenario(
                    config, 0.0, 0.0, record=False, mpc=mpc, initial=init
                )[0]
                assert ref["outcome"] == outcomes[name][b], np.degrees(init[0])
                within(
                    out["fall_time"].iloc[b],
                    ref["fall_time"],
                    atol=1e-12,
                    why="the same fall sample (both compute its time as k dt)",
                )
    print(outcomes)
    assert outcomes["relaxed"] != outcomes["seen"]


# (slow: 8 s of the README's 5-minute run for the plain controller; the ADMM against OSQP on the
# tightened QP and the reference's limit stay in the default run)
@pytest.mark.slow
@pytest.mark.parametrize(
    "variant",
    [{}, {"offset_free": True}, {"infeasible": "exact_penalty"}],
    ids=["plain", "offset_free", "exact_penalty"],
)
def test_batched_and_reference_rate_limited_alike(variant):
    """The C path (the batched kernel's controller: its rate bounds, the ADMM) and the reference
    loop with the same float32 ADMM, for the plain MPC, the offset-free one (its deviation QP:
    the first input's bounds absolute, before the target's offset) and the exact penalty (hard
    input rows): the same outcomes and fall samples, energies within the float32 loop's
    rounding (margins.closed_loop_rounding, as the plain controller's)."""
    config = CONFIG.replace(controller=variant)
    runner = BatchRunner(
        config, physics="c", slots=4, early_stop=False, devices=jax.local_devices()[:1]
    )
    forces, durations = np.array(CELLS).T
    frame = runner.run_frame(forces, durations)
    outcomes = assert_cells_like_the_reference(config, frame, CELLS, AdmmMPC(runner))
    assert {"recovered", "fell"} <= set(outcomes)
