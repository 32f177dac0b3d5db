"""Scalar reference closed loop: MuJoCo C physics (``mujoco.mj_step``) + OSQP MPC.

One scenario at a time, plain Python loops, float64 throughout. Everything the batched JAX path
computes is checked against this module.

Timing (shared definitions). Physics step dt = scenario.physics_dt, control period
scenario.control_dt, substeps = control_dt / dt. At each control instant t_k = k control_dt the
controller measures the joint state, converts it to the convention state, solves the condensed
QP (``qp.py``) and holds the first input, clipped to its bounds, as motor torques for
``substeps`` physics steps. The push (force along x, see ``push_wrench``) acts during physics
steps i < ceil(T / dt - 1e-9). The run starts at upright rest and stops at the first fall sample
or non-finite value (the rules of ``outcomes.py``).

Sensorimotor delay (scenario.controller_delay = D, d = D / dt physics steps): the controller at
t_k sees the joint state (q_a, q_h, dq_a, dq_h) of time t_k - D, i.e. the state after physics
step k * substeps - d; before t = 0 that is the initial state (upright rest, or the run's
``initial`` state, held there until t = 0: the controller sees it from its first period). The
plant, the push and the metrics run undelayed; d = 0 is the undelayed loop. With
scenario.delay_error the measurement is really D + delay_error old while a compensating
controller assumes D. With controller.delay_compensation the controller predicts the state at
t_k from its measurement and the inputs it applied since (``linear.delay_predictor``, over the D
it assumes) and solves the MPC for the prediction; the batched path does the same
(``rollout.kernel.prepare``).
"""

from __future__ import annotations

import functools
import sys
import threading
from typing import Any, Iterator, Protocol

import mujoco
import numpy as np
import pandas as pd

from ..measures import capture, metrics, outcomes
from ..control import law as law_mod
from ..control import offset_free as offset_free_mod
from ..model.linear import delay_predictor, predict
from ..model.mjcf import build_model, indices, settled_rest
from ..control.osqp_mpc import ReferenceMPC
from ..measures.outcomes import SUMMARY_COLUMNS, Limits
from ..model.params import BodyParams, Config, ControllerParams, push_steps
from ..control.qp import CondensedQP, build_qp, rate_bounds
from ..runtime import signals

TIMESERIES_COLUMNS = [
    "scenario",
    "force",
    "duration",
    "convention",
    "time",
    "q_a",
    "q_h",
    "dq_a",
    "dq_h",
    "x1",
    "x2",
    "x3",
    "x4",
    "foot_x",
    "foot_z",
    "foot_pitch",
    "u1",
    "u2",
    "tau_ankle",
    "tau_hip",
    "cop",
    "com",
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "study_energy_u1",
    "study_energy_u2",
    "study_energy_total",
    "com_vel",
    "xcom",
    "mos",
]


def push_wrench(data: mujoco.MjData, upper: int, force: float, push_body: str) -> np.ndarray:
    """The push as ``xfrc_applied`` of the upper body [6] (force, torque; MuJoCo applies it at
    the body's CoM ``xipos``), from the current kinematics in ``data``.

    "upper": force (F, 0, 0) at the upper body's CoM, no torque. "hip": the same force at the
    hip joint point (the upper body's frame origin ``xpos``), i.e. force F plus the moment
    (xpos - xipos) x F about the CoM. A force through the hip axis does no work on the hip
    joint, so applying it to the upper or to the lower body there is the same generalised force.
    """
    wrench = np.zeros(6)
    wrench[0] = force
    if push_body == "hip":
        wrench[3:] = np.cross(data.xpos[upper] - data.xipos[upper], wrench[:3])
    elif push_body != "upper":
        raise ValueError(f"push_body must be 'upper' or 'hip', got {push_body!r}")
    return wrench


class MPC(Protocol):
    """What the closed loop needs of a controller (``osqp_mpc.ReferenceMPC`` is one)."""

    qp: CondensedQP

    def reset(self) -> None:
        """Forget the warm start: scenarios do not depend on each other."""

    def solve(
        self, x0: np.ndarray, offset: np.ndarray | None = None, first: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, bool, float]:
        """(u [2] clipped first input, iterate, converged, primal residual) for state x0
        (``first`` [2, 2]: the first input's own [lower, upper], the rate limit)."""


