"""OSQP on the condensed MPC QP (``qp.py``): the reference's controller and the benchmarks'
trusted solver, set up in one place.

Settings (shared definitions): eps_abs = eps_rel = eps, polishing off, and infeasibility
detection disabled (eps_prim_inf = eps_dual_inf = 1e-30) unless asked for, so that an infeasible
QP runs to max_iter and returns its last iterate, as the batched ADMM does by default.
"""

from __future__ import annotations

import numpy as np
import osqp
import scipy.sparse as sp

from ..model.params import ControllerParams
from .qp import CondensedQP, shift_warm_start

INFEASIBILITY_EPS_OFF = 1e-30  # eps_prim_inf / eps_dual_inf that never certify infeasibility
INFEASIBILITY_EPS_ON = 1e-4  # OSQP's default tolerance


def osqp_solver(qp: CondensedQP, eps: float, max_iter: int = 20000,
                detect_infeasible: bool = False) -> osqp.OSQP:
    """An OSQP instance for ``qp``, set up (and factorised) for x0 = 0, warm starts on."""
    lower, upper = qp.bounds(np.zeros(4))
    inf_eps = INFEASIBILITY_EPS_ON if detect_infeasible else INFEASIBILITY_EPS_OFF
    solver = osqp.OSQP()
    solver.setup(P=sp.triu(sp.csc_matrix(qp.H), format="csc"), q=qp.linear_term(np.zeros(4)),
                 A=sp.csc_matrix(qp.C), l=lower, u=upper, eps_abs=eps, eps_rel=eps,
                 eps_prim_inf=inf_eps, eps_dual_inf=inf_eps, max_iter=max_iter,
                 polishing=False, warm_starting=True, verbose=False)
    return solver


def osqp_solve(solver: osqp.OSQP, qp: CondensedQP, x0: np.ndarray,
               warm: tuple[np.ndarray, np.ndarray] | None = None,
               offset: np.ndarray | None = None):
    """Solve the QP of measured state ``x0`` [4] (optionally from a primal/dual warm start;
    ``offset``: the offset-free deviation QP's row offsets, ``qp.bounds``); OSQP's result
    object, never an exception."""
    lower, upper = qp.bounds(x0, offset)
    solver.update(q=qp.linear_term(x0), l=lower, u=upper)
    if warm is not None:
        solver.warm_start(x=warm[0], y=warm[1])
    return solver.solve(raise_error=False)


class ReferenceMPC:
    """The condensed MPC QP solved by OSQP, set up (and factorised) once, warm-started.

    Settings (shared definitions): eps_abs = eps_rel = controller.osqp_eps, polishing off,
    infeasibility detection disabled (eps_prim_inf = eps_dual_inf = 1e-30) so that an infeasible
    QP runs to max_iter and returns its last iterate, max_iter = controller.osqp_max_iter.
    """

    def __init__(self, qp: CondensedQP, controller: ControllerParams):
        self.qp = qp
        self.controller = controller
        # Dual warm start shifts each constraint block by its per-step row count.
        N = qp.horizon
        self._dual_blocks = [(qp.rows["inputs"], 2), (qp.rows["states"], 2),
                             (qp.rows["cop"], 1), (qp.rows["com"], 1)]
        assert qp.n == 2 * N
        self.reset()

    def reset(self) -> None:
        """Fresh solver (no warm start, initial rho): scenarios do not depend on each other."""
        self._solver = osqp_solver(self.qp, self.controller.osqp_eps,
                                   self.controller.osqp_max_iter)
        self._z: np.ndarray | None = None
        self._y: np.ndarray | None = None

    def _shift_dual(self, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        for rows, stride in self._dual_blocks:
            block = y[rows]
            out[rows] = np.concatenate([block[stride:], block[-stride:]])
        return out

    def solve(self, x0: np.ndarray, offset: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, bool, float]:
        """Solve the QP for measured state x0 [4] (with ``offset``: the offset-free deviation
        QP of x0 = x - x_s, whose first input is offset[:2] + z[:2]; offset_free.py).

        Returns (u [2] first input clipped to its bounds, z [n] the solver's (last) iterate,
        status_ok: OSQP reported SOLVED, primal residual). Never raises on a bad solve.
        """
        x0 = np.asarray(x0, float)
        if self._z is None:
            warm = np.zeros(self.qp.n), np.zeros(self.qp.m)
        else:
            warm = shift_warm_start(self._z), self._shift_dual(self._y)
        result = osqp_solve(self._solver, self.qp, x0, warm, offset)
        z = np.array(result.x, dtype=float)
        y = np.array(result.y, dtype=float)
        status_ok = result.info.status_val == osqp.SolverStatus.OSQP_SOLVED
        prim_res = float(result.info.prim_res)
        if np.isfinite(z).all() and np.isfinite(y).all():
            self._z, self._y = z, y
        else:
            self._z = self._y = None
        first = z[:2] if offset is None else z[:2] + np.asarray(offset[:2], float)
        return self.qp.clip_input(first), z, bool(status_ok), prim_res
