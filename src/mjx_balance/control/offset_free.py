"""Offset-free MPC: a disturbance observer and a steady-state target (``[controller]
offset_free = true``; docs/model.md "Offset-free MPC").

The plain MPC regulates to upright rest with a model that knows nothing of the push, so a
sustained push is met by a lean that grows until an input saturates. The offset-free
controller adds to the linear model a constant disturbance acting as a generalised force
beside the input,

    x+ = A x + B (u + d),     d+ = d                       (d [2], in the convention's units)

Why there: the push is a horizontal force at the upper body, whose generalised force on the
convention's coordinates is some d in R^2 (linearised); B = [0; M^-1 Δt-integrated] has full
column rank, so *every* generalised force, the push's or a model error's (nonlinearity, the
foot), is some B d. A push-shaped 1-D disturbance would only cancel pushes at one height.
Detectability: the state is measured, so the augmented pair ([[A, B], [0, I]], [I 0]) is
observable iff rank [[A - I, B], [I, 0]] = 6, i.e. iff B has rank 2, which it has.

Observer (a reduced observer, the state being measured): once per control period, with the
previous measured state x_{k-1} and the input u_{k-1} applied since,

    d_k = d_{k-1} + L (x_k - A x_{k-1} - B (u_{k-1} + d_{k-1})),    L = (1 - p) B^+

In the linear plant with a constant d the innovation is B (d - d_{k-1}) and B^+ B = I, so the
estimate's error is multiplied by the pole p (``controller.observer_pole``) every period:
a chosen pole placement, documented with its time constant -Δt / ln p.

Steady-state target: the equilibrium (x_s, u_s) of the disturbed model, x_s = [y_s, 0] with
u_s = -K y_s - d (K = Bc_v^-1 Ac_vy: the continuous model's velocity rows; a ZOH equilibrium
is a continuous one), that meets every bound of the MPC (inputs, positions, the CoP with the
accelerations of d, the CoM) and is closest to upright in the MPC's own position weights:

    minimise  y_sᵀ W y_s   subject to  a_i · y_s <= b_i(d),  i = 1..12    (W = diag(Q[:2]))

a strictly convex QP in two variables. Its minimiser is either 0 (upright, when feasible), the
W-projection of 0 onto one constraint line (one active constraint), or the intersection of two
constraint lines (two active; more than two lines through one point of a 2-D problem add no
other candidate). :func:`target` evaluates all 1 + 12 + 66 = 79 candidates and returns the
feasible one of least cost, which is therefore the exact minimiser (KKT: the minimiser has an
active set of at most two independent constraints in two dimensions);
tests/control/test_offset_free.py checks it against OSQP. When no candidate is feasible the
push cannot be held in any steady posture: the candidate of least violation is returned and
``held`` is False.

The MPC then solves its QP in deviation variables δx = x - x_s, δu = u - u_s: the dynamics
δx+ = A δx + B δu are those of the plain QP (the target is an equilibrium), the cost is the
plain cost of δ, and each constraint row's bounds move by the row's value at the target
(:func:`row_offsets`); the input applied is u_s + δu_0, clipped to its bounds.

Everything here is written for an array namespace ``xp`` (numpy for the scalar reference,
jax.numpy for the batched kernel), so both paths run the same code.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, NamedTuple, Union

import numpy as np

from ..model.params import ControllerParams
from .qp import CondensedQP

if TYPE_CHECKING:  # (annotations only)
    import jax

    Arrays = Union[np.ndarray, jax.Array]  # numpy (build) or JAX (cast for the kernel)

# A candidate meets a constraint within this distance [rad of y]: the rows are normalised, so
# this is a distance in the position plane; 1e-5 rad is ~50 float32 roundings of an angle of
# 1 rad, far below any bound's meaning (bounds are 0.15-1.4 rad, and the CoP's 0.15 m ~ 0.1 rad).
FEASIBLE_TOL = 1e-5
_PARALLEL = 1e-9  # |sin| of the angle between two normalised constraint lines taken as parallel


class OffsetFree(NamedTuple):
    """The observer's and the target's fixed matrices (numpy float64 from :func:`build`, or cast
    to the kernel's dtype)."""

    A: Arrays  # [4, 4] the model (discrete, control period)
    B: Arrays  # [4, 2]
    L: Arrays  # [2, 4] the observer gain (1 - p) B^+
    K: Arrays  # [2, 2] u_s = -K y_s - d
    normals: Arrays  # [c, 2] unit constraint normals a_i (c = 12)
    b0: Arrays  # [c] b_i(d) = b0_i + bd_i · d
    bd: Arrays  # [c, 2]
    W: Arrays  # [2, 2] the target's weights
    first: Arrays  # [p] int: the pairs of constraints whose intersections are candidates
    second: Arrays  # [p] int
    rows: Arrays  # [m, 8] a QP row's value at the target: rows @ [x_s, u_s, d]


def build(qp: CondensedQP, controller: ControllerParams) -> OffsetFree:
    """The offset-free matrices of a controller's QP (numpy, float64)."""
    lm = qp.linear
    A, B = lm.A, lm.B
    L = (1.0 - controller.observer_pole) * np.linalg.pinv(B)
    K = np.linalg.solve(lm.Bc[2:], lm.Ac[2:, :2])
    # the constraints a · y <= b0 + bd · d; u_s = -K y - d
    (u_lo, u_hi) = np.array(controller.input_bounds).T
    keep = controller.target_margin * (u_hi - u_lo) / 2  # room left to the MPC about u_s
    u_lo, u_hi = u_lo + keep, u_hi - keep
    (s_lo, s_hi) = np.array(controller.state_bounds).T
    cop_y = lm.cop_x[:2] - lm.cop_u @ K  # steady CoP: cop_y · y + cop_dd · d
    cop_dd = lm.cop_d - lm.cop_u
    com_y = lm.com_x[:2]
    eye = np.eye(2)
    normals = np.vstack([-K, K, eye, -eye, cop_y, -cop_y, com_y, -com_y])
    b0 = np.concatenate(
        [
            u_hi,
            -u_lo,
            s_hi,
            -s_lo,
            [controller.cop_bounds[1]],
            [-controller.cop_bounds[0]],
            [controller.com_bounds[1]],
            [-controller.com_bounds[0]],
        ]
    )
    bd = np.vstack([eye, -eye, np.zeros((4, 2)), -cop_dd, cop_dd, np.zeros((2, 2))])
    scale = np.linalg.norm(normals, axis=1)
    if not (scale > 0).all():
        raise ValueError("a steady-state constraint does not depend on the posture")
    pairs = np.array(list(itertools.combinations(range(len(b0)), 2)))
    W = np.diag(np.maximum(controller.q_diag[:2], 1e-9 * max(max(controller.q_diag[:2]), 1.0)))
    return OffsetFree(
        A=A,
        B=B,
        L=L,
        K=K,
        normals=normals / scale[:, None],
        b0=b0 / scale,
        bd=bd / scale[:, None],
        W=W,
        first=pairs[:, 0],
        second=pairs[:, 1],
        rows=offset_rows(qp),
    )


def offset_rows(qp: CondensedQP) -> np.ndarray:
    """[m, 8]: each constraint row's value at a constant (x_s, u_s, d) (qp.py's row order)."""
    lm, N = qp.linear, qp.horizon
    rows = np.zeros((qp.m, 8))
    inputs = rows[qp.rows["inputs"]].reshape(N, 2, 8)
    inputs[:, :, 4:6] = np.eye(2)
    states = rows[qp.rows["states"]].reshape(N, 2, 8)
    states[:, :, 0:2] = np.eye(2)
    rows[qp.rows["inputs"]] = inputs.reshape(-1, 8)
    rows[qp.rows["states"]] = states.reshape(-1, 8)
    rows[qp.rows["cop"]] = np.concatenate([lm.cop_x, lm.cop_u, lm.cop_d])
    rows[qp.rows["com"]] = np.concatenate([lm.com_x, np.zeros(4)])
    return rows


def cast(of: OffsetFree, xp, dtype) -> OffsetFree:
    """``of`` as arrays of ``xp`` in ``dtype`` (index arrays stay integers)."""
    return OffsetFree(
        *(
            xp.asarray(v) if name in ("first", "second") else xp.asarray(v, dtype)
            for name, v in zip(OffsetFree._fields, of)
        )
    )


def observe(xp, of: OffsetFree, d, x_last, u_last, x):
    """The disturbance estimate after measuring ``x``, from the previous estimate ``d``, the
    previous measurement ``x_last`` and the input ``u_last`` applied since."""
    innovation = x - of.A @ x_last - of.B @ (u_last + d)
    return d + of.L @ innovation


def target(xp, of: OffsetFree, d):
    """The steady-state target for disturbance ``d`` [2]: (y_s [2], u_s [2], held) — the
    exact minimiser of the module docstring's QP, or, when no posture holds ``d`` within every
    bound (held False), the candidate of least violation."""
    b = of.b0 + of.bd @ d  # [c]
    a = of.normals
    W_inv_a = xp.linalg.solve(of.W, a.T).T  # [c, 2]
    # one active constraint: the W-closest point of a_i · y = b_i
    along = W_inv_a * (b / xp.sum(a * W_inv_a, axis=1))[:, None]
    # two active: the intersection of two lines (Cramer's rule; parallel pairs are no candidate)
    ai, aj, bi, bj = a[of.first], a[of.second], b[of.first], b[of.second]
    det = ai[:, 0] * aj[:, 1] - ai[:, 1] * aj[:, 0]
    crossing = xp.abs(det) > _PARALLEL
    safe = xp.where(crossing, det, 1.0)
    corners = xp.stack(
        [(bi * aj[:, 1] - bj * ai[:, 1]) / safe, (ai[:, 0] * bj - aj[:, 0] * bi) / safe], axis=1
    )
    candidates = xp.concatenate([xp.zeros((1, 2), dtype=corners.dtype), along, corners])
    usable = xp.concatenate([xp.ones(1 + along.shape[0], dtype=bool), crossing])
    violation = xp.max(candidates @ a.T - b[None, :], axis=1)
    violation = xp.where(usable, violation, xp.inf)
    feasible = violation <= FEASIBLE_TOL
    cost = xp.sum(candidates * (candidates @ of.W), axis=1)
    held = xp.any(feasible)
    best = xp.where(held, xp.argmin(xp.where(feasible, cost, xp.inf)), xp.argmin(violation))
    y = candidates[best]
    return y, -of.K @ y - d, held


def row_offsets(xp, of: OffsetFree, x_s, u_s, d):
    """[m]: every QP row's value at the target (the bounds of the deviation QP move by it)."""
    return of.rows @ xp.concatenate([x_s, u_s, d])


def steady_state(xp, of: OffsetFree, d):
    """(x_s [4], u_s [2], held, row offsets [m]) of disturbance ``d``."""
    y, u_s, held = target(xp, of, d)
    x_s = xp.concatenate([y, xp.zeros(2, dtype=y.dtype)])
    return x_s, u_s, held, row_offsets(xp, of, x_s, u_s, d)
