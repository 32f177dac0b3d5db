"""The closed loop of one scenario: MJX physics + the ADMM MPC in one ``lax.scan``, pure JAX.

One scenario is a pure function of (force, push steps) (:func:`scenario`):

    for k in 0..n_control-1:                       # outer lax.scan, control periods
        x_k = state_from_joints(measured joints)   # ``controller_delay`` earlier if set
        u_k = admm_solve(x_k, warm_k)              # warm_{k+1} = its shifted solution
        period_update(acc, solve)                  # saturation, solver statistics
        for j in 0..substeps-1:                    # inner lax.scan, physics steps i = k S + j
            advance(push if i < n_push)            # mjx.step + positions at t = (i+1) dt
            sample = measure(d)                    # joints, state, foot, load cells, CoP, CoM
            sample_update(acc, sample)             # fall test, settle band, peaks, energies

The per-scenario summary lives in the scan carry (:class:`Accumulators`), so a batch never
stores trajectories unless asked (``Static.trajectories``). The rules (fall, settle band,
saturation) are those of ``outcomes.py``, shared with the scalar reference. Batching is added
by the runner (``runner.py``); everything here is written for a single scenario, and the
update steps are plain functions of arrays that can be called without a compile.

Fall / divergence. From the first fall sample (or non-finite value) on, nothing accumulates.
The scenario keeps stepping (its slot runs until the engine harvests it, or to t_end in a
batch with trajectories), but at the next control instant its
physics state is reset to upright rest and the controller is fed x = 0 from a cold start, so a
dead scenario costs no extra ADMM or contact-solver iterations (``while_loop`` under ``vmap``
runs until the slowest element is done) and cannot produce NaN.

Times are carried as integer step indices and turned into seconds on the host in float64, so
``fall_time`` and ``settle_time`` are exactly (i + 1) dt as in the reference.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, TypeVar

import jax
import jax.numpy as jnp
import numpy as np

from ..control import admm as admm_mod
from ..control import law as law_mod
from ..model import linear as linear_mod
from ..control import offset_free as offset_free_mod
from ..control.qp import rate_bounds
from ..measures import capture, outcomes
from ..measures.outcomes import Limits
from .physics import advance, mjx, step
from .sensing import Sample, Sensors, joints, measure, measure_step, state, with_positions

Tree = TypeVar("Tree")  # a pytree (Arrays, a Carry) of arrays stacked per body


class Accumulators(NamedTuple):
    """The running summary of one scenario (scalars; steps are physics-step indices i)."""

    alive: jax.Array  # bool: not fallen and not diverged
    fell: jax.Array  # bool
    fall_step: jax.Array  # int32, -1 unless fell
    diverged: jax.Array  # bool
    last_outside: jax.Array  # int32, last step outside the settle band (-1: never)
    in_band: jax.Array  # bool, the latest sample is in the settle band
    peak_ankle: jax.Array
    peak_hip: jax.Array
    peak_foot_pitch: jax.Array
    cop_min: jax.Array
    cop_max: jax.Array
    com_min: jax.Array
    com_max: jax.Array
    peak_tau_ankle: jax.Array
    peak_tau_hip: jax.Array
    energy_ankle: jax.Array
    energy_hip: jax.Array
    work_ankle: jax.Array
    work_hip: jax.Array
    energy_u1: jax.Array
    energy_u2: jax.Array
    work_u1: jax.Array  # signed sum u_i Δx_i: the study's energy is its magnitude (eq. 20)
    work_u2: jax.Array
    max_bound_violation: jax.Array
    control_periods: jax.Array  # int32, periods counted (started before the fall)
    saturated_ankle: jax.Array  # int32, counted periods with u[0] at a bound
    saturated_hip: jax.Array  # int32
    nonconverged_solves: jax.Array  # int32
    max_residual: jax.Array
    admm_iterations: jax.Array  # int32, total over counted periods
    fall_cause: jax.Array  # int32 code into outcomes.FALL_CAUSES (0: none yet)
    first_infeasible: jax.Array  # int32, first counted period reported infeasible (-1: none)
    com_vel_min: jax.Array
    com_vel_max: jax.Array
    mos_toe_min: jax.Array  # smallest toe margin of stability (outcomes.stability_margins)
    mos_toe_step: jax.Array  # int32, the step of it (-1: none)
    mos_heel_min: jax.Array  # smallest heel margin
    mos_heel_step: jax.Array  # int32
    # the decision instant (measures/capture.py): the first sample whose 0-step capture margin
    # is negative, else the fall sample; its step (-1: none) and its capture point
    decision_step: jax.Array  # int32
    decision_xcom: jax.Array

    @staticmethod
    def initial(dtype) -> "Accumulators":
        def f(v):
            return jnp.asarray(v, dtype)

        i0 = jnp.zeros((), jnp.int32)
        inf = math.inf
        return Accumulators(
            alive=jnp.asarray(True),
            fell=jnp.asarray(False),
            fall_step=i0 - 1,
            diverged=jnp.asarray(False),
            last_outside=i0 - 1,
            in_band=jnp.asarray(True),
            peak_ankle=f(-inf),
            peak_hip=f(-inf),
            peak_foot_pitch=f(-inf),
            cop_min=f(inf),
            cop_max=f(-inf),
            com_min=f(inf),
            com_max=f(-inf),
            peak_tau_ankle=f(-inf),
            peak_tau_hip=f(-inf),
            energy_ankle=f(0),
            energy_hip=f(0),
            work_ankle=f(0),
            work_hip=f(0),
            energy_u1=f(0),
            energy_u2=f(0),
            work_u1=f(0),
            work_u2=f(0),
            max_bound_violation=f(0),
            control_periods=i0,
            saturated_ankle=i0,
            saturated_hip=i0,
            nonconverged_solves=i0,
            max_residual=f(-inf),
            admm_iterations=i0,
            fall_cause=i0 + outcomes.NO_CAUSE,
            first_infeasible=i0 - 1,
            com_vel_min=f(inf),
            com_vel_max=f(-inf),
            mos_toe_min=f(inf),
            mos_toe_step=i0 - 1,
            mos_heel_min=f(inf),
            mos_heel_step=i0 - 1,
            decision_step=i0 - 1,
            decision_xcom=f(math.nan),
        )


class Static(NamedTuple):
    """Everything about a configuration that is fixed under jit (hashable numbers/flags)."""

    n_control: int | None  # None in an engine's copy: it reads the traced Arrays.n_control
    substeps: int
    delay_steps: int  # how old the measurement is (physics steps)
    push_at_hip: bool
    settings: admm_mod.ADMMSettings
    trajectories: bool
    limits: Limits  # thresholds of the outcome rules; the bounds are Arrays.bounds (None here)
    compensate: bool = False  # delay compensation (linear.delay_predictor)
    offset_free: bool = False  # the disturbance observer and steady-state target
    # a controller of control/law.py in the MPC's place (None: the MPC, solved by admm.py);
    # its parameters are Arrays.law
    law: law_mod.Law | None = None


def split_limits(limits: Limits, dtype: Any) -> tuple[Limits, jax.Array]:
    """(the thresholds, static; the state and input bounds as a traced [4, 2] array: state
    lower, state upper, input lower, input upper). A subject's body scales its torque bounds;
    as arguments, not constants, they leave the compiled program the same for every body
    (``runner.BatchRunner._shape_key``)."""
    bounds = jnp.asarray(
        np.array(
            [limits.state_lower, limits.state_upper, limits.input_lower, limits.input_upper],
            np.float64,
        ),
        dtype,
    )
    return limits._replace(
        state_lower=None, state_upper=None, input_lower=None, input_upper=None
    ), bounds


def limits_of(arrays: "Arrays", static: Static) -> Limits:
    """The outcome rules' limits: the static thresholds with the traced bounds."""
    return static.limits._replace(
        state_lower=arrays.bounds[0],
        state_upper=arrays.bounds[1],
        input_lower=arrays.bounds[2],
        input_upper=arrays.bounds[3],
    )