def reference_mpc(
    controller: ControllerParams, body: BodyParams, control_dt: float
) -> ReferenceMPC:
    """The OSQP controller of a configuration, built once per thread and configuration: an
    OSQP solver holds its problem's data and iterates, so two threads solving on one at once
    corrupt it (explore computes cells' runs side by side)."""
    return _reference_mpc(controller, body, control_dt, threading.get_ident())


@functools.lru_cache(maxsize=8)
def _reference_mpc(
    controller: ControllerParams, body: BodyParams, control_dt: float, _thread: int
) -> ReferenceMPC:
    return ReferenceMPC(build_qp(controller, body, control_dt), controller)


class LawReference:
    """A controller of control/law.py in the scalar reference (``controller.kind`` other than
    "mpc"): the batched path's ``act`` jitted once, unbatched, fed the reference's state in
    JAX's default float; its input limited to the input bounds and the rate limit as the
    batched path limits it (``rollout.kernel.act``). No QP: nothing is tested for
    infeasibility."""

    hard_infeasible = False

    def __init__(self, controller: law_mod.Controller, qp: CondensedQP, limits: Limits):
        import jax
        import jax.numpy as jnp

        self.qp, self.law = qp, controller.law
        self.dtype = jnp.zeros(()).dtype
        self.params = law_mod.cast(controller.params, self.dtype)
        self.lower = np.asarray(limits.input_lower, float)
        self.upper = np.asarray(limits.input_upper, float)
        self._act = jax.jit(controller.law.act)
        self.reset()

    def reset(self) -> None:
        self.state = self.law.init(self.params)

    def solve(
        self, x0: np.ndarray, offset: np.ndarray | None = None, first: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, bool, float]:
        import jax.numpy as jnp

        u, self.state, status = self._act(self.params, jnp.asarray(x0, self.dtype), self.state)
        u = law_mod.limited(np, np.asarray(u, float).reshape(2), self.lower, self.upper, first)
        return u, u, bool(status.converged), float(status.residual)  # (no iterate but u)


def reference_controller(config: Config) -> "MPC":
    """The reference's controller of ``config``: OSQP on the MPC's QP
    (:func:`reference_mpc`), or the configuration's controller of control/law.py
    (:class:`LawReference`)."""
    ctrl, body, sc = config.controller, config.body, config.scenario
    made = law_mod.controller_of(config)
    if made is None:
        return reference_mpc(ctrl, body, sc.control_dt)
    return LawReference(made, build_qp(ctrl, body, sc.control_dt), Limits.from_params(sc, ctrl))


# MuJoCo's checks of non-finite or huge values; each resets the data when it fires.
_BAD_VALUE_WARNINGS = tuple(
    int(w)
    for w in (
        mujoco.mjtWarning.mjWARN_BADQPOS,
        mujoco.mjtWarning.mjWARN_BADQVEL,
        mujoco.mjtWarning.mjWARN_BADQACC,
        mujoco.mjtWarning.mjWARN_BADCTRL,
    )
)


def _bad_value_warnings(data: mujoco.MjData) -> int:
    """How many times MuJoCo has warned of a bad (NaN, Inf or huge) value in this data."""
    return sum(int(data.warning[w].number) for w in _BAD_VALUE_WARNINGS)


@functools.lru_cache(maxsize=8)
def _model(body, physics_dt: float) -> mujoco.MjModel:
    return build_model(body, physics_dt, foot="free")


def _initial_data(model: mujoco.MjModel, ix: Any, initial: Any) -> mujoco.MjData:
    """MuJoCo data at the run's start: upright rest, or the joint state ``initial`` [4]
    (q_a, q_h, dq_a, dq_h) with the foot as at rest (model.mjcf.settled_rest); kinematics done."""
    data = mujoco.MjData(model)
    if initial is not None and np.any(initial):  # the foot settled (model.mjcf.settled_rest)
        data.qpos[:] = settled_rest(model)
        data.qpos[[ix.ankle_qpos, ix.hip_qpos]] = np.asarray(initial, float)[:2]
        data.qvel[[ix.ankle_dof, ix.hip_dof]] = np.asarray(initial, float)[2:]
    mujoco.mj_forward(model, data)
    return data


