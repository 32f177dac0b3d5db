"""The condensed MPC quadratic program (docs/model.md, "The MPC"), built once per controller
configuration.

Decision variable: the input sequence z = [u_0; ...; u_{N-1}] (n = 2N). Predicted states
X = [x_1; ...; x_N] = Phi x0 + Gamma z. The QP solved at every control instant is

    minimise  ½ zᵀ H z + (F x0)ᵀ z
    subject to  lower0 - E x0  <=  C z  <=  upper0 - E x0

with H = Gammaᵀ Qbar Gamma + Rbar (Qbar = blkdiag(Q, ..., Q, Q_f), Rbar = blkdiag(R, ...)),
F = Gammaᵀ Qbar Phi, and the constraint rows stacked in this order (m = 6N rows):

    inputs   u_k              k = 0..N-1   (2N rows)
    states   x_k[0], x_k[1]   k = 1..N     (2N rows; velocities are free)
    cop      cop(x_k, u_k)    k = 0..N-1   (N rows)
    com      com(x_k)         k = 1..N     (N rows)

Only x0 changes between solves (and between scenarios): H, F, C, E, lower0, upper0 are fixed.
Q_f solves the discrete algebraic Riccati equation for (A, B_free, Q, R_free), where "free" are
the inputs that can act: an input whose bounds are [0, 0] (a motor switched off, e.g. the hip in
the ankle-only study) is left out, since the terminal weight is the cost-to-go of the LQR that
the controller can actually apply; a Q_f that assumed the switched-off input would promise a
cheap correction that never comes (with the paper convention's hip off it makes the closed loop
unstable even at rest).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from ..model.linear import LinearModel, linear_model
from ..model.params import BodyParams, ControllerParams


@dataclass(frozen=True, eq=False)
class CondensedQP:
    """Fixed matrices of the condensed MPC QP (float64 numpy)."""

    horizon: int
    H: np.ndarray  # [n, n]
    F: np.ndarray  # [n, 4]   linear term q = F x0
    C: np.ndarray  # [m, n]
    E: np.ndarray  # [m, 4]   bounds shift with x0
    lower0: np.ndarray  # [m]
    upper0: np.ndarray  # [m]
    Qf: np.ndarray  # [4, 4]
    rows: dict  # name -> slice into the m constraint rows
    input_lower: np.ndarray  # [2]
    input_upper: np.ndarray  # [2]
    linear: LinearModel

    @property
    def n(self) -> int:
        return self.H.shape[0]

    @property
    def m(self) -> int:
        return self.C.shape[0]

    def linear_term(self, x0: np.ndarray) -> np.ndarray:
        return self.F @ x0

    def bounds(
        self, x0: np.ndarray, offset: np.ndarray | None = None, first: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The bounds at state ``x0``; ``offset`` [m]: the rows' values at the offset-free
        target, subtracted (the deviation QP, offset_free.py); ``first`` [2, 2]: the first
        input's own [lower, upper] of this solve (absolute), intersected with its rows' (the
        rate limit, docs/model.md "Strength and timing"; rows 0 and 1 are u_0's)."""
        shift = self.E @ x0 + (0.0 if offset is None else np.asarray(offset, float))
        lower0, upper0 = self.lower0, self.upper0
        if first is not None:
            first = np.asarray(first, float)
            lower0, upper0 = lower0.copy(), upper0.copy()
            lower0[:2] = np.maximum(lower0[:2], first[0])
            upper0[:2] = np.minimum(upper0[:2], first[1])
        return lower0 - shift, upper0 - shift

    def predict(self, x0: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Predicted states [N, 4] for input sequence z."""
        lm, N = self.linear, self.horizon
        xs, x = [], x0
        for k in range(N):
            x = lm.A @ x + lm.B @ z[2 * k : 2 * k + 2]
            xs.append(x)
        return np.array(xs)

    def clip_input(self, u: np.ndarray, first: np.ndarray | None = None) -> np.ndarray:
        """``u`` [2] within the input bounds (and ``first``'s [lower, upper], the rate limit)."""
        if first is None:
            return np.clip(u, self.input_lower, self.input_upper)
        first = np.asarray(first, float)
        lower = np.maximum(self.input_lower, first[0])
        return np.clip(u, lower, np.minimum(self.input_upper, first[1]))

    def feasible(
        self, x0: np.ndarray, offset: np.ndarray | None = None, first: np.ndarray | None = None
    ) -> bool:
        """Whether some input sequence meets every constraint for state ``x0``: the linear
        program min 0 s.t. lower <= C z <= upper, solved by HiGHS (scipy) to its default
        primal feasibility tolerance 1e-7. An exact test, independent of the ADMM and OSQP."""
        lower, upper = self.bounds(np.asarray(x0, float), offset, first)
        lo, hi = np.isfinite(lower), np.isfinite(upper)
        A = np.concatenate([self.C[hi], -self.C[lo]])
        b = np.concatenate([upper[hi], -lower[lo]])
        result = scipy.optimize.linprog(
            np.zeros(self.n), A_ub=A, b_ub=b, bounds=(None, None), method="highs"
        )
        if result.status not in (0, 2):  # 0 optimal (feasible), 2 infeasible
            raise RuntimeError(f"feasibility LP failed: {result.message}")
        return result.status == 0


def rate_bounds(xp, u_last, step):
    """The first input's own [lower, upper] [2, 2] under the rate limit: the input applied
    last plus or minus the most it may change in a period (``step`` [2]; inf: no limit), for
    array namespace ``xp`` (numpy or jax.numpy, each in its arrays' dtype)."""
    return xp.stack([u_last - step, u_last + step])


def shift_warm_start(z: np.ndarray) -> np.ndarray:
    """Previous solution shifted one step, the last input repeated (works on batches [..., n])."""
    return np.concatenate([z[..., 2:], z[..., -2:]], axis=-1)


def terminal_weight(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, input_bounds
) -> np.ndarray:
    """DARE solution for the inputs whose bounds are not [0, 0] (see the module docstring)."""
    free = [i for i, (lo, hi) in enumerate(input_bounds) if not (lo == 0.0 and hi == 0.0)]
    if not free:
        raise ValueError("every input is bounded to [0, 0]: there is nothing to control with")
    return scipy.linalg.solve_discrete_are(A, B[:, free], Q, R[np.ix_(free, free)])


def _prediction_matrices(
    A: np.ndarray, B: np.ndarray, N: int
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The powers A^0..A^N, Phi and Gamma of the states over N steps: x = Phi x0 + Gamma z."""
    nx, nu = B.shape
    powers = [np.eye(nx)]
    for _ in range(N):
        powers.append(A @ powers[-1])
    Phi = np.vstack(powers[1:])  # [N nx, nx], row block k-1 is A^k
    Gamma = np.zeros((N * nx, N * nu))
    for k in range(1, N + 1):
        for j in range(k):
            Gamma[(k - 1) * nx : k * nx, j * nu : (j + 1) * nu] = powers[k - 1 - j] @ B
    return powers, Phi, Gamma


def build_qp(controller: ControllerParams, body: BodyParams, control_dt: float) -> CondensedQP:
    """Build the condensed QP of ``controller`` for ``body`` at the control period."""
    lm = linear_model(body, controller.convention, control_dt)
    A, B = lm.A, lm.B
    N = controller.horizon
    nx, nu = B.shape
    Q = np.diag(controller.q_diag)
    R = np.diag(controller.r_diag)
    Qf = terminal_weight(A, B, Q, R, controller.input_bounds)

    powers, Phi, Gamma = _prediction_matrices(A, B, N)
    Qbar = scipy.linalg.block_diag(*([Q] * (N - 1) + [Qf]))
    Rbar = scipy.linalg.block_diag(*([R] * N))
    H = Gamma.T @ Qbar @ Gamma + Rbar
    H = 0.5 * (H + H.T)
    F = Gamma.T @ Qbar @ Phi

    n = N * nu
    # x_k as affine function of (z, x0): x_k = Gk z + Pk x0, k = 0..N.
    Gk = [np.zeros((nx, n))] + [Gamma[(k - 1) * nx : k * nx] for k in range(1, N + 1)]
    Pk = powers
    blocks_C: list[np.ndarray]
    blocks_E: list[np.ndarray]
    lows: list[np.ndarray | list[float]]
    highs: list[np.ndarray | list[float]]
    blocks_C, blocks_E, lows, highs = [], [], [], []

    (u1l, u1h), (u2l, u2h) = controller.input_bounds
    blocks_C.append(np.eye(n))
    blocks_E.append(np.zeros((n, nx)))
    lows.append(np.tile([u1l, u2l], N))
    highs.append(np.tile([u1h, u2h], N))

    (s1l, s1h), (s2l, s2h) = controller.state_bounds
    for k in range(1, N + 1):
        blocks_C.append(Gk[k][:2])
        blocks_E.append(Pk[k][:2])
        lows.append([s1l, s2l])
        highs.append([s1h, s2h])

    for k in range(N):
        row = lm.cop_x @ Gk[k]
        row = row.copy()
        row[k * nu : (k + 1) * nu] += lm.cop_u
        blocks_C.append(row[None])
        blocks_E.append((lm.cop_x @ Pk[k])[None])
        lows.append([controller.cop_bounds[0]])
        highs.append([controller.cop_bounds[1]])

    for k in range(1, N + 1):
        blocks_C.append((lm.com_x @ Gk[k])[None])
        blocks_E.append((lm.com_x @ Pk[k])[None])
        lows.append([controller.com_bounds[0]])
        highs.append([controller.com_bounds[1]])

    rows = {
        "inputs": slice(0, n),
        "states": slice(n, 2 * n),
        "cop": slice(2 * n, 2 * n + N),
        "com": slice(2 * n + N, 2 * n + 2 * N),
    }
    return CondensedQP(
        horizon=N,
        H=H,
        F=F,
        C=np.vstack(blocks_C),
        E=np.vstack(blocks_E),
        lower0=np.concatenate([np.asarray(v, float) for v in lows]),
        upper0=np.concatenate([np.asarray(v, float) for v in highs]),
        Qf=Qf,
        rows=rows,
        input_lower=np.array([u1l, u2l]),
        input_upper=np.array([u1h, u2h]),
        linear=lm,
    )


# -- what a configuration's QP costs and whether float32 can solve it -------------------------

FLOAT32_EPS = 2.0**-23  # float32's machine epsilon (unit roundoff x 2)


def qp_bytes(horizon: int) -> int:
    """Host memory of the dense QP and ADMM matrices of a horizon-``horizon`` MPC, built in
    float64 [bytes]: with n = 2N inputs and m = 6N rows, H, its whitening T and T⁻¹, the ADMM's
    K⁻¹-folded n x n matrix (4 n²), C, Cᵀ, the folded m x n matrix and its transpose (4 m n =
    12 n²), counted as 16 n² numbers, doubled for the temporaries of the build (the prediction
    matrices Phi, Gamma). Exact in Python integers for any horizon."""
    n = 2 * int(horizon)
    return 2 * 16 * n * n * 8


def float32_conditioning(qp: CondensedQP) -> float:
    """κ(H)·ε_float32: the condition number of the condensed Hessian times float32's epsilon,
    the first-order relative error of solving with H in float32. Below 1 the batched ADMM
    (float32) can resolve the QP; at or above 1 its solution carries no correct digit (inf when
    H is not positive definite in float64). Measured against OSQP at 1e-7 on 4 states near rest
    (default weights): κ·ε = 0.24 (N = 60) -> first input within 0.34 % of its range; 7.9 (N =
    80) -> 26 %; 33 (control_dt = 0.05 s, N = 20) -> 55 % (docs/reliability.md)."""
    if not np.all(np.isfinite(qp.H)):
        return float("inf")
    eigenvalues = np.linalg.eigvalsh(0.5 * (qp.H + qp.H.T))
    if not eigenvalues[0] > 0:
        return float("inf")
    return float(eigenvalues[-1] / eigenvalues[0] * FLOAT32_EPS)
