"""The solver benchmark's states and its trusted references (``bench.solver``,
tests/control/test_admm.py).

- states: closed-loop trajectories of the *linear* model (A, B) under the OSQP MPC, pushed from
  upright rest by F in 20..120 N for T in {0.1, 0.15, 0.2} s (the push enters as a generalised
  force of F at the upper body's CoM, held over whole control periods); a trajectory stops when
  a position state leaves its bound by more than 0.05 rad (the fall criterion). They include
  saturated inputs and infeasible QPs.
- truth: OSQP at eps 1e-9, no polishing, at most 4000 iterations (its infeasibility detection
  on, so that infeasible states are recognised and left out of the accuracy figures).
- ADMM along the trajectories: warm-started as in the closed loop, each state from the previous
  state's ADMM solution shifted one step; this pass also makes the warm starts of the batched
  timings.
- OSQP loop: a Python loop, warm-started from its own previous solution shifted one step
  (inputs and duals, the duals row group by row group as ``admm.shift_index``).

Accuracy is measured on the first control only (what the closed loop applies): a solve "misses"
when |u0 - u0_truth| exceeds ``ACCURACY`` of the input's range for either input.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..control.osqp_mpc import osqp_solve, osqp_solver
from ..model.params import BodyParams
from ..control.qp import CondensedQP, shift_warm_start
from ..control import admm
from ..control.admm import shift_index

ACCURACY = 1e-3  # of each input's range
TILE = 32  # batch tile of admm_solve_batch: small tiles stop early (measured 32..4096)
PUSH_FORCES = tuple(np.arange(20.0, 121.0, 5.0))
PUSH_DURATIONS = (0.1, 0.15, 0.2)
FALL_MARGIN = 0.05  # rad beyond a position bound that ends a trajectory


def push_input(qp: CondensedQP, body: BodyParams) -> np.ndarray:
    """Discrete-time effect of 1 N along x at the upper body's CoM, held one control period."""
    lm = qp.linear
    lever = np.array([body.lower_length, body.upper_com])  # d(x_upper_com)/d(theta)
    return lm.B @ (lm.P.T @ lever)


def closed_loop_states(
    qp: CondensedQP,
    body: BodyParams,
    forces=PUSH_FORCES,
    durations=PUSH_DURATIONS,
    steps: int = 100,
    eps: float = 1e-5,
    max_iter: int = 400,
) -> list[np.ndarray]:
    """Closed-loop trajectories [len, 4] of the linear model under the OSQP MPC (see module doc),
    one per (force, duration), forces outermost."""
    solver = osqp_solver(qp, eps, max_iter)
    lm, push = qp.linear, push_input(qp, body)
    lo = qp.lower0[qp.rows["states"]][:2]
    hi = qp.upper0[qp.rows["states"]][:2]
    trajectories = []
    for force in forces:
        for duration in durations:
            n_push = math.ceil(duration / lm.dt - 1e-9)
            x, states = np.zeros(4), []
            for k in range(steps):
                states.append(x)
                res = osqp_solve(solver, qp, x)
                u = qp.clip_input(res.x[:2])
                x = lm.A @ x + lm.B @ u + (push * force if k < n_push else 0.0)
                if np.any(x[:2] < lo - FALL_MARGIN) or np.any(x[:2] > hi + FALL_MARGIN):
                    break
            trajectories.append(np.array(states))
    return trajectories


@dataclass
class Truth:
    u0: np.ndarray  # [S, 2] first control, clipped (NaN where not solved)
    solved: np.ndarray  # [S] bool
    infeasible: np.ndarray  # [S] bool
    saturated: np.ndarray  # [S] bool: a clipped first input at a bound

    def select(self, index) -> Truth:
        """The truth of the states ``index`` (an integer gives one state's, without the S axis)."""
        return Truth(
            self.u0[index], self.solved[index], self.infeasible[index], self.saturated[index]
        )