class _Series:
    """The series of one run, filled as it goes. Samples (index i: after physics step i, time
    (i+1) dt): time [n], q, dq [n, 2], x [n, 4], foot [n, 3] (x, z, pitch), cell_low [n, 4],
    cop, com, com_vel [n], cell_x [n, 4], tau, u [n, 2]. Control periods (index k):
    u_control [K, 2], converged, infeasible [K] bool, residual [K]. The joint history for a
    delayed measurement:
    history_q, history_dq [n + 1, 2], entry j the state at t = j dt. q0 [2], x0 [4]: the
    state at t = 0 (joint state q0, dq0 [2])."""

    def __init__(
        self, n_steps: int, n_control: int, dt: float, q0: np.ndarray, dq0: np.ndarray, lm: Any
    ):
        self.time = (np.arange(n_steps) + 1) * dt
        self.q = np.zeros((n_steps, 2))
        self.dq = np.zeros((n_steps, 2))
        self.x = np.zeros((n_steps, 4))
        self.foot = np.zeros((n_steps, 3))
        self.cell_low = np.zeros((n_steps, 4))
        self.cop = np.zeros(n_steps)
        self.com = np.zeros(n_steps)
        self.com_vel = np.zeros(n_steps)
        self.cell_x = np.zeros((n_steps, 4))
        self.tau = np.zeros((n_steps, 2))
        self.u = np.zeros((n_steps, 2))
        self.u_control = np.zeros((n_control, 2))
        self.converged = np.zeros(n_control, bool)
        self.infeasible = np.zeros(n_control, bool)
        self.residual = np.zeros(n_control)
        self.history_q = np.zeros((n_steps + 1, 2))
        self.history_dq = np.zeros((n_steps + 1, 2))
        self.history_q[0] = q0
        self.history_dq[0] = dq0
        self.q0 = self.history_q[0].copy()
        self.x0 = lm.state_from_joints(self.q0, self.history_dq[0])


class _Controller:
    """The controller side of the loop (see the module docstring): the measurement, delayed
    by scenario.delay_steps; with delay compensation, the prediction from the inputs applied
    since (``applied`` [P, 2], the last P periods' inputs, newest first: linear.predict);
    with offset-free MPC, the disturbance estimate and the previous measurement and input
    (offset_free.py); the rate limit's bounds on the first input around the last one applied
    (``controller.input_rates``); the MPC solve."""

    def __init__(self, mpc: MPC, ctrl: ControllerParams, sc: Any, lm: Any, x0: np.ndarray):
        self.mpc, self.lm = mpc, lm
        self.substeps, self.delay_steps = sc.substeps, sc.delay_steps
        self.relaxed = sc.relaxed_start  # measurements before t = 0: upright rest
        self.compensate = ctrl.delay_compensation and sc.assumed_delay_steps > 0
        if self.compensate:
            self.pred_A, self.pred_G = delay_predictor(
                lm.Ac, lm.Bc, sc.physics_dt, sc.assumed_delay_steps, sc.substeps
            )
            self.applied = np.zeros((self.pred_G.shape[0], 2))
        self.ofs = offset_free_mod.build(mpc.qp, ctrl) if ctrl.offset_free else None
        self.d_hat, self.x_last, self.u_last = np.zeros(2), x0.copy(), np.zeros(2)
        # the most each input may change in a period (None: no rate limit)
        self.rate_step = (
            None if ctrl.input_rates is None else np.array(ctrl.rate_steps(sc.control_dt))
        )

    def act(self, k: int, series: _Series) -> tuple[np.ndarray, bool, float, bool]:
        """(u [2] clipped first input, converged, primal residual, whether an unsolved QP is
        infeasible) at control instant k, from the joint history in ``series``."""
        s = k * self.substeps - self.delay_steps
        if s < 0 and self.relaxed:  # before t = 0 a relaxed start's controller saw rest
            x_meas = self.lm.state_from_joints(np.zeros(2), np.zeros(2))
        else:
            s = max(s, 0)
            x_meas = self.lm.state_from_joints(series.history_q[s], series.history_dq[s])
        if self.compensate:
            x_meas = predict(np, self.pred_A, self.pred_G, x_meas, self.applied)
        offset = None
        if self.ofs is not None:
            self.d_hat = offset_free_mod.observe(
                np, self.ofs, self.d_hat, self.x_last, self.u_last, x_meas
            )
            x_s, _, _, offset = offset_free_mod.steady_state(np, self.ofs, self.d_hat)
            self.x_last, x_meas = x_meas, x_meas - x_s
        mpc = self.mpc
        extra: dict[str, np.ndarray] = {} if offset is None else {"offset": offset}
        first = None
        if self.rate_step is not None:  # the input applied since the last instant, +- a step
            first = rate_bounds(np, self.u_last, self.rate_step)
            extra["first"] = first
        u, _, ok, prim_res = mpc.solve(x_meas, **extra)
        self.u_last = u
        if self.compensate:
            self.applied = np.concatenate([u[None], self.applied[:-1]])
        # a QP the solver did not solve: is it infeasible (an exact LP test, run only here,
        # unless the exact penalty's solve ran it already)?
        hard = getattr(mpc, "hard_infeasible", None)  # a controller without the LP test: None
        if hard is not None:
            infeasible = hard
        else:
            infeasible = (
                not ok and np.isfinite(x_meas).all() and not mpc.qp.feasible(x_meas, offset, first)
            )
        return u, ok, prim_res, infeasible