class Arrays(NamedTuple):
    """Per-configuration arrays shared by every scenario of a batch (not vmapped)."""

    mx: mjx.Model
    d0: mjx.Data  # upright rest
    qp: admm_mod.ADMMData
    to_state: jax.Array  # [2, 2] convention positions y = to_state @ [q_a, q_h]
    torque_map: jax.Array  # [2, 2] [tau_ankle, tau_hip] = torque_map @ u
    pred_A: jax.Array  # [4, 4] the delay compensator's A_h^d (identity without one)
    pred_G: jax.Array  # [P, 4, 2] its input matrices (P = 0 without one)
    ofs: offset_free_mod.OffsetFree  # the offset-free controller's matrices (used if enabled)
    settled: jax.Array  # [nq] upright rest with the contact settled (model.mjcf.settled_rest)
    bounds: jax.Array  # [4, 2] the outcome rules' state and input bounds (split_limits)
    # [2] the most each input may change in a control period (controller.rate_steps; inf: no
    # rate limit): data, so one program serves bodies with and without a limit
    rate_step: jax.Array
    # bool []: a run from an initial state starts with relaxed muscles (scenario.relaxed_start):
    # the measurements before t = 0 are upright rest (:func:`start`)
    relaxed: jax.Array
    # [] physics steps over which a push rises linearly to its force (scenario.ramp_steps; 0:
    # a step, the study's): data, so one program serves both
    ramp_steps: jax.Array
    # [5] the step model's (cop_back, cop_front, push_gain, omega0, physics_dt), the decision
    # instant's (measures/capture.py, StepModel.data): a body's data
    capture: jax.Array
    # int32 []: control periods in the window (t_end / control_dt). The engines read this
    # traced value, so one compiled engine serves every t_end; the padded batch with
    # trajectories scans Static.n_control periods (its output's length) and so compiles per t_end.
    n_control: jax.Array
    # the parameters of Static.law (a pytree; () for the MPC): data, so a cohort's bodies,
    # each with its own, share one program
    law: Any = ()


