"""Batched OSQP-style ADMM for the condensed MPC QP (pure JAX, jit/vmap).

The QP of qp.py (decision variable z = input sequence, n = 2N; m = 6N constraint rows)

    minimise  ½ zᵀ H z + qᵀ z,   q = F x0
    subject to  l <= C z <= u,   l = lower0 - E x0,  u = upper0 - E x0

is solved with the ADMM of OSQP (Stellato et al., "OSQP: an operator splitting solver for
quadratic programs", Math. Prog. Comp. 2020, Algorithm 1). In the comments x is the decision
variable (our z), z OSQP's constraint value (here ``s``) and y the dual, as in the paper.

Everything that depends only on the controller configuration is computed once, in float64 numpy,
by :func:`build_admm`, then cast to the working dtype:

- Preconditioning (a change of variables z = T x̄ and a row scaling Ē): the fixed H is first
  whitened, T0 = V Λ^(-1/2) from H = V Λ Vᵀ (so T0ᵀ H T0 = I), then OSQP's modified Ruiz
  equilibration (§5.1) of [[T0ᵀ H T0, (C T0)ᵀ], [C T0, 0]] gives D, Ē and the cost scale c:
  T = T0 D, P̄ = c Tᵀ H T, Ā = Ē C T, q̄ = c Tᵀ q, l̄ = Ē l, ū = Ē u. OSQP's cost scaling also
  looks at q; ours changes every solve, so c uses P only. Whitening is possible because H never
  changes; it cuts the iterations for the default accuracy against Ruiz alone.
- ρ is a vector over the constraint rows (as OSQP's per-row ρ): settings.rho times a factor per
  row group (inputs, states, CoP, CoM; ``rho_scale``), measured to favour the CoP rows.
- The reduced KKT system (P̄ + σI + Āᵀ diag(ρ) Ā) x̃ = σx - q̄ + Āᵀ(ρz - y) (OSQP eq. 23) has a
  fixed matrix K; its inverse is folded into Mw = K⁻¹Āᵀ diag(ρ) (n x m), Mx = σK⁻¹ and
  g = -K⁻¹q̄ = G x0; the iteration carries y / ρ in place of y.
- With the defaults (``mjx-balance bench solver``, tests/control/test_admm.py) warm-started
  solves of closed-loop states reach 1e-3 of each input's range against OSQP at 1e-9 on every
  OSQP-solved state measured.

One iteration therefore costs two dense products, x̃ = Mw (z - y/ρ) + g (+ Mx x when σ > 0) and
z̃ = Ā x̃, i.e. 4 n m = 19,200 flops for N = 20 (σ = 0), plus O(m) elementwise work. Products
are written row-vector first (``w @ Mwᵀ``) so that under ``vmap`` they become [B, m] x [m, n]
matrix-matrix products (GEMMs) shared by the whole batch. Per solve only q = F x0 and the bounds
move (a few 4-column products).

Termination (OSQP §3.4, unscaled terms), checked every ``check_every`` iterations:
    ‖C z - s‖∞ <= eps_abs + eps_rel max(‖C z‖∞, ‖s‖∞)
    ‖H z + q + Cᵀ y‖∞ <= eps_abs + eps_rel max(‖H z‖∞, ‖Cᵀ y‖∞, ‖q‖∞)
Iterations run in chunks of ``check_every`` inside a ``lax.while_loop`` capped at
ceil(max_iter / check_every) chunks (the cap is max_iter rounded up to whole chunks). Under
``vmap`` a converged element is frozen (its carry no longer changes) while others go on. A solve
that does not converge keeps iterating to the cap: for a primal infeasible QP the x-iterates
converge to the minimiser over the minimally shifted constraint set (Banjac et al., "Infeasibility
detection in the alternating direction method of multipliers for convex optimization", JOTA 2019).
Its status is then PRIMAL_INFEASIBLE if OSQP's certificate holds for δy = y_k - y_{k-check}
(‖Cᵀδy‖∞ <= eps_pinf ‖δy‖∞ and uᵀ max(δy, 0) + lᵀ min(δy, 0) < eps_pinf ‖δy‖∞), else MAX_ITER.
No exception is raised inside jit and the outputs stay finite for finite x0 and warm start.

Shapes: n = 2N decision variables, m = 6N constraint rows, state 4, input 2.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..model.params import ControllerParams
from .qp import CondensedQP

SOLVED, MAX_ITER, PRIMAL_INFEASIBLE = 1, 2, 3
RHO_GROUPS = ("inputs", "states", "cop", "com")  # constraint row groups of qp.py
STATUS_NAMES = {SOLVED: "solved", MAX_ITER: "max_iter", PRIMAL_INFEASIBLE: "primal_infeasible"}

_MIN_SCALING, _MAX_SCALING = 1e-4, 1e4  # OSQP's bounds on one Ruiz step


_DEFAULTS = ControllerParams()  # the configuration holds the defaults of the shared settings


class ADMMSettings(NamedTuple):
    """Solver hyper-parameters; hashable, passed as a static argument under jit.

    The settings a configuration can set take their defaults from ``ControllerParams``
    (``admm_*``, where they are explained); the others are fixed here. rho, sigma,
    scaling_iters and whiten enter the matrices precomputed by :func:`build_admm` (build the
    data with the same settings you solve with); the rest is used by :func:`admm_solve`.
    """

    rho: float = _DEFAULTS.admm_rho
    # ρ of each row group (RHO_GROUPS) = rho x factor, as OSQP's per-row ρ. A larger ρ on the
    # CoP rows (often active during a push) and the input rows removes the slow tail of
    # warm-started solves after large pushes (the bench states of ``mjx-balance bench solver``).
    rho_scale: tuple[float, float, float, float] = (3.0, 1.0, 30.0, 1.0)
    sigma: float = _DEFAULTS.admm_sigma  # proximal term; H ≻ 0, so 0 is allowed
    alpha: float = _DEFAULTS.admm_alpha  # over-relaxation
    max_iter: int = _DEFAULTS.admm_max_iter
    check_every: int = _DEFAULTS.admm_check_every
    eps_abs: float = _DEFAULTS.admm_eps_abs
    eps_rel: float = _DEFAULTS.admm_eps_rel
    scaling_iters: int = 3  # Ruiz equilibration passes (after whitening)
    whiten: bool = True  # change of variables with H^(-1/2) before Ruiz
    eps_prim_inf: float = 1e-4  # OSQP's primal infeasibility tolerance
    # Stop a solve at the first check where OSQP's primal infeasibility certificate holds
    # (instead of iterating to the cap).
    stop_on_infeasible: bool = _DEFAULTS.admm_stop_on_infeasible
    # The exact (l1) penalty of the softenable rows (controller.infeasible = "exact_penalty"):
    # the weight of each row group (RHO_GROUPS) on the rows' violation, inf for a hard group;
    # None: every row hard and an infeasible QP runs to the cap ("capped", the default).
    penalty: tuple[float, ...] | None = None  # one weight per RHO_GROUPS entry

    @property
    def n_chunks(self) -> int:
        return max(1, math.ceil(self.max_iter / self.check_every))

    @property
    def iteration_cap(self) -> int:
        return self.n_chunks * self.check_every


def settings_from_controller(controller: ControllerParams) -> ADMMSettings:
    """The ADMM settings of a controller configuration."""
    return ADMMSettings(
        rho=float(controller.admm_rho),
        sigma=float(controller.admm_sigma),
        alpha=float(controller.admm_alpha),
        max_iter=int(controller.admm_max_iter),
        check_every=int(controller.admm_check_every),
        eps_abs=float(controller.admm_eps_abs),
        eps_rel=float(controller.admm_eps_rel),
        stop_on_infeasible=bool(controller.admm_stop_on_infeasible),
        penalty=penalty_of(controller),
    )


def penalty_of(controller: ControllerParams) -> tuple[float, ...] | None:
    """The row groups' l1 weights of ``controller.infeasible = "exact_penalty"`` (inputs hard),
    None for "capped"."""
    if controller.infeasible != "exact_penalty":
        return None
    return (math.inf, *(float(w) for w in controller.penalty_weights))


class ADMMData(NamedTuple):
    """Everything precomputed once per controller configuration (arrays; row-vector layout)."""

    MwT: jax.Array  # [m, n]  (K⁻¹ Āᵀ diag(ρ))ᵀ
    MxT: jax.Array  # [n, n]  (σ K⁻¹)ᵀ
    GT: jax.Array  # [4, n]  x̃ offset -K⁻¹ q̄ = x0 @ GT
    AT: jax.Array  # [n, m]  Āᵀ
    l0: jax.Array  # [m]     l̄ = l0 - x0 @ bT
    u0: jax.Array  # [m]
    bT: jax.Array  # [4, m]
    rho: jax.Array  # [m]
    E: jax.Array  # [m]     row scaling (z̄ = E z)
    cost_scale: jax.Array  # []  c
    T: jax.Array  # [n, n]  z = T x̄
    T_inv: jax.Array  # [n, n]
    H: jax.Array  # [n, n]  unscaled, for the residuals
    CT: jax.Array  # [n, m]  Cᵀ unscaled
    FT: jax.Array  # [4, n]  q = x0 @ FT
    input_lower: jax.Array  # [2]
    input_upper: jax.Array  # [2]
    z_shift: jax.Array  # [n] int32 gather index: input sequence shifted one step
    y_shift: jax.Array  # [m] int32 gather index: constraint rows shifted one step
    soft: jax.Array  # [m] the l1 penalty's threshold in the scaled iteration, c w / (E ρ)
    #                  (inf: a hard row; all inf without settings.penalty)


class ADMMWarm(NamedTuple):
    """Warm start in unscaled terms: decision variable z [n] and duals y [m]."""

    z: jax.Array
    y: jax.Array


class ADMMResult(NamedTuple):
    z: jax.Array  # [n] input sequence (last iterate)
    u0: jax.Array  # [2] first input clipped to the input bounds
    status: jax.Array  # int32: SOLVED, MAX_ITER or PRIMAL_INFEASIBLE
    prim_res: jax.Array  # unscaled ‖C z - s‖∞ at the last check
    dual_res: jax.Array  # unscaled ‖H z + q + Cᵀ y‖∞ at the last check
    iters: jax.Array  # int32 iterations run
    warm_next: ADMMWarm  # solution shifted one control step


# --------------------------------------------------------------------------------------------
# Precomputation (numpy, float64)


def ruiz(P: np.ndarray, A: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray, float]:
    """OSQP's modified Ruiz equilibration of [[P, Aᵀ], [A, 0]] -> (D, E, c).

    The cost scale c uses the mean column norm of P only (q varies per solve here).
    """
    n, m = P.shape[0], A.shape[0]
    D, E, c = np.ones(n), np.ones(m), 1.0
    Ps, As = P.copy(), A.copy()
    for _ in range(iters):
        col = np.maximum(np.abs(Ps).max(axis=0), np.abs(As).max(axis=0))
        row = np.abs(As).max(axis=1)
        d = 1.0 / np.sqrt(np.clip(col, _MIN_SCALING, _MAX_SCALING))
        e = 1.0 / np.sqrt(np.clip(row, _MIN_SCALING, _MAX_SCALING))
        Ps = d[:, None] * Ps * d[None, :]
        As = e[:, None] * As * d[None, :]
        D, E = D * d, E * e
        gamma = 1.0 / np.clip(np.abs(Ps).max(axis=0).mean(), _MIN_SCALING, _MAX_SCALING)
        Ps, c = Ps * gamma, c * gamma
    return D, E, c


def shift_index(rows: dict, n: int, m: int, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Gather indices that move each row group one step ahead, repeating the last step."""
    per = n // horizon
    z_idx = np.minimum(np.arange(n) + per, n - per + np.arange(n) % per)
    y_idx = np.arange(m)
    for sl in rows.values():
        size = sl.stop - sl.start
        width = size // horizon
        local = np.arange(size)
        y_idx[sl] = sl.start + np.minimum(local + width, size - width + local % width)
    return z_idx.astype(np.int32), y_idx.astype(np.int32)