def _record(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    ix: Any,
    lm: Any,
    series: _Series,
    i: int,
    *,
    torques: np.ndarray,
    u: np.ndarray,
) -> None:
    """Sample i into ``series``: positions refreshed to t = (i+1) dt, contacts and forces
    those of step i; the torques [2] and input u [2] held during step i."""
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    q, dq = series.q, series.dq
    q[i] = data.qpos[[ix.ankle_qpos, ix.hip_qpos]]
    dq[i] = data.qvel[[ix.ankle_dof, ix.hip_dof]]
    series.history_q[i + 1], series.history_dq[i + 1] = q[i], dq[i]
    series.x[i] = lm.state_from_joints(q[i], dq[i])
    series.foot[i] = data.qpos[[ix.foot_x, ix.foot_z, ix.foot_pitch]]
    series.cell_low[i] = metrics.cell_heights(model, data, ix.cell_geoms)
    series.cop[i] = metrics.load_cell_cop(model, data, ix.cell_geoms)[0]
    series.com[i] = metrics.whole_body_com(data, ix.foot_body)
    series.com_vel[i] = metrics.com_velocity(model, data, ix.foot_body)
    series.cell_x[i] = metrics.cell_x(data, ix.cell_geoms)
    series.tau[i], series.u[i] = torques, u


def _closed_loop(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    ix: Any,
    series: _Series,
    controller: _Controller,
    *,
    force: float,
    n_push: int,
    sc: Any,
    limits: Limits,
) -> tuple[int, int, bool]:
    """Run the control periods from ``data`` until t_end, the first fall sample or a
    non-finite value, filling ``series``; the push acts during physics steps i < n_push.
    Returns (samples taken, control periods done, diverged)."""
    lm, upper = controller.lm, ix.upper_body
    n = 0  # samples taken
    k_done = 0
    stop = False
    diverged = False
    for k in range(sc.n_control):
        signals.check()  # a signal ends the run within one period, also in another thread
        u, ok, prim_res, infeasible = controller.act(k, series)
        torques = lm.motor_torques(u)
        series.u_control[k], series.converged[k], series.residual[k] = u, ok, prim_res
        series.infeasible[k] = infeasible
        k_done = k + 1
        if not (np.isfinite(u).all() and np.isfinite(torques).all()):
            diverged = True
            break
        data.ctrl[:] = torques
        for j in range(sc.substeps):
            i = k * sc.substeps + j
            push = (
                push_wrench(data, upper, force * sc.ramp_factor(i), sc.push_body)
                if i < n_push
                else 0.0
            )
            data.xfrc_applied[upper] = push
            warned = _bad_value_warnings(data)
            mujoco.mj_step(model, data)
            if _bad_value_warnings(data) > warned:
                # MuJoCo met a NaN/Inf/huge value and reset the data to the model's initial
                # state: what follows would be a fresh start from rest, not this scenario.
                diverged = True
                stop = True
                break
            _record(model, data, ix, lm, series, i, torques=torques, u=u)
            n = i + 1
            if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
                diverged = True
                stop = True
                break
            if outcomes.falls(
                np,
                series.foot[i, 2],
                series.cell_low[i],
                outcomes.bound_excess(np, series.x[i], limits),
                series.q[i, 0],
                limits,
            ):
                stop = True
                break
        if stop:
            break
    data.xfrc_applied[upper] = 0.0
    return n, k_done, diverged