# MuJoCo's bound on qpos, qvel, qacc and ctrl (mjMAXVAL): beyond it, or NaN, the C library
# warns of a bad value (mjWARN_BADQPOS/QVEL/QACC/CTRL) and resets the data, which the
# reference counts as divergence; a sample beyond it counts as not finite here.
MAX_VALUE = 1e10


class Carry(NamedTuple):
    d: mjx.Data
    warm: admm_mod.ADMMWarm
    history: jax.Array  # [delay+1, 4] joint (q, dq), newest first
    q_prev: jax.Array  # [2] joint angles at the previous sample
    x_prev: jax.Array  # [4] convention state at the previous sample
    acc: Accumulators
    inputs: jax.Array  # [P, 2] inputs applied in the last P control periods, newest first
    dist: jax.Array  # [2] offset-free: the disturbance estimate
    x_last: jax.Array  # [4] offset-free: the previous control instant's measured state
    u_last: jax.Array  # [2] offset-free: the input applied since
    law_state: Any = ()  # Static.law's own carried state (law.init), () for the MPC


def select(pred: jax.Array, a: Any, b: Any) -> Any:
    """Leaf by leaf, ``a`` where ``pred`` else ``b``; pred is a scalar, or [B] over the leading
    axis of batched leaves."""

    def pick(u, v):
        extra = (1,) * (jnp.ndim(u) - jnp.ndim(pred))
        return jnp.where(jnp.reshape(pred, jnp.shape(pred) + extra), u, v)

    return jax.tree_util.tree_map(pick, a, b)


def remember(history: jax.Array, s: Sample) -> jax.Array:
    """The controller's measurement buffer [delay+1, 4] with sample ``s`` as its newest."""
    return jnp.concatenate([jnp.concatenate([s.q, s.dq])[None], history[:-1]])


def cannot_hold(
    s: Sample, i: jax.Array, push: tuple[jax.Array, jax.Array, jax.Array] | None
) -> jax.Array:
    """Whether the feet in place can no longer hold the capture point after step ``i``
    (``capture.hold_margin`` < 0: the decision instant's test); ``push``: (force, push steps,
    ``Arrays.capture``), None: never (the decision is the fall sample)."""
    if push is None:
        return jnp.asarray(False)
    force, n_push, data = push
    remaining = (n_push - i - 1).astype(data.dtype) * data[4]
    return capture.hold_margin(jnp, s.xcom, force, remaining, data) < 0


def decision(acc: Accumulators, decides: jax.Array, s: Sample, i: jax.Array) -> dict:
    """The decision instant's accumulators, set at step ``i`` where ``decides``."""
    return {
        "decision_step": jnp.where(decides, i, acc.decision_step),
        "decision_xcom": jnp.where(decides, s.xcom, acc.decision_xcom),
    }


