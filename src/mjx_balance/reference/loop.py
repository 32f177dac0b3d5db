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
step k * substeps - d; before t = 0 that is the initial upright rest state. The plant, the push
and the metrics run undelayed; d = 0 is the undelayed loop. With scenario.delay_error the
measurement is really D + delay_error old while a compensating controller assumes D. With
controller.delay_compensation the controller predicts the state at t_k from its measurement
and the inputs it applied since (``linear.delay_predictor``, over the D it assumes) and solves
the MPC for the prediction; the batched path does the same (``rollout.kernel.control``).
"""

from __future__ import annotations

import functools
import math
import sys
from typing import Any, Protocol

import mujoco
import numpy as np
import pandas as pd

from ..measures import metrics, outcomes
from ..control import offset_free as offset_free_mod
from ..model.linear import delay_predictor, predict
from ..model.mjcf import build_model, indices, settled_rest
from ..control.osqp_mpc import ReferenceMPC
from ..measures.outcomes import SUMMARY_COLUMNS, Limits
from ..model.params import BodyParams, Config, ControllerParams
from ..control.qp import CondensedQP, build_qp

TIMESERIES_COLUMNS = [
    "scenario", "force", "duration", "convention", "time",
    "q_a", "q_h", "dq_a", "dq_h", "x1", "x2", "x3", "x4",
    "foot_x", "foot_z", "foot_pitch", "u1", "u2", "tau_ankle", "tau_hip", "cop", "com",
    "energy_ankle", "energy_hip", "energy_total",
    "study_energy_u1", "study_energy_u2", "study_energy_total",
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

    def solve(self, x0: np.ndarray, offset: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, bool, float]:
        """(u [2] clipped first input, iterate, converged, primal residual) for state x0."""


@functools.lru_cache(maxsize=8)
def reference_mpc(controller: ControllerParams, body: BodyParams,
                  control_dt: float) -> ReferenceMPC:
    """The OSQP controller of a configuration (built once per process and configuration)."""
    return ReferenceMPC(build_qp(controller, body, control_dt), controller)


# MuJoCo's checks of non-finite or huge values; each resets the data when it fires.
_BAD_VALUE_WARNINGS = tuple(int(w) for w in (
    mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADCTRL))


def _bad_value_warnings(data: mujoco.MjData) -> int:
    """How many times MuJoCo has warned of a bad (NaN, Inf or huge) value in this data."""
    return sum(int(data.warning[w].number) for w in _BAD_VALUE_WARNINGS)


@functools.lru_cache(maxsize=8)
def _model(body, physics_dt: float) -> mujoco.MjModel:
    return build_model(body, physics_dt, foot="free")


def simulate_scenario(config: Config, force: float, duration: float, *, record: bool = True,
                      scenario_id: int = 0, mpc: MPC | None = None,
                      initial: Any = None) -> tuple[dict[str, Any], pd.DataFrame | None]:
    """Run one push scenario; return (summary row, long time series or None).

    ``force`` [N] (+ forward) and ``duration`` [s] override config.scenario's; the summary row
    has the keys ``outcomes.SUMMARY_COLUMNS``; the time series has ``TIMESERIES_COLUMNS``, one
    row per physics step (time = (i+1) dt), ending at the fall sample if the body fell.
    ``mpc``: the controller (default: OSQP, :func:`reference_mpc`); it is reset first.
    ``initial``: the initial joint state [q_a, q_h, dq_a, dq_h] (default upright rest; the
    foot as at rest), as the batched engine's per-scenario initial state.
    """
    config = config.replace(scenario={"force": float(force), "duration": float(duration)})
    body, ctrl, sc = config.body, config.controller, config.scenario
    model = _model(body, sc.physics_dt)
    if mpc is None:
        mpc = reference_mpc(ctrl, body, sc.control_dt)
    mpc.reset()
    limits = Limits.from_params(sc, ctrl)
    lm = mpc.qp.linear
    ix = indices(model)
    data = mujoco.MjData(model)
    if initial is not None and np.any(initial):  # the foot settled (model.settled_rest)
        data.qpos[:] = settled_rest(model)
        data.qpos[[ix.ankle_qpos, ix.hip_qpos]] = np.asarray(initial, float)[:2]
        data.qvel[[ix.ankle_dof, ix.hip_dof]] = np.asarray(initial, float)[2:]
    mujoco.mj_forward(model, data)

    dt, substeps, n_control = sc.physics_dt, sc.substeps, sc.n_control
    n_steps = n_control * substeps
    n_push = math.ceil(duration / dt - 1e-9)
    joints_q = [ix.ankle_qpos, ix.hip_qpos]
    joints_v = [ix.ankle_dof, ix.hip_dof]
    upper = ix.upper_body

    # sample buffers (index i: after physics step i)
    time = (np.arange(n_steps) + 1) * dt
    q = np.zeros((n_steps, 2))
    dq = np.zeros((n_steps, 2))
    x = np.zeros((n_steps, 4))
    foot = np.zeros((n_steps, 3))
    cell_low = np.zeros((n_steps, 4))
    cop = np.zeros(n_steps)
    com = np.zeros(n_steps)
    tau = np.zeros((n_steps, 2))
    u_step = np.zeros((n_steps, 2))
    u_control = np.zeros((n_control, 2))
    converged = np.zeros(n_control, bool)
    infeasible = np.zeros(n_control, bool)
    residual = np.zeros(n_control)
    # joint history for a delayed measurement: entry j is the state at t = j dt
    history_q = np.zeros((n_steps + 1, 2))
    history_dq = np.zeros((n_steps + 1, 2))
    history_q[0] = data.qpos[joints_q]
    history_dq[0] = data.qvel[joints_v]
    q0 = history_q[0].copy()
    x0 = lm.state_from_joints(q0, history_dq[0])

    # delay compensation: the inputs of the last P periods, newest first (linear.predict)
    compensate = ctrl.delay_compensation and sc.assumed_delay_steps > 0
    if compensate:
        pred_A, pred_G = delay_predictor(lm.Ac, lm.Bc, dt, sc.assumed_delay_steps, substeps)
        applied = np.zeros((pred_G.shape[0], 2))
    # offset-free: the disturbance estimate, the previous measurement and input (offset_free.py)
    ofs = offset_free_mod.build(mpc.qp, ctrl) if ctrl.offset_free else None
    d_hat, x_last, u_last = np.zeros(2), x0.copy(), np.zeros(2)

    n = 0  # samples taken
    k_done = 0
    stop = False
    diverged = False
    for k in range(n_control):
        s = max(k * substeps - sc.delay_steps, 0)
        x_meas = lm.state_from_joints(history_q[s], history_dq[s])
        if compensate:
            x_meas = predict(np, pred_A, pred_G, x_meas, applied)
        offset = None
        if ofs is not None:
            d_hat = offset_free_mod.observe(np, ofs, d_hat, x_last, u_last, x_meas)
            x_s, _, _, offset = offset_free_mod.steady_state(np, ofs, d_hat)
            x_last, x_meas = x_meas, x_meas - x_s
        u, _, ok, prim_res = mpc.solve(x_meas) if offset is None else mpc.solve(x_meas, offset)
        u_last = u
        if compensate:
            applied = np.concatenate([u[None], applied[:-1]])
        torques = lm.motor_torques(u)
        u_control[k], converged[k], residual[k] = u, ok, prim_res
        # a QP the solver did not solve: is it infeasible (an exact LP test, run only here)?
        infeasible[k] = (not ok and np.isfinite(x_meas).all()
                         and not mpc.qp.feasible(x_meas, offset))
        k_done = k + 1
        if not (np.isfinite(u).all() and np.isfinite(torques).all()):
            diverged = True
            break
        data.ctrl[:] = torques
        for j in range(substeps):
            i = k * substeps + j
            push = push_wrench(data, upper, force, sc.push_body) if i < n_push else 0.0
            data.xfrc_applied[upper] = push
            warned = _bad_value_warnings(data)
            mujoco.mj_step(model, data)
            if _bad_value_warnings(data) > warned:
                # MuJoCo met a NaN/Inf/huge value and reset the data to the model's initial
                # state: what follows would be a fresh start from rest, not this scenario.
                diverged = True
                stop = True
                break
            # positions at t = (i+1) dt; contacts/forces stay those of step i
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            q[i] = data.qpos[joints_q]
            dq[i] = data.qvel[joints_v]
            history_q[i + 1], history_dq[i + 1] = q[i], dq[i]
            x[i] = lm.state_from_joints(q[i], dq[i])
            foot[i] = data.qpos[[ix.foot_x, ix.foot_z, ix.foot_pitch]]
            cell_low[i] = metrics.cell_heights(model, data, ix.cell_geoms)
            cop[i] = metrics.load_cell_cop(model, data, ix.cell_geoms)[0]
            com[i] = metrics.whole_body_com(data, ix.foot_body)
            tau[i], u_step[i] = torques, u
            n = i + 1
            if not (np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()):
                diverged = True
                stop = True
                break
            if outcomes.falls(np, foot[i, 2], cell_low[i], outcomes.bound_excess(np, x[i], limits),
                              q[i, 0], limits):
                stop = True
                break
        if stop:
            break
    data.xfrc_applied[upper] = 0.0

    sl = slice(0, n)
    summary = metrics.summarize(
        force=force, duration=duration, convention=ctrl.convention, scenario=sc, controller=ctrl,
        time=time[sl], q=q[sl], dq=dq[sl], x=x[sl], foot_pitch=foot[sl, 2],
        cell_low_z=cell_low[sl], cop=cop[sl], com=com[sl], tau=tau[sl], u=u_step[sl],
        q0=q0, x0=x0, u_control=u_control[:k_done], converged=converged[:k_done],
        residual=residual[:k_done], completed=(n == n_steps), diverged=diverged,
        infeasible=infeasible[:k_done],
    )
    if not record:
        return summary, None

    frame = timeseries_frame(scenario_id, force, duration, ctrl.convention, q0, time[sl],
                             q[sl], dq[sl], x[sl], foot[sl], u_step[sl], tau[sl], cop[sl],
                             com[sl], x0=x0)
    return summary, frame


def timeseries_frame(scenario_id: int, force: float, duration: float, convention: str,
                     q0: np.ndarray, time: np.ndarray, q: np.ndarray, dq: np.ndarray,
                     x: np.ndarray, foot: np.ndarray, u: np.ndarray, tau: np.ndarray,
                     cop: np.ndarray, com: np.ndarray, *, x0: np.ndarray) -> pd.DataFrame:
    """The long time series of one run (TIMESERIES_COLUMNS, one row per sample), with the
    cumulative joint energies of the motors sum |tau dq| from q0 and the study's (eq. 20,
    docs/model.md) |sum u_i dx_i| of the convention's pairs from x0 [4]. foot: [n, 3] (x, z,
    pitch)."""
    n = time.shape[0]
    energy = np.cumsum(np.abs(tau * metrics.increments(q0, q)), axis=0)
    study = np.abs(np.cumsum(u * metrics.increments(x0[:2], x[:, :2]), axis=0))
    return pd.DataFrame({
        "scenario": np.full(n, scenario_id, dtype=np.int64),
        "force": np.full(n, float(force)),
        "duration": np.full(n, float(duration)),
        "convention": convention,
        "time": time,
        "q_a": q[:, 0], "q_h": q[:, 1], "dq_a": dq[:, 0], "dq_h": dq[:, 1],
        "x1": x[:, 0], "x2": x[:, 1], "x3": x[:, 2], "x4": x[:, 3],
        "foot_x": foot[:, 0], "foot_z": foot[:, 1], "foot_pitch": foot[:, 2],
        "u1": u[:, 0], "u2": u[:, 1],
        "tau_ankle": tau[:, 0], "tau_hip": tau[:, 1],
        "cop": cop, "com": com,
        "energy_ankle": energy[:, 0], "energy_hip": energy[:, 1],
        "energy_total": energy[:, 0] + energy[:, 1],
        "study_energy_u1": study[:, 0], "study_energy_u2": study[:, 1],
        "study_energy_total": study[:, 0] + study[:, 1],
    }, columns=TIMESERIES_COLUMNS)


# --- many scenarios -------------------------------------------------------------------------


def simulate_many(config: Config, forces: list[float], durations: list[float], *,
                  progress: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every (duration, force) pair: (summary table, long time series)."""
    from tqdm import tqdm

    pairs = [(f, T) for T in durations for f in forces]
    for _, T in pairs:  # validate every duration before running anything
        config.replace(scenario={"duration": T})
    rows, frames = [], []
    for scenario_id, (force, duration) in enumerate(
            tqdm(pairs, desc="scenarios", unit="scenario", disable=not progress,
                 file=sys.stderr)):
        summary, frame = simulate_scenario(config, force, duration, scenario_id=scenario_id)
        rows.append(summary)
        frames.append(frame)
    summary = pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
    return summary, pd.concat(frames, ignore_index=True)