def build_admm(qp: CondensedQP, settings: ADMMSettings, dtype=jnp.float32) -> ADMMData:
    """Precondition the QP and precompute the ADMM matrices once (float64), cast to ``dtype``."""
    H, C, n, m = qp.H, qp.C, qp.n, qp.m
    if settings.whiten:
        lam, V = np.linalg.eigh(H)
        T0 = V / np.sqrt(lam)[None, :]
    else:
        T0 = np.eye(n)
    D, E, c = ruiz(T0.T @ H @ T0, C @ T0, settings.scaling_iters)
    T = T0 * D[None, :]
    Ps = c * T.T @ H @ T
    Ps = 0.5 * (Ps + Ps.T)
    As = E[:, None] * (C @ T)
    rho = np.full(m, float(settings.rho))
    for name, factor in zip(RHO_GROUPS, settings.rho_scale):
        rho[qp.rows[name]] *= factor
    sigma = float(settings.sigma)
    K = Ps + sigma * np.eye(n) + As.T @ (rho[:, None] * As)  # OSQP eq. 23, reduced form
    K_inv = np.linalg.inv(0.5 * (K + K.T))
    q_x0 = c * T.T @ qp.F  # q̄ = q_x0 @ x0
    # The l1 penalty w |violation| of a row, in the scaled problem c w |Ē violation| / Ē, is
    # the prox step z = a - clip(a - Π(a), -t, t) with t = c w / (Ē ρ) (the loop carries y/ρ).
    weight = np.full(m, np.inf)
    if settings.penalty is not None:
        for name, w in zip(RHO_GROUPS, settings.penalty):
            weight[qp.rows[name]] = w
    soft = np.where(np.isfinite(weight), c * weight / (E * rho), np.inf)
    z_idx, y_idx = shift_index(qp.rows, n, m, qp.horizon)
    arrays = dict(
        MwT=(K_inv @ As.T @ np.diag(rho)).T,
        MxT=(sigma * K_inv).T,
        GT=(-K_inv @ q_x0).T,
        AT=As.T,
        l0=E * qp.lower0,
        u0=E * qp.upper0,
        bT=(E[:, None] * qp.E).T,
        rho=rho,
        E=E,
        cost_scale=np.array(c),
        T=T,
        T_inv=np.linalg.inv(T),
        H=H,
        CT=C.T,
        FT=qp.F.T,
        input_lower=qp.input_lower,
        input_upper=qp.input_upper,
        soft=soft,
    )
    data = {k: jnp.asarray(v, dtype=dtype) for k, v in arrays.items()}
    return ADMMData(**data, z_shift=jnp.asarray(z_idx), y_shift=jnp.asarray(y_idx))