def sample_update(
    acc: Accumulators,
    s: Sample,
    i: jax.Array,
    torques: jax.Array,
    u: jax.Array,
    q_prev: jax.Array,
    x_prev: jax.Array,
    limits: Limits,
    *,
    push: tuple[jax.Array, jax.Array, jax.Array] | None = None,
) -> Accumulators:
    """Fold the sample of physics step ``i`` into the accumulators: divergence (a non-finite
    value, or one beyond MuJoCo's bound MAX_VALUE as in the reference), the fall test, the
    settle band, peaks, extremes, energies, the decision instant (``push``: :func:`cannot_hold`).
    ``torques`` / ``u`` are held during step i; ``q_prev`` / ``x_prev`` are the previous
    sample's. Nothing changes once the scenario is dead (fallen or diverged)."""
    excess = outcomes.bound_excess(jnp, s.x, limits)
    finite = (
        jnp.isfinite(s.q).all()
        & jnp.isfinite(s.dq).all()
        & jnp.isfinite(s.x).all()
        & jnp.isfinite(torques).all()
        & (s.magnitude <= MAX_VALUE)
    )
    ok = acc.alive & finite
    cause = outcomes.fall_cause(jnp, s.pitch, s.cell_low, excess, s.q[0], limits)
    falls = cause != outcomes.NO_CAUSE
    band = outcomes.in_settle_band(jnp, s.q, s.dq, limits)
    newly_fell = ok & falls

    def upd(old, new):
        return jnp.where(ok, new, old)

    power = torques * (s.q - q_prev)
    power_u = u * (s.x[:2] - x_prev[:2])
    loaded = ok & jnp.isfinite(s.cop)
    return acc._replace(
        alive=ok & ~falls,
        fell=acc.fell | newly_fell,
        fall_step=jnp.where(newly_fell, i, acc.fall_step),
        diverged=acc.diverged | (acc.alive & ~finite),
        fall_cause=jnp.where(
            newly_fell, cause, jnp.where(acc.alive & ~finite, outcomes.NON_FINITE, acc.fall_cause)
        ),
        last_outside=jnp.where(ok & ~band, i, acc.last_outside),
        in_band=band,
        peak_ankle=upd(acc.peak_ankle, jnp.maximum(acc.peak_ankle, jnp.abs(s.q[0]))),
        peak_hip=upd(acc.peak_hip, jnp.maximum(acc.peak_hip, jnp.abs(s.q[1]))),
        peak_foot_pitch=upd(
            acc.peak_foot_pitch, jnp.maximum(acc.peak_foot_pitch, jnp.abs(s.pitch))
        ),
        cop_min=jnp.where(loaded, jnp.minimum(acc.cop_min, s.cop), acc.cop_min),
        cop_max=jnp.where(loaded, jnp.maximum(acc.cop_max, s.cop), acc.cop_max),
        com_min=upd(acc.com_min, jnp.minimum(acc.com_min, s.com)),
        com_max=upd(acc.com_max, jnp.maximum(acc.com_max, s.com)),
        peak_tau_ankle=upd(
            acc.peak_tau_ankle, jnp.maximum(acc.peak_tau_ankle, jnp.abs(torques[0]))
        ),
        peak_tau_hip=upd(acc.peak_tau_hip, jnp.maximum(acc.peak_tau_hip, jnp.abs(torques[1]))),
        energy_ankle=upd(acc.energy_ankle, acc.energy_ankle + jnp.abs(power[0])),
        energy_hip=upd(acc.energy_hip, acc.energy_hip + jnp.abs(power[1])),
        work_ankle=upd(acc.work_ankle, acc.work_ankle + power[0]),
        work_hip=upd(acc.work_hip, acc.work_hip + power[1]),
        energy_u1=upd(acc.energy_u1, acc.energy_u1 + jnp.abs(power_u[0])),
        energy_u2=upd(acc.energy_u2, acc.energy_u2 + jnp.abs(power_u[1])),
        work_u1=upd(acc.work_u1, acc.work_u1 + power_u[0]),
        work_u2=upd(acc.work_u2, acc.work_u2 + power_u[1]),
        max_bound_violation=upd(
            acc.max_bound_violation, jnp.maximum(acc.max_bound_violation, excess)
        ),
        com_vel_min=upd(acc.com_vel_min, jnp.minimum(acc.com_vel_min, s.com_vel)),
        com_vel_max=upd(acc.com_vel_max, jnp.maximum(acc.com_vel_max, s.com_vel)),
        mos_toe_min=upd(acc.mos_toe_min, jnp.minimum(acc.mos_toe_min, s.mos_toe)),
        mos_toe_step=jnp.where(ok & (s.mos_toe < acc.mos_toe_min), i, acc.mos_toe_step),
        mos_heel_min=upd(acc.mos_heel_min, jnp.minimum(acc.mos_heel_min, s.mos_heel)),
        mos_heel_step=jnp.where(ok & (s.mos_heel < acc.mos_heel_min), i, acc.mos_heel_step),
        **decision(acc, ok & (acc.decision_step < 0) & (cannot_hold(s, i, push) | falls), s, i),
    )


def period_update(
    acc: Accumulators,
    res: "admm_mod.ADMMResult | LawResult",
    u: jax.Array,
    torques: jax.Array,
    limits: Limits,
    k: jax.Array,
) -> Accumulators:
    """Fold the solve of control period ``k`` into the accumulators (counted only while
    alive): a non-finite input or torque diverges the scenario; saturation, non-converged
    solves, the largest primal residual, the ADMM iterations and the first period whose QP
    the solver reported infeasible (its certificate, admm.py) are counted."""
    dtype = acc.max_residual.dtype
    alive = acc.alive
    finite = jnp.isfinite(u).all() & jnp.isfinite(torques).all()
    counted = alive
    saturated = outcomes.at_input_bound(jnp, u, limits)
    residual_ok = counted & jnp.isfinite(res.prim_res)
    first_infeasible = (
        counted & (res.status == admm_mod.PRIMAL_INFEASIBLE) & (acc.first_infeasible < 0)
    )
    return acc._replace(
        alive=alive & finite,
        diverged=acc.diverged | (counted & ~finite),
        fall_cause=jnp.where(counted & ~finite, outcomes.NON_FINITE, acc.fall_cause),
        first_infeasible=jnp.where(first_infeasible, k, acc.first_infeasible),
        control_periods=acc.control_periods + counted,
        saturated_ankle=acc.saturated_ankle + (counted & saturated[0]),
        saturated_hip=acc.saturated_hip + (counted & saturated[1]),
        nonconverged_solves=(acc.nonconverged_solves + (counted & (res.status != admm_mod.SOLVED))),
        max_residual=jnp.where(
            residual_ok, jnp.maximum(acc.max_residual, res.prim_res.astype(dtype)), acc.max_residual
        ),
        admm_iterations=acc.admm_iterations + jnp.where(counted, res.iters, 0),
    )


def initial_carry(arrays: Arrays, sensors: Sensors, static: Static) -> Carry:
    """Upright rest, a cold controller, fresh accumulators (every scenario starts here)."""
    dtype = arrays.d0.qpos.dtype
    q0, dq0 = joints(sensors, arrays.d0)
    history0 = jnp.tile(jnp.concatenate([q0, dq0])[None], (static.delay_steps + 1, 1))
    x0 = state(arrays, q0, dq0)
    return Carry(
        d=arrays.d0,
        warm=admm_mod.initial_warm(arrays.qp),
        history=history0,
        q_prev=q0,
        x_prev=x0,
        acc=Accumulators.initial(dtype),
        inputs=jnp.zeros((arrays.pred_G.shape[0], 2), dtype),
        dist=jnp.zeros(2, dtype),
        x_last=x0,
        u_last=jnp.zeros(2, dtype),
        law_state=() if static.law is None else static.law.init(arrays.law),
    )