def simulate_scenario(
    config: Config,
    force: float,
    duration: float,
    *,
    record: bool = True,
    scenario_id: int = 0,
    mpc: MPC | None = None,
    initial: Any = None,
) -> tuple[dict[str, Any], pd.DataFrame | None]:
    """Run one push scenario; return (summary row, long time series or None).

    ``force`` [N] (+ forward) and ``duration`` [s] override config.scenario's; the summary row
    has the keys ``outcomes.SUMMARY_COLUMNS``; the time series has ``TIMESERIES_COLUMNS``, one
    row per physics step (time = (i+1) dt), ending at the fall sample if the body fell.
    ``mpc``: the controller (default: :func:`reference_controller`, OSQP for the MPC); it
    is reset first.
    ``initial``: the initial joint state [q_a, q_h, dq_a, dq_h] (default upright rest; the
    foot as at rest), as the batched engine's per-scenario initial state.
    """
    config = config.replace(scenario={"force": float(force), "duration": float(duration)})
    body, ctrl, sc = config.body, config.controller, config.scenario
    model = _model(body, sc.physics_dt)
    if mpc is None:
        mpc = reference_controller(config)
    mpc.reset()
    limits = Limits.from_params(sc, ctrl)
    lm = mpc.qp.linear
    ix = indices(model)
    data = _initial_data(model, ix, initial)

    n_steps = sc.n_control * sc.substeps
    s = _Series(
        n_steps,
        sc.n_control,
        sc.physics_dt,
        data.qpos[[ix.ankle_qpos, ix.hip_qpos]],
        data.qvel[[ix.ankle_dof, ix.hip_dof]],
        lm,
    )
    n, k_done, diverged = _closed_loop(
        model,
        data,
        ix,
        s,
        _Controller(mpc, ctrl, sc, lm, s.x0),
        force=force,
        n_push=int(push_steps(duration, sc.physics_dt)),
        sc=sc,
        limits=limits,
    )

    sl = slice(0, n)
    xcom, mos = margin_series(model, ix, force, s.com[sl], s.com_vel[sl], s.cell_x[sl])
    summary = _summary_of(
        s,
        config,
        force,
        duration,
        n,
        k_done,
        completed=(n == n_steps),
        diverged=diverged,
        mos=mos,
        xcom=xcom,
    )
    if not record:
        return summary, None

    frame = _frame_of(s, scenario_id, force, duration, ctrl.convention, n)
    frame["com_vel"], frame["xcom"], frame["mos"] = s.com_vel[sl], xcom, mos
    return summary, frame


def _summary_of(
    s: _Series,
    config: Config,
    force: float,
    duration: float,
    n: int,
    k_done: int,
    *,
    completed: bool,
    diverged: bool,
    mos: np.ndarray,
    xcom: np.ndarray,
) -> dict[str, Any]:
    """The run's summary row (``metrics.summarize``) of its first n samples and k_done periods."""
    sc, ctrl = config.scenario, config.controller
    sl = slice(0, n)
    return metrics.summarize(
        force=force,
        duration=duration,
        convention=ctrl.convention,
        scenario=sc,
        controller=ctrl,
        time=s.time[sl],
        q=s.q[sl],
        dq=s.dq[sl],
        x=s.x[sl],
        foot_pitch=s.foot[sl, 2],
        cell_low_z=s.cell_low[sl],
        cop=s.cop[sl],
        com=s.com[sl],
        tau=s.tau[sl],
        u=s.u[sl],
        q0=s.q0,
        x0=s.x0,
        u_control=s.u_control[:k_done],
        converged=s.converged[:k_done],
        residual=s.residual[:k_done],
        completed=completed,
        diverged=diverged,
        infeasible=s.infeasible[:k_done],
        com_vel=s.com_vel[sl],
        mos=mos,
        xcom=xcom,
        steps=capture.step_model(config),
    )


def _frame_of(
    s: _Series, scenario_id: int, force: float, duration: float, convention: str, n: int
) -> pd.DataFrame:
    """The run's time series (:func:`timeseries_frame`) of its first ``n`` samples."""
    sl = slice(0, n)
    return timeseries_frame(
        scenario_id,
        force,
        duration,
        convention,
        q0=s.q0,
        x0=s.x0,
        time=s.time[sl],
        q=s.q[sl],
        dq=s.dq[sl],
        x=s.x[sl],
        foot=s.foot[sl],
        u=s.u[sl],
        tau=s.tau[sl],
        cop=s.cop[sl],
        com=s.com[sl],
    )