def initial_warm(data: ADMMData) -> ADMMWarm:
    """A cold start (zeros)."""
    m, n = data.MwT.shape
    return ADMMWarm(z=jnp.zeros(n, data.MwT.dtype), y=jnp.zeros(m, data.MwT.dtype))


def flops_per_iteration(n: int, m: int, sigma: float = 0.0) -> int:
    """Floating-point operations of one ADMM iteration (products + elementwise, approx.)."""
    products = 2 * n * m + 2 * m * n + (2 * n * n if sigma > 0 else 0)
    return products + 3 * n + 7 * m


def flops_per_check(n: int, m: int) -> int:
    """Floating-point operations of one residual check (unscaled residuals)."""
    return 2 * n * n + 2 * n * m + 2 * n * n + 2 * m * n + 12 * (n + m)


# --------------------------------------------------------------------------------------------
# The solve (pure JAX)


def _inf_norm(v: jax.Array) -> jax.Array:
    return jnp.max(jnp.abs(v))


class _Carry(NamedTuple):
    x: jax.Array  # [n] scaled decision variable
    s: jax.Array  # [m] scaled constraint value (OSQP's z)
    y: jax.Array  # [m] scaled dual divided by ρ
    y_check: jax.Array  # [m] the same at the previous check (for δy)
    chunk: jax.Array  # int32 chunks done
    done: jax.Array  # bool converged
    stop: jax.Array  # bool converged, or infeasible with settings.stop_on_infeasible
    prim_res: jax.Array
    dual_res: jax.Array