def start(arrays: Arrays, sensors: Sensors, rest: Carry, init: jax.Array) -> Carry:
    """The carry of a scenario that starts from joint state ``init`` = [q_a, q_h, dq_a, dq_h]
    instead of upright rest (``rest``: :func:`initial_carry`): the foot settled on the floor
    (``arrays.settled``, as the reference), a cold controller, the measurement buffer full of the
    initial state (with ``arrays.relaxed``: the state at t = 0 only, rest before it, so that the
    controller first sees the initial state one delay later). init = 0 gives ``rest`` exactly
    (push scenarios start at qpos = 0)."""
    init = jnp.asarray(init, rest.x_prev.dtype)
    q, dq = init[:2], init[2:]
    qpos = jnp.where(jnp.any(init != 0), arrays.settled, rest.d.qpos)
    d = rest.d.replace(
        qpos=qpos.at[sensors.joints_q].set(q), qvel=rest.d.qvel.at[sensors.joints_v].set(dq)
    )
    x = state(arrays, q, dq)
    seen = jnp.broadcast_to(init, rest.history.shape)  # newest first: t = 0, then before it
    history = jnp.where(arrays.relaxed, rest.history.at[0].set(init), seen)
    return rest._replace(d=d, history=history, q_prev=q, x_prev=x, x_last=x)


class Prepared(NamedTuple):
    """A scenario's control instant before the solve (:func:`prepare`)."""

    carry: Carry  # after the reset of a dead scenario (``rest`` given)
    x0: jax.Array  # [4] the QP's state
    offset: Any  # [m] the offset-free QP's row offsets, or None
    x_meas: jax.Array  # [4]
    dist: jax.Array  # [2]
    alive: jax.Array  # bool
    first: jax.Array  # [2, 2] the first input's [lower, upper] this period (the rate limit)


def prepare(arrays: Arrays, static: Static, carry: Carry, rest: Carry | None = None) -> Prepared:
    """The MPC's state from the carry's (delayed) measurement, predicted to the control
    instant with delay compensation (``linear.predict``), x = 0 for a dead scenario;
    offset-free, the observer's update and the QP in deviation from the steady-state target
    (``offset_free.py``). With ``rest`` (:func:`initial_carry`), a dead scenario first restarts
    from rest with a cold controller (the MJX period; see the module docstring)."""
    dtype = arrays.d0.qpos.dtype
    alive = carry.acc.alive
    if rest is not None:
        carry = carry._replace(
            d=select(alive, carry.d, arrays.d0),
            warm=select(alive, carry.warm, rest.warm),
            law_state=select(alive, carry.law_state, rest.law_state),
        )
    measured = carry.history[static.delay_steps]
    x_meas = state(arrays, measured[:2], measured[2:])
    if static.compensate:
        x_meas = linear_mod.predict(jnp, arrays.pred_A, arrays.pred_G, x_meas, carry.inputs)
    x_meas = jnp.where(alive, x_meas, jnp.zeros(4, dtype))
    first = rate_bounds(jnp, carry.u_last, arrays.rate_step)  # the rate limit
    if static.offset_free:
        dist = offset_free_mod.observe(
            jnp, arrays.ofs, carry.dist, carry.x_last, carry.u_last, x_meas
        )
        x_s, _, _, offset = offset_free_mod.steady_state(jnp, arrays.ofs, dist)
        return Prepared(carry, x_meas - x_s, offset, x_meas, dist, alive, first)
    return Prepared(carry, x_meas, None, x_meas, carry.dist, alive, first)


class LawResult(NamedTuple):
    """A :data:`Static.law` controller's period in the fields of ``admm.ADMMResult`` that
    :func:`conclude` reads (its status as a solve's), and its next carried state."""

    u0: jax.Array  # [2] its input, limited to the input bounds and the rate limit
    status: jax.Array  # int32: admm.SOLVED or MAX_ITER (law.Status.converged)
    prim_res: jax.Array
    iters: jax.Array
    warm_next: admm_mod.ADMMWarm  # the carry's, unchanged
    law_state: Any


def act(arrays: Arrays, static: Static, pre: Prepared) -> LawResult:
    """:data:`Static.law`'s period at :func:`prepare`'s state: its input limited to the
    body's input bounds and the rate limit (``pre.first``), as the MPC's QP limits its own."""
    assert static.law is not None
    u, law_state, status = static.law.act(arrays.law, pre.x0, pre.carry.law_state)
    dtype = pre.x0.dtype
    u = jnp.asarray(u, dtype).reshape(2)
    return LawResult(
        u0=law_mod.limited(jnp, u, arrays.bounds[2], arrays.bounds[3], pre.first),
        status=jnp.where(
            jnp.asarray(status.converged, bool), admm_mod.SOLVED, admm_mod.MAX_ITER
        ).astype(jnp.int32),
        prim_res=jnp.asarray(status.residual, dtype),
        iters=jnp.asarray(status.iterations, jnp.int32),
        warm_next=pre.carry.warm,
        law_state=law_state,
    )


