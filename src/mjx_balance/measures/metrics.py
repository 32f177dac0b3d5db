"""Measurements of one closed-loop run from MuJoCo C data, and its summary row (numpy).

The scalar reference (``reference/loop.py``) samples a run with the functions of the first section
and turns the sample series into one summary row with :func:`summarize`; the outcome rules
(fall, settle band, saturation, classification) are those of ``outcomes.py``, shared with the
batched closed loop.

Samples. Metrics are evaluated after every physics step i = 0..n-1, at time t = (i+1) dt. Joint
angles, foot pose, load-cell heights and the CoM are those of the state at t (the reference
refreshes positions with ``mj_kinematics`` + ``mj_comPos`` after ``mj_step``); the load-cell
forces are the contact forces that acted during step i (as ``mj_step`` leaves them in ``data``).
Everything is accumulated up to and including the first fall sample and nothing after it;
control periods count if their control instant lies before the fall sample's time.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from . import capture, outcomes
from .outcomes import DIVERGED, FELL, OUTCOMES, RECOVERED, Limits
from ..model.params import ControllerParams, ScenarioParams


# --- measurements from MuJoCo C data -------------------------------------------------------


def load_cell_cop(
    model: mujoco.MjModel, data: mujoco.MjData, cell_geoms: tuple[int, ...]
) -> tuple[float, float]:
    """(CoP x, total normal force) from the contacts that involve a load-cell geom.

    CoP = sum F_i x_i / sum F_i (the study's eq. 18), F_i the contact normal force
    (``mj_contactForce``, first component of the contact frame), x_i the contact point's world x.
    NaN when the load cells carry no load (sum F_i <= 0).
    """
    cells = set(cell_geoms)
    wrench = np.zeros(6)
    moment = 0.0
    total = 0.0
    for i in range(data.ncon):
        contact = data.contact[i]
        if contact.geom1 in cells or contact.geom2 in cells:
            mujoco.mj_contactForce(model, data, i, wrench)
            moment += wrench[0] * contact.pos[0]
            total += wrench[0]
    return (moment / total if total > 0 else math.nan), total


def whole_body_com(data: mujoco.MjData, foot_body: int) -> float:
    """Horizontal CoM of the whole body (the foot's subtree), world x (the study's eq. 19)."""
    return float(data.subtree_com[foot_body, 0])


def com_velocity(model: mujoco.MjModel, data: mujoco.MjData, foot_body: int) -> float:
    """Horizontal velocity of the whole-body CoM (the foot's subtree): the subtree's CoM
    Jacobian at the positions in ``data`` (``mj_jacSubtreeCom``, needs ``mj_comPos``) times
    qvel."""
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jacSubtreeCom(model, data, jacp, foot_body)
    return float(jacp[0] @ data.qvel)


def cell_x(data: mujoco.MjData, cell_geoms: tuple[int, ...]) -> np.ndarray:
    """World x of each load-cell sphere's centre [4] (over a flat floor, its contact point's)."""
    return np.array(data.geom_xpos[list(cell_geoms), 0])


def pendulum_frequency(model: mujoco.MjModel, foot_body: int, ankle_dof: int) -> float:
    """omega0 = sqrt(g / l) of the extrapolated CoM: l the whole-body CoM's height above the
    ankle axis at upright rest (qpos = 0), g the model's gravity."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    ankle = int(model.dof_jntid[ankle_dof])
    length = float(data.subtree_com[foot_body, 2] - data.xanchor[ankle, 2])
    return math.sqrt(abs(float(model.opt.gravity[2])) / length)


def cell_heights(
    model: mujoco.MjModel, data: mujoco.MjData, cell_geoms: tuple[int, ...]
) -> np.ndarray:
    """Lowest point (centre z - radius) of each load-cell sphere [4]."""
    cells = list(cell_geoms)
    return data.geom_xpos[cells, 2] - model.geom_size[cells, 0]


# --- rules over a series ----------------------------------------------------------------


def settle_time(time: np.ndarray, q: np.ndarray, dq: np.ndarray, limits: Limits) -> float:
    """Time of the last sample outside the settle band (0.0 if never outside)."""
    outside = ~outcomes.in_settle_band(np, np.asarray(q), np.asarray(dq), limits)
    if not outside.any():
        return 0.0
    return float(np.asarray(time)[np.flatnonzero(outside)[-1]])


def saturation_fractions(u: np.ndarray, limits: Limits) -> tuple[float, float]:
    """Fraction of control periods with each input at a bound (outcomes.at_input_bound).
    u: [K, 2]; NaN when K = 0."""
    u = np.asarray(u, float).reshape(-1, 2)
    if u.shape[0] == 0:
        return math.nan, math.nan
    at_bound = outcomes.at_input_bound(np, u, limits)
    return float(np.mean(at_bound[:, 0])), float(np.mean(at_bound[:, 1]))


# --- the summary row -----------------------------------------------------------------------


def study_energies(work_u1, work_u2) -> dict[str, Any]:
    """The study's joint energy (its eq. 20, docs/model.md) from the signed work of the
    convention's pairs, W_i = sum u_i Δx_i (∫ u_i dx_i): ``work_u1``, ``work_u2`` themselves,
    ``study_energy_u1/u2`` = |W_i| (a recovery's signed work is negative; the study reports its
    magnitude) and ``study_energy_total`` = |W_1| + |W_2|. Floats or numpy arrays (summary
    columns of the reference and of the batched paths alike)."""
    e1, e2 = abs(work_u1), abs(work_u2)
    return {
        "work_u1": work_u1,
        "work_u2": work_u2,
        "study_energy_u1": e1,
        "study_energy_u2": e2,
        "study_energy_total": e1 + e2,
    }


def increments(initial: np.ndarray, series: np.ndarray) -> np.ndarray:
    """Per-sample increments of ``series`` [n, ...] starting from ``initial`` [...]."""
    return np.diff(np.concatenate([np.asarray(initial)[None], series]), axis=0)


def _nanmax_abs(values: np.ndarray) -> float:
    values = np.abs(np.asarray(values, float))
    values = values[np.isfinite(values)]
    return float(values.max()) if values.size else math.nan


def _finite_min_max(values: np.ndarray) -> tuple[float, float]:
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if not values.size:
        return math.nan, math.nan
    return float(values.min()), float(values.max())


def _balance_columns(
    time: np.ndarray, com_vel: np.ndarray | None, mos: np.ndarray | None, end: int
) -> dict[str, Any]:
    """CoM velocity extremes and the smallest margin of stability (the push direction's,
    docs/model.md) with its time, over the first ``end`` samples; NaN without the series."""
    nan = np.full(time.shape[0], math.nan)
    vel = np.asarray(nan if com_vel is None else com_vel, float)[:end]
    margin = np.asarray(nan if mos is None else mos, float)[:end]
    vel_min, vel_max = _finite_min_max(vel)
    finite = np.isfinite(margin)
    at = int(np.argmin(np.where(finite, margin, np.inf))) if finite.any() else -1
    return {
        "com_vel_min": vel_min,
        "com_vel_max": vel_max,
        "mos_min": float(margin[at]) if at >= 0 else math.nan,
        "mos_min_time": float(time[at]) if at >= 0 else math.nan,
    }


def _first_fall(
    time: np.ndarray,
    q: np.ndarray,
    x: np.ndarray,
    foot_pitch: np.ndarray,
    cell_low_z: np.ndarray,
    limits: Limits,
) -> tuple[np.ndarray, bool, int, float]:
    """(bound excess [n] of the states x [n, 4], fell, samples kept ``end`` (up to and
    including the first fall sample; n if none), fall time (NaN if none)) of the series."""
    n = time.shape[0]
    excess = outcomes.bound_excess(np, x, limits) if n else np.zeros(0)  # [n]
    flags = (
        outcomes.falls(np, foot_pitch, cell_low_z, excess, q[:, 0], limits)
        if n
        else np.zeros(0, bool)
    )
    fell = bool(flags.any())
    end = int(np.flatnonzero(flags)[0]) + 1 if fell else n  # samples kept: [0, end)
    fall_time = float(time[end - 1]) if fell else math.nan
    return excess, fell, end, fall_time


def _diverged(
    diverged: bool, q: np.ndarray, dq: np.ndarray, tau: np.ndarray, x: np.ndarray, u_control
) -> bool:
    """Whether the run diverged: said so (``diverged``) or a non-finite sample or input."""
    finite = (
        np.isfinite(q).all(axis=-1)
        & np.isfinite(dq).all(axis=-1)
        & np.isfinite(tau).all(axis=-1)
        & np.isfinite(x).all(axis=-1)
    )
    return bool(diverged or not finite.all() or not np.isfinite(np.asarray(u_control, float)).all())


def _outcome_code(
    completed: bool,
    diverged: bool,
    fell: bool,
    time: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    limits: Limits,
) -> int:
    """The run's outcome code (an OUTCOMES index) from its divergence, its fall and its end."""
    n = time.shape[0]
    settled = bool(completed and n and outcomes.in_settle_band(np, q[-1:], dq[-1:], limits)[0])
    return int(outcomes.classify(np, diverged, fell, settled and not fell))


def _outcome_columns(
    force: float, duration: float, convention: str, code: int, settle: float, fall_time: float
) -> dict[str, Any]:
    """The row's first columns: the push, the convention, the outcome and its times."""
    return {
        "force": float(force),
        "duration": float(duration),
        "convention": convention,
        "outcome": OUTCOMES[code],
        "settle_time": settle,
        "fall_time": fall_time if code == FELL else math.nan,
    }


def _peak_columns(
    q: np.ndarray, foot_pitch: np.ndarray, tau: np.ndarray, cop, com, end: int
) -> dict[str, float]:
    """The peak angles and torques and the CoP's and CoM's ranges of the samples before ``end``."""
    sl = slice(0, end)
    cop_min, cop_max = _finite_min_max(np.asarray(cop, float)[sl])
    com_min, com_max = _finite_min_max(np.asarray(com, float)[sl])
    return {
        "peak_ankle": _nanmax_abs(q[sl, 0]),
        "peak_hip": _nanmax_abs(q[sl, 1]),
        "peak_foot_pitch": _nanmax_abs(foot_pitch[sl]),
        "cop_min": cop_min,
        "cop_max": cop_max,
        "com_min": com_min,
        "com_max": com_max,
        "peak_tau_ankle": _nanmax_abs(tau[sl, 0]),
        "peak_tau_hip": _nanmax_abs(tau[sl, 1]),
    }


def _max_violation(excess: np.ndarray, end: int) -> float:
    """The largest finite bound excess of the samples before ``end`` (0: none)."""
    excess = excess[slice(0, end)]
    excess = excess[np.isfinite(excess)]
    return float(excess.max()) if excess.size else 0.0


def _control_columns(
    u_control: np.ndarray,
    converged: np.ndarray,
    residual: np.ndarray,
    infeasible: np.ndarray | None,
    *,
    fell: bool,
    fall_time: float,
    control_dt: float,
    limits: Limits,
) -> tuple[float, float, int, float, float]:
    """(ankle and hip saturation fractions, non-converged solves, max residual, first
    infeasible time) of the control periods [K] whose instant precedes the fall sample."""
    n_ctrl = len(u_control)
    if fell:
        n_ctrl = min(n_ctrl, int(math.ceil(fall_time / control_dt - 1e-9)))
    u_control = np.asarray(u_control, float)[:n_ctrl]
    converged = np.asarray(converged, bool)[:n_ctrl]
    residual = np.asarray(residual, float)[:n_ctrl]
    infeasible = (
        np.zeros(n_ctrl, bool) if infeasible is None else np.asarray(infeasible, bool)[:n_ctrl]
    )
    first_infeasible = (
        float(np.flatnonzero(infeasible)[0] * control_dt) if infeasible.any() else math.nan
    )
    saturation_ankle, saturation_hip = saturation_fractions(u_control, limits)
    res = residual[np.isfinite(residual)]
    return (
        saturation_ankle,
        saturation_hip,
        int(np.count_nonzero(~converged)),
        float(res.max()) if res.size else math.nan,
        first_infeasible,
    )


def _fall_cause(
    code: int,
    end: int,
    foot_pitch: np.ndarray,
    cell_low_z: np.ndarray,
    excess: np.ndarray,
    q: np.ndarray,
    limits: Limits,
) -> int:
    """The fall cause (outcomes.FALL_CAUSES index) of a run of outcome ``code``: that of the
    fall sample end - 1 for a fall."""
    if code == DIVERGED:
        return outcomes.NON_FINITE
    if code == FELL:
        return int(
            outcomes.fall_cause(
                np, foot_pitch[end - 1], cell_low_z[end - 1], excess[end - 1], q[end - 1, 0], limits
            )
        )
    return outcomes.NO_CAUSE


def _energy_columns(
    q0: np.ndarray,
    x0: np.ndarray,
    q: np.ndarray,
    x: np.ndarray,
    tau: np.ndarray,
    u: np.ndarray,
    end: int,
) -> dict[str, Any]:
    """The energy and work columns of the first ``end`` samples: the motors' sum |tau dq|
    and sum tau dq from q0 [2], the convention's pairs' sum |u_i dx_i| and the study's
    (:func:`study_energies`) from x0 [4]."""
    sl = slice(0, end)
    dq_step = increments(q0, q)[sl]
    dx_step = increments(x0, x)[sl]
    tau_k, u_k = tau[sl], u[sl]
    power_ankle = tau_k[:, 0] * dq_step[:, 0]
    power_hip = tau_k[:, 1] * dq_step[:, 1]
    power_u = u_k * dx_step[:, :2]  # the convention's pairs (u_i, x_i)
    energy_ankle = float(np.nansum(np.abs(power_ankle)))
    energy_hip = float(np.nansum(np.abs(power_hip)))
    return {
        "energy_ankle": energy_ankle,
        "energy_hip": energy_hip,
        "energy_total": energy_ankle + energy_hip,
        "work_ankle": float(np.nansum(power_ankle)),
        "work_hip": float(np.nansum(power_hip)),
        "energy_u1": float(np.nansum(np.abs(power_u[:, 0]))),
        "energy_u2": float(np.nansum(np.abs(power_u[:, 1]))),
        **study_energies(float(np.nansum(power_u[:, 0])), float(np.nansum(power_u[:, 1]))),
    }


def summarize(
    *,
    force: float,
    duration: float,
    convention: str,
    scenario: ScenarioParams,
    controller: ControllerParams,
    time: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    x: np.ndarray,
    foot_pitch: np.ndarray,
    cell_low_z: np.ndarray,
    cop: np.ndarray,
    com: np.ndarray,
    tau: np.ndarray,
    u: np.ndarray,
    q0: np.ndarray,
    x0: np.ndarray,
    u_control: np.ndarray,
    converged: np.ndarray,
    residual: np.ndarray,
    completed: bool,
    diverged: bool = False,
    infeasible: np.ndarray | None = None,
    com_vel: np.ndarray | None = None,
    mos: np.ndarray | None = None,
    xcom: np.ndarray | None = None,
    steps: capture.StepModel | None = None,
) -> dict[str, Any]:
    """The per-scenario summary row (keys = SUMMARY_COLUMNS) from the sample series.

    Sample series (one entry per physics step, time = (i+1) dt): time [n]; q, dq [n, 2] joint
    angles/rates; x [n, 4] the convention state; foot_pitch [n]; cell_low_z [n, 4]; cop, com [n]
    (cop NaN where the load cells carry nothing); tau [n, 2] motor torques and u [n, 2] the
    convention's input held during step i. q0 [2], x0 [4]: the state at t = 0.
    Control series (one entry per control instant k, t_k = k control_dt): u_control [K, 2] the
    clipped input; converged [K] bool; residual [K] primal residual; infeasible [K] bool, the
    period's QP found infeasible (None: never). com_vel, mos, xcom [n], ``steps`` (optional):
    CoM velocity, margin of stability (push's direction), capture point, ``capture.step_model``
    (NaN columns without them). completed: the series reach t_end (False when the caller stopped
    early at a fall or a non-finite value). Series are cut at the first fall sample."""
    time = np.asarray(time, float)
    q, dq, x = np.asarray(q, float), np.asarray(dq, float), np.asarray(x, float)
    tau, u = np.asarray(tau, float), np.asarray(u, float)
    foot_pitch, cell_low_z = np.asarray(foot_pitch, float), np.asarray(cell_low_z, float)
    diverged = _diverged(diverged, q, dq, tau, x, u_control)

    limits = Limits.from_params(scenario, controller)
    excess, fell, end, fall_time = _first_fall(time, q, x, foot_pitch, cell_low_z, limits)
    # control periods whose instant precedes the last kept sample's time
    saturation_ankle, saturation_hip, nonconverged, max_residual, first_infeasible = (
        _control_columns(
            u_control,
            converged,
            residual,
            infeasible,
            fell=fell,
            fall_time=fall_time,
            control_dt=scenario.control_dt,
            limits=limits,
        )
    )
    code = _outcome_code(completed, diverged, fell, time, q, dq, limits)
    cause = _fall_cause(code, end, foot_pitch, cell_low_z, excess, q, limits)
    settle = settle_time(time, q, dq, limits) if code == RECOVERED else math.nan
    return {
        **_outcome_columns(force, duration, convention, code, settle, fall_time),
        **_peak_columns(q, foot_pitch, tau, cop, com, end),
        "ankle_saturation_fraction": saturation_ankle,
        "hip_saturation_fraction": saturation_hip,
        **_energy_columns(q0, x0, q, x, tau, u, end),
        "nonconverged_solves": nonconverged,
        "max_residual": max_residual,
        "max_bound_violation": _max_violation(excess, end),
        "fall_cause": outcomes.FALL_CAUSES[cause],
        "first_infeasible_time": first_infeasible,
        **_balance_columns(time, com_vel, mos, end)
        | _capture_columns(steps, code, xcom, end, force, duration),
    }


def _capture_columns(
    steps: capture.StepModel | None,
    code: int,
    xcom: np.ndarray | None,
    end: int,
    force: float,
    duration: float,
) -> dict[str, float]:
    """The capture columns (``capture.columns``) at the decision sample
    (``capture.decision_index``) of a run that fell at sample ``end - 1``; NaN without the
    series or the step model."""
    if steps is None or xcom is None:
        return {name: math.nan for name in capture.STEP_COLUMNS}
    xi, when = math.nan, math.nan
    if code == FELL and end > 0:
        i = capture.decision_index(xcom, force, duration, steps, end)
        xi, when = float(np.asarray(xcom, float)[i]), (i + 1) * steps.physics_dt
    cols = capture.columns(steps, np.asarray([code]), [when], [xi], [force], [duration])
    # NaN as math.nan itself, as every other column's: rows compare equal (``is`` before ==)
    return {name: math.nan if np.isnan(v[0]) else float(v[0]) for name, v in cols.items()}