class _Solve(NamedTuple):
    """The per-solve terms of one :func:`admm_solve` (scaled unless said; n, m as above)."""

    alpha: jax.Array  # [] over-relaxation
    eps_abs: jax.Array  # []
    eps_rel: jax.Array  # []
    eps_pinf: jax.Array  # [] primal infeasibility tolerance
    rho: jax.Array  # [m]
    E: jax.Array  # [m] row scaling
    E_inv: jax.Array  # [m]
    c: jax.Array  # [] cost scale
    q: jax.Array  # [n] unscaled linear term F x0
    g: jax.Array  # [n] x̃ offset -K⁻¹ q̄
    lo: jax.Array  # [m] scaled lower bounds
    hi: jax.Array  # [m] scaled upper bounds


def _setup(
    data: ADMMData,
    x0: jax.Array,
    settings: ADMMSettings,
    offset: jax.Array | None,
    first: jax.Array | None = None,
) -> _Solve:
    """The per-solve terms at state ``x0`` [4]: only q and the bounds move with x0 (and
    ``offset`` [m], which moves every row's bounds down; ``first`` [2, 2], the first input's
    own [lower, upper] of this solve, which tightens its rows: the rate limit)."""
    dtype = data.MwT.dtype
    x0 = jnp.asarray(x0, dtype)
    alpha = jnp.asarray(settings.alpha, dtype)
    eps_abs = jnp.asarray(settings.eps_abs, dtype)
    eps_rel = jnp.asarray(settings.eps_rel, dtype)
    rho = data.rho
    E, E_inv, c = data.E, 1.0 / data.E, data.cost_scale

    # Per-solve data: only q and the bounds move with x0.
    q = x0 @ data.FT  # unscaled linear term
    g = x0 @ data.GT  # -K⁻¹ q̄
    shift = x0 @ data.bT
    if offset is not None:
        shift = shift + E * jnp.asarray(offset, dtype)
    l0, u0 = data.l0, data.u0
    if first is not None:  # rows 0 and 1 are u_0's (qp.py's row order); E > 0
        first = jnp.asarray(first, dtype)
        l0 = l0.at[:2].set(jnp.maximum(l0[:2], E[:2] * first[0]))
        u0 = u0.at[:2].set(jnp.minimum(u0[:2], E[:2] * first[1]))
    lo, hi = l0 - shift, u0 - shift  # scaled bounds
    eps_pinf = jnp.asarray(settings.eps_prim_inf, dtype)
    return _Solve(
        alpha=alpha,
        eps_abs=eps_abs,
        eps_rel=eps_rel,
        eps_pinf=eps_pinf,
        rho=rho,
        E=E,
        E_inv=E_inv,
        c=c,
        q=q,
        g=g,
        lo=lo,
        hi=hi,
    )