def solve(arrays: Arrays, static: Static, pre: Prepared) -> "admm_mod.ADMMResult | LawResult":
    """The MPC's QP at :func:`prepare`'s state, warm-started from the carry (or, with
    :data:`Static.law`, that controller's :func:`act`)."""
    if static.law is not None:
        return act(arrays, static, pre)
    return admm_mod.admm_solve(
        arrays.qp, pre.x0, pre.carry.warm, static.settings, pre.offset, pre.first
    )


def solve_batch(
    arrays: Arrays,
    static: Static,
    pre: Prepared,
    tile: int | None,
    tiles: tuple[admm_mod.ADMMData, jax.Array] | None = None,
) -> "admm_mod.ADMMResult | LawResult":
    """:func:`solve` over a batch of :func:`prepare` results, ``arrays.qp`` shared
    (``admm_solve_batch``: with ``tile``, sequential tiles of that many lanes, each stopping at
    its own slowest). ``tiles``: (the bodies' QPs stacked, each tile's body), every tile of
    ``tile`` lanes solving its body's QP (``admm_solve_tiles``; ``arrays.qp`` unused). With
    :data:`Static.law`, that controller's :func:`act` on every lane (``arrays`` per lane with
    ``tiles``, shared without)."""
    if static.law is not None:
        axis = None if tiles is None else 0
        return jax.vmap(lambda a, p: act(a, static, p), in_axes=(axis, 0))(arrays, pre)
    if tiles is not None:
        assert tile is not None  # (body tiles come with their lane count: engine.Engine.tile)
        return admm_mod.admm_solve_tiles(
            tiles[0],
            tiles[1],
            pre.x0,
            pre.carry.warm,
            static.settings,
            tile,
            offset=pre.offset,
            first=pre.first,
        )
    return admm_mod.admm_solve_batch(
        arrays.qp, pre.x0, pre.carry.warm, static.settings, tile, offset=pre.offset, first=pre.first
    )


def conclude(
    arrays: Arrays,
    static: Static,
    pre: Prepared,
    res: "admm_mod.ADMMResult | LawResult",
    k: jax.Array,
    rest: Carry | None = None,
) -> tuple[Carry, jax.Array, jax.Array]:
    """After the solve: the carry (next warm start, :func:`period_update` folded in, the input
    buffer, the observer's state), the input u [2] and the motor torques [2] to hold (zero if
    not finite). With ``rest``, a dead scenario's buffers start from rest."""
    dtype = arrays.d0.qpos.dtype
    carry = pre.carry
    u = res.u0.astype(dtype)
    torques = arrays.torque_map @ u
    acc = period_update(carry.acc, res, u, torques, limits_of(arrays, static), k)
    finite = jnp.isfinite(u).all() & jnp.isfinite(torques).all()
    u = jnp.where(finite, u, jnp.zeros_like(u))
    torques = jnp.where(finite, torques, jnp.zeros_like(torques))
    warm = admm_mod.ADMMWarm(*(w.astype(dtype) for w in res.warm_next))
    inputs = jnp.concatenate([u[None], carry.inputs[:-1]])[: carry.inputs.shape[0]]
    carry = carry._replace(
        warm=warm, acc=acc, inputs=inputs, dist=pre.dist, x_last=pre.x_meas, u_last=u
    )
    if isinstance(res, LawResult):  # (static.law's period)
        carry = carry._replace(law_state=res.law_state)
    if rest is not None:
        kept = select(
            pre.alive,
            (carry.history, carry.inputs, carry.dist, carry.x_last, carry.u_last, carry.law_state),
            (rest.history, rest.inputs, rest.dist, rest.x_last, rest.u_last, rest.law_state),
        )
        carry = carry._replace(
            history=kept[0],
            inputs=kept[1],
            dist=kept[2],
            x_last=kept[3],
            u_last=kept[4],
            law_state=kept[5],
        )
    return carry, u, torques


def period(
    arrays: Arrays,
    sensors: Sensors,
    static: Static,
    carry: Carry,
    k: jax.Array,
    force: jax.Array,
    n_push: jax.Array,
) -> tuple[Carry, dict[str, jax.Array] | None]:
    """Control period k of one scenario: the MPC solve, then ``static.substeps`` physics steps.

    Returns the carry and, with ``static.trajectories``, the period's per-step series [S, ...].
    """
    rest = initial_carry(arrays, sensors, static)
    pre = prepare(arrays, static, carry, rest)
    return advance_period(
        arrays, sensors, static, pre, solve(arrays, static, pre), k, force, n_push
    )


