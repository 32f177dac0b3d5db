"""The study's MPC: the same problem as ``qp.py`` posed as an NLP and solved by CasADi/IPOPT.

Formulation: multiple shooting, RK4 on the continuous linear model (Ac, Bc) over one control
period, the same weights (Q, R, terminal Qf) and constraints (input bounds, position-state
bounds, CoP and CoM bounds) as the condensed QP; decision vector w = [X (4 (N+1)); U (2 N)]
(columns stacked). RK4 on Ac is not the exact ZOH discretisation of the QP, so first controls
differ slightly from the QP's.

``IpoptMPC`` puts it behind the reference closed loop's controller interface
(``reference.MPC``), so ``reference.simulate_scenario(..., mpc=IpoptMPC(...))`` runs the
study's toolchain: MuJoCo C physics, this MPC, the reference's metrics unchanged.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..model.params import BodyParams, ControllerParams
from ..control.qp import CondensedQP, build_qp


def ipopt_mpc(qp: CondensedQP, controller: ControllerParams):
    """The study's MPC as an NLP: multiple shooting, RK4 on (Ac, Bc), IPOPT (CasADi).

    Returns (solve, shift): solve(x0, w0) -> (u0 clipped [2], w_opt), warm-started from w0 (None:
    zeros); shift(w_opt) -> the next period's warm start (one step on, last step repeated).
    Raises ImportError when casadi is not installed.
    """
    import casadi as ca

    lm, N, dt = qp.linear, qp.horizon, qp.linear.dt
    Ac, Bc = ca.DM(lm.Ac), ca.DM(lm.Bc)
    Q, R, Qf = ca.DM(np.diag(controller.q_diag)), ca.DM(np.diag(controller.r_diag)), ca.DM(qp.Qf)
    X = ca.SX.sym("X", 4, N + 1)
    U = ca.SX.sym("U", 2, N)
    P = ca.SX.sym("x0", 4)

    def f(x, u):
        return Ac @ x + Bc @ u

    def rk4(x, u):
        k1 = f(x, u)
        k2 = f(x + dt / 2 * k1, u)
        k3 = f(x + dt / 2 * k2, u)
        k4 = f(x + dt * k3, u)
        return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    cost: ca.SX | int  # (0, then the SX expression)
    cost, g, lbg, ubg = 0, [X[:, 0] - P], [0.0] * 4, [0.0] * 4
    cop_x, cop_u, com_x = ca.DM(lm.cop_x).T, ca.DM(lm.cop_u).T, ca.DM(lm.com_x).T
    for k in range(N):
        cost += 0.5 * (X[:, k].T @ Q @ X[:, k] + U[:, k].T @ R @ U[:, k])
        g.append(X[:, k + 1] - rk4(X[:, k], U[:, k]))
        lbg += [0.0] * 4
        ubg += [0.0] * 4
        g.append(cop_x @ X[:, k] + cop_u @ U[:, k])
        lbg.append(controller.cop_bounds[0])
        ubg.append(controller.cop_bounds[1])
        g.append(com_x @ X[:, k + 1])
        lbg.append(controller.com_bounds[0])
        ubg.append(controller.com_bounds[1])
    cost += 0.5 * X[:, N].T @ Qf @ X[:, N]
    w = ca.vertcat(ca.vec(X), ca.vec(U))
    nlp = {"x": w, "f": cost, "g": ca.vertcat(*g), "p": P}
    solver = ca.nlpsol(
        "mpc", "ipopt", nlp, {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes"}
    )
    inf = np.inf
    lbx_x = np.tile([-inf] * 4, N + 1).reshape(N + 1, 4)
    ubx_x = np.tile([inf] * 4, N + 1).reshape(N + 1, 4)
    (s1l, s1h), (s2l, s2h) = controller.state_bounds
    lbx_x[1:, 0], ubx_x[1:, 0], lbx_x[1:, 1], ubx_x[1:, 1] = s1l, s1h, s2l, s2h
    lbu = np.tile(qp.input_lower, N)
    ubu = np.tile(qp.input_upper, N)
    lbx = np.concatenate([lbx_x.ravel(), lbu])
    ubx = np.concatenate([ubx_x.ravel(), ubu])
    nX = 4 * (N + 1)

    def solve(x0: np.ndarray, w0: np.ndarray | None):
        w0 = np.zeros(nX + 2 * N) if w0 is None else w0
        sol = solver(x0=w0, p=x0, lbx=lbx, ubx=ubx, lbg=np.array(lbg), ubg=np.array(ubg))
        w_opt = np.asarray(sol["x"]).ravel()
        return qp.clip_input(w_opt[nX : nX + 2]), w_opt

    def shift(w_opt: np.ndarray) -> np.ndarray:
        Xs = w_opt[:nX].reshape(N + 1, 4)
        Us = w_opt[nX:].reshape(N, 2)
        return np.concatenate(
            [np.vstack([Xs[1:], Xs[-1:]]).ravel(), np.vstack([Us[1:], Us[-1:]]).ravel()]
        )

    return solve, shift


class IpoptMPC:
    """The study's MPC (CasADi/IPOPT, :func:`ipopt_mpc`) behind ``reference.MPC``'s interface,
    warm-started from its shifted previous solution."""

    def __init__(self, qp: CondensedQP, controller: ControllerParams):
        self.qp = qp
        self._solve, self._shift = ipopt_mpc(qp, controller)
        self._w = None

    def reset(self) -> None:
        self._w = None

    def solve(self, x0: np.ndarray):
        u, w = self._solve(np.asarray(x0, float), self._w)
        ok = bool(np.isfinite(w).all())
        self._w = self._shift(w) if ok else None
        # IPOPT's own status is not exposed by ipopt_mpc: count a solve as converged when its
        # result is finite; no primal residual (NaN).
        return u, w, ok, math.nan


@functools.lru_cache(maxsize=8)
def study_mpc(controller: ControllerParams, body: BodyParams, control_dt: float) -> IpoptMPC:
    """The study's controller of a configuration (built once per process and configuration),
    as ``reference.reference_mpc`` is the OSQP one."""
    return IpoptMPC(build_qp(controller, body, control_dt), controller)
