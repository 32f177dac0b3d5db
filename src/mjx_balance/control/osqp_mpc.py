"""OSQP on the condensed MPC QP (``qp.py``): the reference's controller and the benchmarks'
trusted solver, set up in one place.

Settings (shared definitions): eps_abs = eps_rel = eps, polishing off, and infeasibility
detection disabled (eps_prim_inf = eps_dual_inf = 1e-30) unless asked for, so that an infeasible
QP runs to max_iter and returns its last iterate, as the batched ADMM does by default.
"""

from __future__ import annotations

import signal
import sys
import threading

import numpy as np
import osqp
import scipy.sparse as sp

from ..model.params import ControllerParams
from ..runtime import signals
from .qp import CondensedQP, shift_warm_start

INFEASIBILITY_EPS_OFF = 1e-30  # eps_prim_inf / eps_dual_inf that never certify infeasibility
INFEASIBILITY_EPS_ON = 1e-4  # OSQP's default tolerance


def osqp_solver(
    qp: CondensedQP, eps: float, max_iter: int = 20000, detect_infeasible: bool = False
) -> osqp.OSQP:
    """An OSQP instance for ``qp``, set up (and factorised) for x0 = 0, warm starts on."""
    lower, upper = qp.bounds(np.zeros(4))
    inf_eps = INFEASIBILITY_EPS_ON if detect_infeasible else INFEASIBILITY_EPS_OFF
    solver = osqp.OSQP()
    solver.setup(
        P=sp.triu(sp.csc_matrix(qp.H), format="csc"),
        q=qp.linear_term(np.zeros(4)),
        A=sp.csc_matrix(qp.C),
        l=lower,
        u=upper,
        eps_abs=eps,
        eps_rel=eps,
        eps_prim_inf=inf_eps,
        eps_dual_inf=inf_eps,
        max_iter=max_iter,
        polishing=False,
        warm_starting=True,
        verbose=False,
    )
    return solver


def osqp_solve(
    solver: osqp.OSQP,
    qp: CondensedQP,
    x0: np.ndarray,
    warm: tuple[np.ndarray, np.ndarray] | None = None,
    offset: np.ndarray | None = None,
    first: np.ndarray | None = None,
):
    """Solve the QP of measured state ``x0`` [4] (optionally from a primal/dual warm start;
    ``offset``: the offset-free deviation QP's row offsets, ``first``: the first input's own
    bounds, ``qp.bounds``); OSQP's result object; an exception only for a Ctrl-C that OSQP
    caught (:func:`checked`)."""
    lower, upper = qp.bounds(x0, offset, first)
    solver.update(q=qp.linear_term(x0), l=lower, u=upper)
    if warm is not None:
        solver.warm_start(x=warm[0], y=warm[1])
    return solved(solver)


def solved(solver: osqp.OSQP):
    """``solver.solve()`` without OSQP's line: while it solves, OSQP listens for SIGINT itself,
    and on a Ctrl-C it ends the solve and writes "Solver interrupted" to Python's
    ``sys.stdout`` (before the command's own one line; verbose=False does not silence it).
    That line alone is dropped (:class:`_WithoutOsqpLine`); the Ctrl-C itself is delivered by
    :func:`checked`."""
    global _solving
    with _stdout_lock:
        if _solving == 0:
            sys.stdout = _WithoutOsqpLine(sys.stdout)
        _solving += 1
    try:
        result = solver.solve(raise_error=False)
    finally:
        with _stdout_lock:
            _solving -= 1
            if _solving == 0 and isinstance(sys.stdout, _WithoutOsqpLine):
                sys.stdout = sys.stdout.inner
    return checked(result)


OSQP_INTERRUPTED = "Solver interrupted\n"  # what OSQP writes on a Ctrl-C it caught
_stdout_lock = threading.Lock()  # sys.stdout is swapped once for solves in several threads
_solving = 0  # solves under way (in any thread)


class _WithoutOsqpLine:
    """``sys.stdout`` while OSQP solves: everything written goes to ``inner`` but OSQP's
    interrupted line."""

    def __init__(self, inner):
        self.inner = inner

    def write(self, text: str) -> int:
        return len(text) if text == OSQP_INTERRUPTED else self.inner.write(text)

    def __getattr__(self, name: str):
        return getattr(self.inner, name)