def period_batch(
    arrays: Arrays,
    sensors: Sensors,
    static: Static,
    carry: Carry,
    k: jax.Array,
    force: jax.Array,
    n_push: jax.Array,
    *,
    tile: int | None = None,
    axis: int | None = None,
    tiles: tuple[admm_mod.ADMMData, jax.Array] | None = None,
) -> tuple[Carry, dict[str, jax.Array] | None]:
    """:func:`period` of a batch of scenarios (every argument but ``arrays`` with a leading batch
    axis), the QPs solved by :func:`solve_batch` (``tile``: lanes per ADMM loop). ``axis``
    None: ``arrays`` shared by every lane; 0: one body per lane (every leaf [B, ...], the
    engine's lanes; see :func:`lane_arrays`), the QPs then by ``tiles`` of ``tile`` lanes
    (:func:`solve_batch`)."""
    if axis is not None and tiles is None:
        raise ValueError("per-lane bodies (axis 0) solve their QPs by body tiles (tiles=)")
    rest = rest_of(arrays, sensors, static, axis)
    pre = prepare_batch(arrays, static, carry, rest, axis)
    res = solve_batch(arrays, static, pre, tile, tiles)
    carry, u, torques = conclude_batch(arrays, static, pre, res, k, rest, axis)
    return physics_batch(
        arrays, sensors, static, carry, k, force, n_push, torques=torques, u=u, axis=axis
    )


def rest_of(arrays: Arrays, sensors: Sensors, static: Static, axis: int | None = None) -> Carry:
    """:func:`initial_carry` of shared ``arrays`` (axis None), or of each lane's (axis 0)."""
    if axis is None:
        return initial_carry(arrays, sensors, static)
    return jax.vmap(lambda a: initial_carry(a, sensors, static), in_axes=(axis,))(arrays)


def lane_arrays(bodies: Tree, body: jax.Array) -> Tree:
    """Each lane's body: ``bodies`` stacked [n_bodies, ...] gathered at ``body`` [B] (int)."""
    return jax.tree.map(lambda v: v[body], bodies)


def prepare_batch(
    arrays: Arrays, static: Static, carry: Carry, rest: Carry | None = None, axis: int | None = None
) -> Prepared:
    """:func:`prepare` over a batch of carries (``rest``: one carry, shared; with ``axis`` 0,
    ``arrays`` and ``rest`` per lane)."""
    if rest is None:
        return jax.vmap(lambda a, c: prepare(a, static, c), in_axes=(axis, 0))(arrays, carry)
    return jax.vmap(
        lambda a, c, r: prepare(a, static, c, r), in_axes=(axis, 0, None if axis is None else 0)
    )(arrays, carry, rest)


def solve_lanes(arrays: Arrays, static: Static, pre: Prepared) -> "admm_mod.ADMMResult | LawResult":
    """:func:`solve` vmapped over a batch of :func:`prepare` results (the C path's solve)."""
    return jax.vmap(lambda p: solve(arrays, static, p))(pre)


def conclude_batch(
    arrays: Arrays,
    static: Static,
    pre: Prepared,
    res: "admm_mod.ADMMResult | LawResult",
    k: jax.Array,
    rest: Carry | None = None,
    axis: int | None = None,
) -> tuple[Carry, jax.Array, jax.Array]:
    """:func:`conclude` over a batch (``rest``: one carry, shared; with ``axis`` 0,
    ``arrays`` and ``rest`` per lane)."""
    if rest is None:
        return jax.vmap(lambda a, p, r, k: conclude(a, static, p, r, k), in_axes=(axis, 0, 0, 0))(
            arrays, pre, res, k
        )
    return jax.vmap(
        lambda a, p, r, k, rest: conclude(a, static, p, r, k, rest),
        in_axes=(axis, 0, 0, 0, None if axis is None else 0),
    )(arrays, pre, res, k, rest)


def physics_batch(
    arrays: Arrays,
    sensors: Sensors,
    static: Static,
    carry: Carry,
    k: jax.Array,
    force: jax.Array,
    n_push: jax.Array,
    *,
    torques: jax.Array,
    u: jax.Array,
    axis: int | None = None,
) -> tuple[Carry, dict[str, jax.Array] | None]:
    """:func:`physics_period` over a batch (``axis`` 0: ``arrays`` per lane)."""
    return jax.vmap(
        lambda a, c, k, f, n, t, u: physics_period(a, sensors, static, c, k, f, n, torques=t, u=u),
        in_axes=(axis, 0, 0, 0, 0, 0, 0),
    )(arrays, carry, k, force, n_push, torques, u)


def advance_period(
    arrays: Arrays,
    sensors: Sensors,
    static: Static,
    pre: Prepared,
    res: "admm_mod.ADMMResult | LawResult",
    k: jax.Array,
    force: jax.Array,
    n_push: jax.Array,
) -> tuple[Carry, dict[str, jax.Array] | None]:
    """:func:`period` after the solve: :func:`conclude` (a dead scenario restarts from rest with
    a cold controller; see the module docstring), then :func:`physics_period`."""
    carry, u, torques = conclude(
        arrays, static, pre, res, k, initial_carry(arrays, sensors, static)
    )
    return physics_period(arrays, sensors, static, carry, k, force, n_push, torques=torques, u=u)