def margin_series(
    model: mujoco.MjModel,
    ix: Any,
    force: float,
    com: np.ndarray,
    com_vel: np.ndarray,
    cell_x: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(XcoM [n], margin of stability [n]) of a run's samples (docs/model.md): the toe margin
    for a push with force >= 0, the heel margin for a backward one."""
    omega0 = metrics.pendulum_frequency(model, ix.foot_body, ix.ankle_dof)
    heel, toe = outcomes.support_edges(np, cell_x)
    xcom, mos_toe, mos_heel = outcomes.stability_margins(np, com, com_vel, heel, toe, omega0)
    return xcom, (mos_toe if force >= 0 else mos_heel)


def timeseries_frame(
    scenario_id: int,
    force: float,
    duration: float,
    convention: str,
    *,
    q0: np.ndarray,
    x0: np.ndarray,
    time: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    x: np.ndarray,
    foot: np.ndarray,
    u: np.ndarray,
    tau: np.ndarray,
    cop: np.ndarray,
    com: np.ndarray,
) -> pd.DataFrame:
    """The long time series of one run (TIMESERIES_COLUMNS, one row per sample), with the
    cumulative joint energies of the motors sum |tau dq| from q0 [2] and the study's (eq. 20,
    docs/model.md) |sum u_i dx_i| of the convention's pairs from x0 [4]. Series [n]: time, cop,
    com; [n, 2]: q, dq, u, tau; x [n, 4]; foot [n, 3] (x, z, pitch)."""
    n = time.shape[0]
    energy = np.cumsum(np.abs(tau * metrics.increments(q0, q)), axis=0)
    study = np.abs(np.cumsum(u * metrics.increments(x0[:2], x[:, :2]), axis=0))
    return pd.DataFrame(
        {
            "scenario": np.full(n, scenario_id, dtype=np.int64),
            "force": np.full(n, float(force)),
            "duration": np.full(n, float(duration)),
            "convention": convention,
            "time": time,
            "q_a": q[:, 0],
            "q_h": q[:, 1],
            "dq_a": dq[:, 0],
            "dq_h": dq[:, 1],
            "x1": x[:, 0],
            "x2": x[:, 1],
            "x3": x[:, 2],
            "x4": x[:, 3],
            "foot_x": foot[:, 0],
            "foot_z": foot[:, 1],
            "foot_pitch": foot[:, 2],
            "u1": u[:, 0],
            "u2": u[:, 1],
            "tau_ankle": tau[:, 0],
            "tau_hip": tau[:, 1],
            "cop": cop,
            "com": com,
            "energy_ankle": energy[:, 0],
            "energy_hip": energy[:, 1],
            "energy_total": energy[:, 0] + energy[:, 1],
            "study_energy_u1": study[:, 0],
            "study_energy_u2": study[:, 1],
            "study_energy_total": study[:, 0] + study[:, 1],
        },
        columns=TIMESERIES_COLUMNS,
    )


# --- many scenarios -------------------------------------------------------------------------


def simulate_many(
    config: Config, forces: list[float], durations: list[float], *, progress: bool = True
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every (force, duration) of the cross product, every force for the first duration, then
    the next: (summary table, long time series)."""
    return simulate_pairs(config, [(f, T) for T in durations for f in forces], progress=progress)


def simulate_pairs(
    config: Config, pairs: list[tuple[float, float]], *, progress: bool = True
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The given (force, duration) pairs in their order: (summary table, long time series,
    scenario_id = the pair's index)."""
    rows, frames = [], []
    for _, summary, frame in each_pair(config, pairs, progress=progress):
        rows.append(summary)
        frames.append(frame)
    summary = pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
    return summary, pd.concat(frames, ignore_index=True)


def each_pair(
    config: Config, pairs: list[tuple[float, float]], *, skip: Any = (), progress: bool = True
) -> Iterator[tuple[int, dict[str, Any], pd.DataFrame]]:
    """Run the pairs in their order, but those whose index is in ``skip`` (finished before):
    yield (scenario_id = the pair's index, summary row, time series) as each ends. Every
    duration is checked before anything runs."""
    from tqdm import tqdm

    for _, T in pairs:  # validate every duration before running anything
        config.replace(scenario={"duration": T})
    skip = set(skip)
    with tqdm(
        total=len(pairs),
        initial=len(skip),
        desc="scenarios",
        unit="scenario",
        disable=not progress,
        file=sys.stderr,
    ) as bar:
        for scenario_id, (force, duration) in enumerate(pairs):
            if scenario_id in skip:
                continue
            signals.check()  # a checkpoint: a signal dropped where it landed ends the run
            summary, frame = simulate_scenario(config, force, duration, scenario_id=scenario_id)
            bar.update(1)
            yield scenario_id, summary, frame