def checked(result):
    """OSQP's result, unless OSQP stopped on a Ctrl-C: while it solves, OSQP listens for
    SIGINT itself and ends the solve with status OSQP_SIGINT, so Python's handler never sees
    the signal; it is delivered here (runtime/signals.py: Interrupted, KeyboardInterrupt)."""
    if result.info.status_val == osqp.SolverStatus.OSQP_SIGINT:
        signals.received(signal.SIGINT)
    return result


SOFT_GROUPS = ("states", "cop", "com")  # the rows an exact penalty softens (inputs stay hard)
VIOLATION_TOL = 1e-4  # a penalised solution this far outside a row's bounds: hard QP infeasible


class PenaltyOSQP:
    """The QP with the exact l1 penalty of ``controller.infeasible = "exact_penalty"``, as
    OSQP solves it: slack variables σ >= 0 on the state, CoP and CoM rows,

        minimise ½ zᵀ H z + qᵀ z + Σ w σ   s.t.  l_in <= C_in z <= u_in,
                                                  C_s z - σ <= u_s,  C_s z + σ >= l_s,  σ >= 0,

    whose z is the hard QP's solution whenever that exists (w above its multipliers) and the
    least weighted violation otherwise (the batched ADMM's prox, admm.py)."""

    def __init__(self, qp: CondensedQP, controller: ControllerParams):
        self.qp = qp
        self.soft = np.concatenate([np.arange(qp.m)[qp.rows[g]] for g in SOFT_GROUPS])
        self.hard = np.setdiff1d(np.arange(qp.m), self.soft)
        weights = dict(zip(SOFT_GROUPS, controller.penalty_weights))
        self.weight = np.concatenate(
            [np.full(qp.rows[g].stop - qp.rows[g].start, weights[g]) for g in SOFT_GROUPS]
        )
        n, k = qp.n, self.soft.size
        eye, zero = sp.identity(k, format="csc"), sp.csc_matrix((k, n))
        C = sp.csc_matrix(qp.C)
        self.A = sp.vstack(
            [
                sp.hstack([C[self.hard], sp.csc_matrix((self.hard.size, k))]),
                sp.hstack([C[self.soft], -eye]),
                sp.hstack([C[self.soft], eye]),
                sp.hstack([zero, eye]),
            ],
            format="csc",
        )
        self.P = sp.block_diag([sp.triu(sp.csc_matrix(qp.H)), sp.csc_matrix((k, k))], format="csc")
        self.solver = osqp.OSQP()
        q, lower, upper = self.terms(np.zeros(4))
        self.solver.setup(
            P=self.P,
            q=q,
            A=self.A,
            l=lower,
            u=upper,
            eps_abs=controller.osqp_eps,
            eps_rel=controller.osqp_eps,
            eps_prim_inf=INFEASIBILITY_EPS_OFF,
            eps_dual_inf=INFEASIBILITY_EPS_OFF,
            max_iter=controller.osqp_max_iter,
            polishing=False,
            warm_starting=True,
            verbose=False,
        )

    def terms(
        self, x0: np.ndarray, offset: np.ndarray | None = None, first: np.ndarray | None = None
    ):
        """(q, l, u) of the slack QP at state ``x0``."""
        lower, upper = self.qp.bounds(x0, offset, first)
        k, inf = self.soft.size, np.inf
        q = np.concatenate([self.qp.linear_term(x0), self.weight])
        lo = np.concatenate([lower[self.hard], np.full(k, -inf), lower[self.soft], np.zeros(k)])
        hi = np.concatenate([upper[self.hard], upper[self.soft], np.full(k, inf), np.full(k, inf)])
        return q, lo, hi

    def solve(
        self,
        x0: np.ndarray,
        z_warm: np.ndarray | None,
        offset: np.ndarray | None = None,
        first: np.ndarray | None = None,
    ):
        """(z [n], status solved, primal residual, the largest slack: the hard rows' violation)."""
        q, lo, hi = self.terms(x0, offset, first)
        self.solver.update(q=q, l=lo, u=hi)
        if z_warm is not None:
            self.solver.warm_start(x=np.concatenate([z_warm, np.zeros(self.soft.size)]))
        result = solved(self.solver)
        x = np.array(result.x, dtype=float)
        ok = result.info.status_val == osqp.SolverStatus.OSQP_SOLVED
        z, slack = x[: self.qp.n], x[self.qp.n :]
        violation = float(np.max(slack, initial=0.0)) if np.isfinite(slack).all() else np.inf
        return z, ok, float(result.info.prim_res), violation


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
        self._dual_blocks = [
            (qp.rows["inputs"], 2),
            (qp.rows["states"], 2),
            (qp.rows["cop"], 1),
            (qp.rows["com"], 1),
        ]
        assert qp.n == 2 * N
        self.reset()

    def reset(self) -> None:
        """Fresh solver (no warm start, initial rho): scenarios do not depend on each other."""
        self._penalty = (
            PenaltyOSQP(self.qp, self.controller)
            if self.controller.infeasible == "exact_penalty"
            else None
        )
        self._solver = osqp_solver(self.qp, self.controller.osqp_eps, self.controller.osqp_max_iter)
        self._z: np.ndarray | None = None
        self._y: np.ndarray | None = None
        self.violation = 0.0  # the last penalised solve's largest slack (0 when capped)
        self.hard_infeasible: bool | None = None  # the last solve's LP test, when it ran

    def _soft(
        self,
        x0: np.ndarray,
        z: np.ndarray,
        offset: np.ndarray | None,
        hard: tuple,
        first: np.ndarray | None = None,
    ) -> tuple[np.ndarray, bool, float]:
        """An unsolved hard QP under the exact penalty: if it is infeasible (the LP test), the
        slack QP's solution (warm-started from the hard iterate), else the hard result as is.

        Why not the slack QP for every state: a solvable QP's penalised solution is its hard
        one (the weights exceed its multipliers), which OSQP reaches reliably on the hard QP,
        while on the slack QP, an LP-like problem, OSQP at eps 1e-8 misses 6 of 64 solvable
        bench states even with 200,000 iterations."""
        self.hard_infeasible = not self.qp.feasible(x0, offset, first)
        if not self.hard_infeasible:
            return hard
        warm = z if np.isfinite(z).all() else None
        assert self._penalty is not None  # (solve calls this only under the exact penalty)
        z, ok, prim_res, self.violation = self._penalty.solve(x0, warm, offset, first)
        self._z = z if np.isfinite(z).all() else None
        self._y = None if self._z is None else np.zeros(self.qp.m)
        return z, ok, prim_res

    def _shift_dual(self, y: np.ndarray) -> np.ndarray:
        out = np.empty_like(y)
        for rows, stride in self._dual_blocks:
            block = y[rows]
            out[rows] = np.concatenate([block[stride:], block[-stride:]])
        return out

    def solve(
        self, x0: np.ndarray, offset: np.ndarray | None = None, first: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, bool, float]:
        """Solve the QP for measured state x0 [4] (with ``offset``: the offset-free deviation
        QP of x0 = x - x_s, whose first input is offset[:2] + z[:2]; offset_free.py; with
        ``first`` [2, 2]: the first input's own [lower, upper], the rate limit, ``qp.bounds``).

        Returns (u [2] first input clipped to its bounds, z [n] the solver's (last) iterate,
        status_ok: OSQP reported SOLVED, primal residual). Never raises on a bad solve.
        """
        x0 = np.asarray(x0, float)
        self.hard_infeasible = None
        if self._z is None:
            warm = np.zeros(self.qp.n), np.zeros(self.qp.m)
        else:
            assert self._y is not None  # (set together with _z)
            warm = shift_warm_start(self._z), self._shift_dual(self._y)
        result = osqp_solve(self._solver, self.qp, x0, warm, offset, first)
        z = np.array(result.x, dtype=float)
        y = np.array(result.y, dtype=float)
        status_ok = result.info.status_val == osqp.SolverStatus.OSQP_SOLVED
        prim_res = float(result.info.prim_res)
        if np.isfinite(z).all() and np.isfinite(y).all():
            self._z, self._y = z, y
        else:
            self._z = self._y = None
        if self._penalty is not None and not status_ok:
            z, status_ok, prim_res = self._soft(x0, z, offset, (z, status_ok, prim_res), first)
        head = z[:2] if offset is None else z[:2] + np.asarray(offset[:2], float)
        return self.qp.clip_input(head, first), z, bool(status_ok), prim_res