def _iteration(
    data: ADMMData, p: _Solve, settings: ADMMSettings, state: tuple[jax.Array, jax.Array, jax.Array]
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """One ADMM iteration (OSQP alg. 1, lines 4-7) on (x [n], s [m], v [m])."""
    # The loop carries the dual divided by ρ, v = y / ρ (ρ is folded into MwT).
    x, s, v = state
    alpha = p.alpha
    # OSQP alg. 1, line 4: solve the reduced KKT system (eq. 23) for x̃, z̃ = Ā x̃;
    # its right-hand side σx - q̄ + Āᵀ(ρz - y) = σx - q̄ + Āᵀ ρ(z - v).
    x_tilde = (s - v) @ data.MwT + p.g
    if settings.sigma > 0:
        x_tilde = x_tilde + x @ data.MxT
    s_tilde = x_tilde @ data.AT
    # line 5: x ← α x̃ + (1 - α) x
    x_next = alpha * x_tilde + (1.0 - alpha) * x
    # line 6: z ← Π_[l,u](α z̃ + (1 - α) z + y / ρ)
    s_relaxed = alpha * s_tilde + (1.0 - alpha) * s
    s_next = jnp.clip(s_relaxed + v, p.lo, p.hi)
    if settings.penalty is not None:
        # the prox of the exact penalty w·dist(·, [l, u]) in place of the projection: a row
        # whose violation exceeds t moves only t toward its bounds (its dual stays within w)
        a = s_relaxed + v
        s_next = a - jnp.clip(a - s_next, -data.soft, data.soft)
    # line 7: y ← y + ρ (α z̃ + (1 - α) z - z), i.e. v ← v + (α z̃ + (1 - α) z - z)
    v_next = v + (s_relaxed - s_next)
    return x_next, s_next, v_next


def _residuals(
    data: ADMMData, p: _Solve, x: jax.Array, s: jax.Array, y: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Unscaled primal/dual residuals [] and OSQP's termination test (§3.4) of the scaled
    iterate x [n], s [m] and dual y [m]."""
    E, E_inv, c, eps_abs, eps_rel = p.E, p.E_inv, p.c, p.eps_abs, p.eps_rel
    z = x @ data.T.T
    Cz = z @ data.CT
    s_u = E_inv * s
    y_u = E * y / c
    Hz = z @ data.H
    CTy = y_u @ data.CT.T
    prim = _inf_norm(Cz - s_u)
    prim_tol = eps_abs + eps_rel * jnp.maximum(_inf_norm(Cz), _inf_norm(s_u))
    dual = _inf_norm(Hz + p.q + CTy)
    dual_tol = eps_abs + eps_rel * jnp.maximum(
        jnp.maximum(_inf_norm(Hz), _inf_norm(CTy)), _inf_norm(p.q)
    )
    return prim, dual, (prim <= prim_tol) & (dual <= dual_tol)


def _infeasible(data: ADMMData, p: _Solve, y: jax.Array, y_check: jax.Array) -> jax.Array:
    """OSQP's primal infeasibility certificate on δy (§3.4, unscaled terms; homogeneous
    in δy, so c drops out) of the duals y, y_check [m] (carried as y / ρ); bool []."""
    E_inv, eps_pinf = p.E_inv, p.eps_pinf
    dy = p.E * p.rho * (y - y_check)
    dy_norm = _inf_norm(dy)
    return (
        (dy_norm > 0)
        & (_inf_norm(dy @ data.CT.T) <= eps_pinf * dy_norm)
        & (
            (E_inv * p.hi) @ jnp.maximum(dy, 0) + (E_inv * p.lo) @ jnp.minimum(dy, 0)
            < eps_pinf * dy_norm
        )
    )


def _chunk(data: ADMMData, p: _Solve, settings: ADMMSettings, carry: _Carry) -> _Carry:
    """``check_every`` iterations, then the termination test (the while loop's body)."""
    x, s, y = jax.lax.fori_loop(
        0,
        settings.check_every,
        lambda _, state: _iteration(data, p, settings, state),
        (carry.x, carry.s, carry.y),
    )
    prim, dual, converged = _residuals(data, p, x, s, p.rho * y)
    stop = converged
    if settings.stop_on_infeasible:
        stop = stop | _infeasible(data, p, y, carry.y)
    return _Carry(x, s, y, carry.y, carry.chunk + 1, converged, stop, prim, dual)


def _start(data: ADMMData, p: _Solve, warm: ADMMWarm) -> _Carry:
    """The loop's first carry from the warm start (unscaled -> scaled): x̄ = T⁻¹ z,
    ȳ = c Ē⁻¹ y, z̄ = Ā x̄ (as OSQP's warm start)."""
    dtype = data.MwT.dtype
    x_start = jnp.asarray(warm.z, dtype) @ data.T_inv.T
    y_start = p.c * p.E_inv * jnp.asarray(warm.y, dtype) / p.rho  # carried as y / ρ
    s_start = x_start @ data.AT
    zero = jnp.zeros((), dtype)
    return _Carry(
        x_start,
        s_start,
        y_start,
        y_start,
        jnp.zeros((), jnp.int32),
        jnp.zeros((), bool),
        jnp.zeros((), bool),
        zero,
        zero,
    )


def _finish(
    data: ADMMData,
    p: _Solve,
    settings: ADMMSettings,
    carry: _Carry,
    offset: jax.Array | None,
    first_bounds: jax.Array | None = None,
) -> ADMMResult:
    """The result of the last carry: status (the primal infeasibility certificate on δy over
    the last chunk), unscaled z [n] and y [m], the first input (clipped to the input bounds,
    tightened by ``first_bounds``) and the shifted warm start."""
    dtype = data.MwT.dtype
    if settings.penalty is None:
        certificate = _infeasible(data, p, carry.y, carry.y_check)
        status = jnp.where(carry.done, SOLVED, jnp.where(certificate, PRIMAL_INFEASIBLE, MAX_ITER))
    else:
        # the hard QP has no solution where the penalised one's rows stay outside their bounds
        # (with weights above every multiplier of a solvable QP, its solution is the hard one)
        # (judged on a converged solve only: an unconverged iterate's violation says nothing)
        violation = _inf_norm(p.E_inv * (carry.s - jnp.clip(carry.s, p.lo, p.hi)))
        certificate = carry.done & (violation > p.eps_pinf)
        status = jnp.where(certificate, PRIMAL_INFEASIBLE, jnp.where(carry.done, SOLVED, MAX_ITER))

    z = carry.x @ data.T.T
    y = p.E * p.rho * carry.y / p.c
    head = z[:2] if offset is None else z[:2] + jnp.asarray(offset[:2], dtype)
    lower, upper = data.input_lower, data.input_upper
    if first_bounds is not None:
        first_bounds = jnp.asarray(first_bounds, dtype)
        lower = jnp.maximum(lower, first_bounds[0])
        upper = jnp.minimum(upper, first_bounds[1])
    u0 = jnp.clip(head, lower, upper)
    return ADMMResult(
        z=z,
        u0=u0,
        status=status.astype(jnp.int32),
        prim_res=carry.prim_res,
        dual_res=carry.dual_res,
        iters=(carry.chunk * settings.check_every).astype(jnp.int32),
        warm_next=ADMMWarm(z=z[data.z_shift], y=y[data.y_shift]),
    )


def admm_solve(
    data: ADMMData,
    x0: jax.Array,
    warm: ADMMWarm,
    settings: ADMMSettings,
    offset: jax.Array | None = None,
    first: jax.Array | None = None,
) -> ADMMResult:
    """Solve the QP at state ``x0`` [4] from ``warm``; pure, jit-able (settings static).

    ``offset`` [m] (the offset-free MPC's deviation QP, offset_free.py): every row's bounds
    move down by it, and the first input returned is offset[:2] + z[:2] (the input rows' offset
    is the target input u_s), clipped to the input bounds. None: the plain QP.

    ``first`` [2, 2] ([lower, upper] of u_0, absolute, not offset): this solve's own bounds of
    the first input, intersected with its rows' (the rate limit: the input applied last plus
    or minus the most it may change in a period; docs/model.md, "Strength and timing"). With
    -inf / inf every number is the plain QP's, bit for bit. None: no such bounds.

    Batch with ``jax.vmap(admm_solve, in_axes=(None, 0, 0, None))`` (see
    :func:`admm_solve_batch`).

    Steps: :func:`_setup` (per-solve terms), :func:`_start` (warm start), chunks of
    :func:`_chunk` (``check_every`` :func:`_iteration` s, then :func:`_residuals` and
    :func:`_infeasible`) in a ``lax.while_loop``, :func:`_finish` (status and result).
    """
    p = _setup(data, x0, settings, offset, first)
    carry = jax.lax.while_loop(
        lambda carry: (~carry.stop) & (carry.chunk < settings.n_chunks),
        lambda carry: _chunk(data, p, settings, carry),
        _start(data, p, warm),
    )
    return _finish(data, p, settings, carry, offset, first)


def admm_solve_batch(
    data: ADMMData,
    x0: jax.Array,
    warm: ADMMWarm,
    settings: ADMMSettings,
    tile: int | None = None,
    offset: jax.Array | None = None,
    first: jax.Array | None = None,
) -> ADMMResult:
    """``admm_solve`` vmapped over x0 [B, 4], warm ([B, n], [B, m]), offset ([B, m] or None)
    and first ([B, 2, 2] or None), the QP ``data`` shared (one QP per tile of lanes:
    :func:`admm_solve_tiles`).

    With ``tile`` (a divisor of B), the batch is solved as B / tile sequential tiles
    (``lax.map`` over a vmapped solve): each tile's iterates stay in cache, and a tile whose
    solves all converge stops early instead of waiting for the slowest solve of the batch.
    Every lane's iterates are the same whatever its tile: a lane that stopped is held, not
    iterated, while its tile runs on.
    """
    # (offset, first): per-lane arguments that may be None (a None has no leaves to map)
    solve = jax.vmap(lambda x, w, lane: admm_solve(data, x, w, settings, *lane))
    lane = (offset, first)
    if tile is None or tile >= x0.shape[0]:
        return solve(x0, warm, lane)
    return _by_tiles(lambda args: jax.lax.map(lambda a: solve(*a), args), tile, x0, warm, lane)


def _by_tiles(solve, tile: int, x0: jax.Array, warm: ADMMWarm, lane: Any, *leading) -> ADMMResult:
    """``solve((*leading, x0, warm, lane))`` with x0, warm and every leaf of ``lane`` [B, ...]
    split into B / ``tile`` tiles [B / tile, tile, ...] (``leading``: per-tile arguments, given
    as they are), and its result merged back to [B, ...]."""
    batch = x0.shape[0]
    if batch % tile:
        raise ValueError(f"tile {tile} must divide the batch size {batch}")

    def split(a):
        return a.reshape((batch // tile, tile) + a.shape[1:])

    out = solve((*leading, split(x0), jax.tree.map(split, warm), jax.tree.map(split, lane)))
    return jax.tree.map(lambda a: a.reshape((batch,) + a.shape[2:]), out)


def admm_solve_tiles(
    bodies: ADMMData,
    tile_body: jax.Array,
    x0: jax.Array,
    warm: ADMMWarm,
    settings: ADMMSettings,
    tile: int,
    offset: jax.Array | None = None,
    first: jax.Array | None = None,
) -> ADMMResult:
    """``admm_solve`` over x0 [B, 4], warm ([B, n], [B, m]), offset ([B, m] or None) and
    first ([B, 2, 2] or None) in B / ``tile`` tiles of ``tile`` consecutive lanes, every lane
    of tile t solving the QP ``bodies[tile_body[t]]`` (``bodies``: QPs stacked
    [n_bodies, ...], every leaf; tile_body [B / tile] int).

    Within a tile the QP is shared, so its products are [tile, m] x [m, n] matrix products, as
    :func:`admm_solve_batch` computes them for a batch that shares one QP, where one QP per lane
    would read each lane's matrices every iteration (docs/engine.md, "Per-lane bodies", has
    the cost). A lane's row of a product is its own sums: each lane equals its body's shared
    solve (tests/rollout/test_body_tiles.py). One loop for every tile, as ``admm_solve_batch``
    without tiles: it runs to the slowest lane's stop.
    """
    solve = jax.vmap(
        lambda d, x, w, lane: admm_solve(d, x, w, settings, *lane), in_axes=(None, 0, 0, 0)
    )
    per_tile = jax.vmap(
        lambda b, x, w, lane: solve(jax.tree.map(lambda v: v[b], bodies), x, w, lane)
    )
    return _by_tiles(lambda args: per_tile(*args), tile, x0, warm, (offset, first), tile_body)
