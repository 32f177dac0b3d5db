"""Scalar reference closed loop: MuJoCo C physics (``mujoco.mj_step``) + OSQP MPC.

One scenario at a time, plain Python loops, float64 throughout. Everything the batched JAX path
computes is checked against this module.

Timing (shared definitions). Physics step dt = scenario.physics_dt, control period
scenario.control_dt, substeps = control_dt / dt. At each control instant t_k = k control_dt the
controller measures the joint state, converts it to the convention state, solves the condensed
QP (``qp.py``) and holds the first input, clipped to its bounds, as motor torques for
``substeps`` physics steps. The push (force along x, see ``push_wrench``) acts during physics
steps i < ceil(T / dt - 1e-9). The run starts at upright rest and stops at the first fall sample
or non-finite value (see ``metrics.py``).

Sensorimotor delay (scenario.controller_delay = D, d = D / dt physics steps): the controller at
t_k sees the joint state (q_a, q_h, dq_a, dq_h) of time t_k - D, i.e. the state after physics
step k * substeps - d; before t = 0 that is the initial upright rest state. The plant, the push
and the metrics run undelayed; d = 0 is the undelayed loop.
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import osqp
import pandas as pd
import scipy.sparse as sp

from . import metrics
from .model import build_model, indices
from .params import Config, ControllerParams, ParameterError, save_config
from .qp import CondensedQP, build_qp, shift_warm_start

TIMESERIES_COLUMNS = [
    "scenario", "force", "duration", "convention", "time",
    "q_a", "q_h", "dq_a", "dq_h", "x1", "x2", "x3", "x4",
    "foot_x", "foot_z", "foot_pitch", "u1", "u2", "tau_ankle", "tau_hip", "cop", "com",
    "energy_ankle", "energy_hip", "energy_total",
]


class ReferenceMPC:
    """The condensed MPC QP solved by OSQP, set up (and factorised) once, warm-started.

    Settings (shared definitions): eps_abs = eps_rel = controller.osqp_eps, polishing off,
    infeasibility detection disabled (eps_prim_inf = eps_dual_inf = 1e-30) so that an infeasible
    QP runs to max_iter and returns its last iterate, max_iter = controller.osqp_max_iter.
    """

    INFEASIBILITY_EPS = 1e-30

    def __init__(self, qp: CondensedQP, controller: ControllerParams):
        self.qp = qp
        self.controller = controller
        self._P = sp.triu(sp.csc_matrix(qp.H), format="csc")
        self._A = sp.csc_matrix(qp.C)
        # Dual warm start shifts each constraint block by its per-step row count.
        N = qp.horizon
        self._dual_blocks = [(qp.rows["inputs"], 2), (qp.rows["states"], 2),
                             (qp.rows["cop"], 1), (qp.rows["com"], 1)]
        assert qp.n == 2 * N
        self.reset()

    def reset(self) -> None:
        """Fresh solver (no warm start, initial rho): scenarios do not depend on each other."""
        x0 = np.zeros(4)
        lower, upper = self.qp.bounds(x0)
        self._solver = osqp.OSQP()
        self._solver.setup(
            P=self._P, q=self.qp.linear_term(x0), A=self._A, l=lower, u=upper,
            eps_abs=self.controller.osqp_eps, eps_rel=self.controller.osqp_eps,
            eps_prim_inf=self.INFEASIBILITY_EPS, eps_dual_inf=self.INFEASIBILITY_EPS,
            max_iter=self.controller.osqp_max_iter, polishing=False, warm_starting=True,
            verbose=False,
        )
        self._z: np.ndarray | None = None
        self._y: np.ndarray | None = None

    def _shift_dual(self, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        for rows, stride in self._dual_blocks:
            block = y[rows]
            out[rows] = np.concatenate([block[stride:], block[-stride:]])
        return out

    def solve(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool, float]:
        """Solve the QP for measured state x0 [4].

        Returns (u [2] first input clipped to its bounds, z [n] the solver's (last) iterate,
        status_ok: OSQP reported SOLVED, primal residual). Never raises on a bad solve.
        """
        x0 = np.asarray(x0, float)
        lower, upper = self.qp.bounds(x0)
        self._solver.update(q=self.qp.linear_term(x0), l=lower, u=upper)
        if self._z is None:
            self._solver.warm_start(x=np.zeros(self.qp.n), y=np.zeros(self.qp.m))
        else:
            self._solver.warm_start(x=shift_warm_start(self._z), y=self._shift_dual(self._y))
        result = self._solver.solve(raise_error=False)
        z = np.array(result.x, dtype=float)
        y = np.array(result.y, dtype=float)
        status_ok = result.info.status_val == osqp.SolverStatus.OSQP_SOLVED
        prim_res = float(result.info.prim_res)
        if np.isfinite(z).all() and np.isfinite(y).all():
            self._z, self._y = z, y
        else:
            self._z = self._y = None
        return self.qp.clip_input(z[:2]), z, bool(status_ok), prim_res


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


@functools.lru_cache(maxsize=8)
def _mpc(controller: ControllerParams, body, control_dt: float) -> ReferenceMPC:
    return ReferenceMPC(build_qp(controller, body, control_dt), controller)


@functools.lru_cache(maxsize=8)
def _model(body, physics_dt: float) -> mujoco.MjModel:
    return build_model(body, physics_dt, foot="free")


def simulate_scenario(config: Config, force: float, duration: float, *, record: bool = True,
                      scenario_id: int = 0) -> tuple[dict[str, Any], pd.DataFrame | None]:
    """Run one push scenario; return (summary row, long time series or None).

    ``force`` [N] (+ forward) and ``duration`` [s] override config.scenario's; the summary row
    has the keys ``metrics.SUMMARY_COLUMNS``; the time series has ``TIMESERIES_COLUMNS``, one row
    per physics step (time = (i+1) dt), ending at the fall sample if the body fell.
    """
    config = config.replace(scenario={"force": float(force), "duration": float(duration)})
    body, ctrl, sc = config.body, config.controller, config.scenario
    model = _model(body, sc.physics_dt)
    mpc = _mpc(ctrl, body, sc.control_dt)
    mpc.reset()
    lm = mpc.qp.linear
    ix = indices(model)
    data = mujoco.MjData(model)
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
    residual = np.zeros(n_control)
    # joint history for a delayed measurement: entry j is the state at t = j dt
    history_q = np.zeros((n_steps + 1, 2))
    history_dq = np.zeros((n_steps + 1, 2))
    history_q[0] = data.qpos[joints_q]
    history_dq[0] = data.qvel[joints_v]
    q0 = history_q[0].copy()
    x0 = lm.state_from_joints(q0, history_dq[0])

    n = 0  # samples taken
    k_done = 0
    stop = False
    diverged = False
    for k in range(n_control):
        s = max(k * substeps - sc.delay_steps, 0)
        x_meas = lm.state_from_joints(history_q[s], history_dq[s])
        u, _, ok, prim_res = mpc.solve(x_meas)
        torques = lm.motor_torques(u)
        u_control[k], converged[k], residual[k] = u, ok, prim_res
        k_done = k + 1
        if not (np.isfinite(u).all() and np.isfinite(torques).all()):
            diverged = True
            break
        data.ctrl[:] = torques
        for j in range(substeps):
            i = k * substeps + j
            push = push_wrench(data, upper, force, sc.push_body) if i < n_push else 0.0
            data.xfrc_applied[upper] = push
            mujoco.mj_step(model, data)
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
            if metrics.fall_flags(foot[i, 2], cell_low[i][None], x[i][None], q[i, 0],
                                  sc, ctrl)[0]:
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
    )
    if not record:
        return summary, None

    energy_ankle = np.cumsum(np.abs(tau[sl, 0] * np.diff(np.concatenate([[q0[0]], q[sl, 0]]))))
    energy_hip = np.cumsum(np.abs(tau[sl, 1] * np.diff(np.concatenate([[q0[1]], q[sl, 1]]))))
    frame = pd.DataFrame({
        "scenario": np.full(n, scenario_id, dtype=np.int64),
        "force": np.full(n, float(force)),
        "duration": np.full(n, float(duration)),
        "convention": ctrl.convention,
        "time": time[sl],
        "q_a": q[sl, 0], "q_h": q[sl, 1], "dq_a": dq[sl, 0], "dq_h": dq[sl, 1],
        "x1": x[sl, 0], "x2": x[sl, 1], "x3": x[sl, 2], "x4": x[sl, 3],
        "foot_x": foot[sl, 0], "foot_z": foot[sl, 1], "foot_pitch": foot[sl, 2],
        "u1": u_step[sl, 0], "u2": u_step[sl, 1],
        "tau_ankle": tau[sl, 0], "tau_hip": tau[sl, 1],
        "cop": cop[sl], "com": com[sl],
        "energy_ankle": energy_ankle, "energy_hip": energy_hip,
        "energy_total": energy_ankle + energy_hip,
    }, columns=TIMESERIES_COLUMNS)
    return summary, frame


# --- the ``mjx-balance simulate`` command ----------------------------------------------------

TABLE_COLUMNS = ["force", "duration", "convention", "outcome", "settle_time", "fall_time",
                 "peak_ankle", "peak_hip", "peak_tau_ankle", "peak_tau_hip",
                 "ankle_saturation_fraction", "energy_ankle", "energy_hip", "energy_total",
                 "nonconverged_solves", "max_bound_violation"]


def parse_values(text: str, name: str, *, nonnegative: bool = False) -> list[float]:
    """Comma-separated finite numbers; ParameterError naming ``name`` otherwise."""
    items = [item.strip() for item in str(text).split(",")]
    if not any(items):
        raise ParameterError(f"--{name}: give at least one value")
    values = []
    for item in items:
        try:
            value = float(item)
        except ValueError:
            raise ParameterError(f"--{name}: {item!r} is not a number") from None
        if not math.isfinite(value):
            raise ParameterError(f"--{name}: {item!r} must be a finite number")
        if nonnegative and value < 0:
            raise ParameterError(f"--{name}: {item!r} must be >= 0")
        values.append(value)
    return values


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
    summary = pd.DataFrame(rows, columns=metrics.SUMMARY_COLUMNS)
    return summary, pd.concat(frames, ignore_index=True)


def simulate_command(args: argparse.Namespace) -> int:
    """``mjx-balance simulate``: run the pushes, write tables, configuration and figures."""
    from .cli import load_run_config
    from .plots import timeseries_figures

    forces = parse_values(args.force, "force")
    durations = parse_values(args.duration, "duration", nonnegative=True)
    config = load_run_config(args)
    for duration in durations:  # fail before creating anything
        config.replace(scenario={"duration": duration})
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary, series = simulate_many(config, forces, durations)
    summary.to_csv(out / "summary.csv", index=False)
    series.to_parquet(out / "timeseries.parquet", index=False)
    save_config(config, out / "config.toml")
    figures = timeseries_figures(series, out)
    with pd.option_context("display.width", 200, "display.max_columns", None,
                           "display.float_format", lambda v: f"{v:.4g}"):
        print(summary[TABLE_COLUMNS].to_string(index=False))
    print(f"wrote {out / 'summary.csv'}, {out / 'timeseries.parquet'}, {out / 'config.toml'} "
          f"and {len(figures)} figures in {out}")
    return 0