def truth_solutions(
    qp: CondensedQP, states: np.ndarray, eps: float = 1e-9, max_iter: int = 4000
) -> Truth:
    """OSQP at ``eps`` (no polishing, infeasibility detection on) on every state.

    States not solved within ``max_iter`` (the slowest solved one on our closed-loop states
    needs under 3,000 iterations at 1e-9) are left out of the accuracy figures.
    """
    solver = osqp_solver(qp, eps, max_iter=max_iter, detect_infeasible=True)
    u0 = np.full((len(states), 2), np.nan)
    solved = np.zeros(len(states), bool)
    infeasible = np.zeros(len(states), bool)
    for i, x0 in enumerate(states):
        res = osqp_solve(solver, qp, x0)
        solved[i] = res.info.status == "solved"
        infeasible[i] = "infeasible" in res.info.status
        if solved[i]:
            u0[i] = qp.clip_input(res.x[:2])
    span = qp.input_upper - qp.input_lower
    at_bound = (np.abs(u0 - qp.input_lower) <= 1e-6 * span) | (
        np.abs(u0 - qp.input_upper) <= 1e-6 * span
    )
    return Truth(u0=u0, solved=solved, infeasible=infeasible, saturated=at_bound.any(axis=1))


def first_control_error(qp: CondensedQP, u0: np.ndarray, truth: Truth) -> np.ndarray:
    """max over the two inputs of |u0 - truth| / range (NaN where the truth is not solved)."""
    span = qp.input_upper - qp.input_lower
    return np.max(np.abs(qp.clip_input(u0) - truth.u0) / span, axis=-1)


def misses(error: np.ndarray, truth: Truth) -> int:
    """Solves of truth-solved states whose first-control error exceeds ``ACCURACY`` (or is NaN)."""
    return int(np.sum(truth.solved & ~(error <= ACCURACY)))


def admm_along_trajectories(
    qp: CondensedQP, trajectories: list[np.ndarray], settings=None, dtype=None, warm: bool = True
) -> dict[str, np.ndarray]:
    """Solve every state with the ADMM, warm-started from the previous state's shifted solution.

    Batched over trajectories, sequential in time (as in the closed loop). Returns flat arrays
    (trajectory order): u0 [S, 2], status, iters, prim_res, z [S, n] and the warm starts used
    (warm_z [S, n], warm_y [S, m]).
    """
    import jax
    import jax.numpy as jnp

    dtype = jnp.float32 if dtype is None else dtype
    settings = admm.ADMMSettings() if settings is None else settings
    data = admm.build_admm(qp, settings, dtype)
    lengths = [len(t) for t in trajectories]
    B, L = len(trajectories), max(lengths)
    X = np.zeros((L, B, 4))
    for i, t in enumerate(trajectories):
        X[: len(t), i] = t
        X[len(t) :, i] = t[-1]
    solve = jax.jit(admm.admm_solve_batch, static_argnums=3)
    cold = admm.initial_warm(data)
    w = admm.ADMMWarm(z=jnp.tile(cold.z, (B, 1)), y=jnp.tile(cold.y, (B, 1)))
    keys = ("u0", "status", "iters", "prim_res", "z")
    out: dict[str, list[np.ndarray]] = {k: [] for k in keys + ("warm_z", "warm_y")}
    for k in range(L):
        res = solve(data, jnp.asarray(X[k], dtype), w, settings)
        out["warm_z"].append(np.asarray(w.z))
        out["warm_y"].append(np.asarray(w.y))
        for key in keys:
            out[key].append(np.asarray(getattr(res, key)))
        if warm:
            w = res.warm_next
    flat = {}
    for key, frames in out.items():
        arr = np.stack(frames, axis=1)  # [B, L, ...]
        flat[key] = np.concatenate([arr[i, : lengths[i]] for i in range(B)])
    return flat


def osqp_loop(
    qp: CondensedQP, trajectories: list[np.ndarray], eps: float, max_iter: int = 4000
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OSQP in a Python loop, warm-started from its shifted previous solution (primal and dual).

    Returns (u0 [S, 2], seconds [S] per solve (update + solve + warm start), iterations [S]).
    OSQP's infeasibility detection is on here (its fastest setting: an infeasible state stops at
    the certificate instead of running to max_iter as in the closed-loop policy), which favours
    OSQP in the comparison.
    """
    solver = osqp_solver(qp, eps, max_iter, detect_infeasible=True)
    _, y_shift = shift_index(qp.rows, qp.n, qp.m, qp.horizon)
    u0, iters, seconds = [], [], []
    for traj in trajectories:
        warm = np.zeros(qp.n), np.zeros(qp.m)
        for x0 in traj:
            t0 = time.perf_counter()
            res = osqp_solve(solver, qp, x0, warm)
            warm = shift_warm_start(res.x), res.y[y_shift]
            seconds.append(time.perf_counter() - t0)
            u0.append(qp.clip_input(res.x[:2]))
            iters.append(res.info.iter)
    return np.array(u0), np.array(seconds), np.array(iters)