def physics_period(
    arrays: Arrays,
    sensors: Sensors,
    static: Static,
    carry: Carry,
    k: jax.Array,
    force: jax.Array,
    n_push: jax.Array,
    *,
    torques: jax.Array,
    u: jax.Array,
) -> tuple[Carry, dict[str, jax.Array] | None]:
    """The ``static.substeps`` physics steps of control period k with ``torques`` held (u: the
    input they come from), each sample folded into the accumulators; with
    ``static.trajectories``, the per-step series [S, ...]."""
    dtype = arrays.d0.qpos.dtype
    S = static.substeps

    limits, pushed = limits_of(arrays, static), (force, n_push, arrays.capture)

    def fold(carry: Carry, s: Sample, i: jax.Array) -> Carry:
        """Carry after the complete sample ``s`` of physics step ``i``."""
        acc = sample_update(
            carry.acc, s, i, torques, u, carry.q_prev, carry.x_prev, limits, push=pushed
        )
        return carry._replace(q_prev=s.q, x_prev=s.x, acc=acc)

    def push(i: jax.Array) -> jax.Array:
        """The push at step i: its force (times the ramp's share while it rises), 0 after."""
        ramp = arrays.ramp_steps
        share = jnp.minimum((i + 1).astype(dtype) / jnp.maximum(ramp, 1), 1)
        on = jnp.where(ramp > 0, force * share, force)  # without a ramp exactly the force
        return jnp.where(i < n_push, on, jnp.zeros((), dtype))

    def record(carry: Carry, d: mjx.Data, s: Sample) -> Carry:
        """The new physics state and the controller's (delayed) measurement buffer."""
        return carry._replace(d=d, history=remember(carry.history, s))

    def physics_step(carry: Carry, i: jax.Array):
        """Step i, then its sample: positions from an extra ``mjx.kinematics``."""
        d = advance(arrays.mx, sensors, carry.d, torques, push(i), static.push_at_hip)
        s = measure(arrays, sensors, d)
        carry = fold(record(carry, d, s), s, i)
        out = None
        if static.trajectories:  # NaN from the fall sample on (the run is reset)
            out = dict(qpos=d.qpos, qvel=d.qvel, tau=torques, u=u, cop=s.cop, com=s.com)
            out = {k: jnp.where(carry.acc.alive, v, jnp.nan).astype(dtype) for k, v in out.items()}
        return carry, out

    def lean_step(state: tuple[Carry, Sample], i: jax.Array):
        """Step i; the positions its start computed complete sample i - 1 (``pending``,
        folded unless i starts the period), and sample i waits for the next step's."""
        carry, pending = state
        d = step(arrays.mx, sensors, carry.d, torques, push(i), static.push_at_hip)
        folded = fold(carry, with_positions(pending, arrays, sensors, d), i - 1)
        kept = select(
            i > k * S,
            (folded.acc, folded.q_prev, folded.x_prev),
            (carry.acc, carry.q_prev, carry.x_prev),
        )
        carry = carry._replace(acc=kept[0], q_prev=kept[1], x_prev=kept[2])
        s = measure_step(arrays, sensors, d)
        return (record(carry, d, s), s), None

    steps = k * S + jnp.arange(S, dtype=jnp.int32)
    if static.trajectories or static.push_at_hip:
        # the series are read step by step, and the push at the hip needs the positions at
        # the step's start: one mjx.kinematics per step
        return jax.lax.scan(physics_step, carry, steps)
    # lean: a sample's positions are those the next step computes at its start; the period's
    # last sample takes them from one mjx.kinematics, so no sample is pending between periods
    (carry, last), _ = jax.lax.scan(
        lean_step, (carry, measure_step(arrays, sensors, carry.d)), steps
    )
    positions = mjx.kinematics(arrays.mx, carry.d)
    return fold(carry, with_positions(last, arrays, sensors, positions), steps[-1]), None


def scenario(
    arrays: Arrays, sensors: Sensors, static: Static, force: jax.Array, n_push: jax.Array
) -> tuple[Accumulators, dict[str, jax.Array] | None]:
    """Run one scenario to t_end; pure, jit-able (``sensors``, ``static`` static). force: [] N;
    n_push: [] int.

    Returns the final accumulators and, with ``static.trajectories``, per-physics-step series
    (qpos [n, nq], qvel [n, nv], tau [n, 2], u [n, 2], cop [n], com [n]; sample i is at
    t = (i+1) dt; NaN from the fall sample on, which the reference's series still holds).
    """
    dtype = arrays.d0.qpos.dtype
    force = jnp.asarray(force, dtype)
    n_push = jnp.asarray(n_push, jnp.int32)

    def control_period(carry: Carry, k: jax.Array):
        return period(arrays, sensors, static, carry, k, force, n_push)

    assert static.n_control is not None  # (the runner's own Static: its window's length)
    carry, series = jax.lax.scan(
        control_period,
        initial_carry(arrays, sensors, static),
        jnp.arange(static.n_control, dtype=jnp.int32),
    )
    if series is not None:
        S = static.substeps
        series = {k: v.reshape((static.n_control * S,) + v.shape[2:]) for k, v in series.items()}
    return carry.acc, series
