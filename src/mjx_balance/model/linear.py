"""Analytic linearisation about upright (foot held flat), both conventions (docs/model.md,
"Linear model and discretisation" and "Two conventions").

Notation. Joint angles q = [q_a, q_h]; absolute segment tilts theta = [q1, q2] = S q with
S = [[1, 0], [1, 1]]. Lagrangian of the two-link body on a fixed foot, linearised about
theta = 0 (c1, c2: CoM distances above the ankle and the hip; L1: lower-body length):

    M_abs = [[I1 + m1 c1^2 + m2 L1^2,  m2 L1 c2      ],
             [m2 L1 c2,                I2 + m2 c2^2  ]]
    G_abs = g diag(m1 c1 + m2 L1, m2 c2)                 (gravity's destabilising stiffness)
    M_abs theta'' = G_abs theta + Q_abs                  (Q_abs: generalised forces on theta)

A convention picks its coordinates y = P^-1 theta and inputs u with Q_abs = P^-T u, so that in
both M y'' = G y + u with M = P^T M_abs P and G = P^T G_abs P:

    paper: P = I  (y = theta, u = [tau1, tau2]; tau_ankle = tau1 + tau2, tau_hip = tau2)
    joint: P = S  (y = q,     u = [tau_ankle, tau_hip])

Hip servo (BodyParams.hip_servo_stiffness K, hip_servo_damping D; both 0 by default): a passive
spring-damper in the plant with generalised force -K q_h - D dq_h on the hip joint, i.e.
-Kj q - Dj q' with Kj = diag(0, K), Dj = diag(0, D) in joint coordinates. With q = W y,
W = S^-1 P, virtual work gives the force W^T (-Kj q - Dj q') on y, so

    M y'' = (G - Ks) y - Ds y' + u,   Ks = W^T Kj W,  Ds = W^T Dj W.

State x = [y, y'] (4,), input u (2,). Continuous: x' = Ac x + Bc u; discrete (exact
zero-order hold over the control period): x+ = A x + B u.

CoP (foot in static equilibrium, moments about the ankle at height h above the sole; the hip
servo acts between lower and upper body, not on the foot):
    cop = -(tau_ankle + h Fx) / (M g),  Fx = sum_i m_i x_i''  (linearised)
CoM (horizontal, all three segments, foot CoM at x = 0):  com = sum_i m_i x_i / M.
Both are linear: cop = cop_x @ x + cop_u @ u, com = com_x @ x.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .params import BodyParams

S = np.array([[1.0, 0.0], [1.0, 1.0]])


@dataclass(frozen=True, eq=False)
class LinearModel:
    """Linear model of one convention. Arrays are float64 numpy."""

    convention: str
    dt: float
    Ac: np.ndarray  # [4, 4]
    Bc: np.ndarray  # [4, 2]
    A: np.ndarray  # [4, 4] discrete, ZOH at dt
    B: np.ndarray  # [4, 2]
    cop_x: np.ndarray  # [4]
    cop_u: np.ndarray  # [2]
    com_x: np.ndarray  # [4]
    P: np.ndarray  # [2, 2] theta = P y
    torque_map: np.ndarray  # [2, 2] [tau_ankle, tau_hip] = torque_map @ u
    # [2] a generalised force d beside u (M y'' = (G - Ks) y - Ds y' + u + d) moves the CoP
    # by cop_d @ d through the accelerations only (offset_free.py):
    # cop_d = cop_u + torque_map[0] / (M g)
    cop_d: np.ndarray

    def state_from_joints(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Convention state from joint angles/rates [q_a, q_h] (works on batches [..., 2])."""
        to_y = np.linalg.solve(self.P, S)  # y = P^-1 S q
        return np.concatenate([q @ to_y.T, dq @ to_y.T], axis=-1)

    def joints_from_state(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        to_q = np.linalg.solve(S, self.P)
        return x[..., :2] @ to_q.T, x[..., 2:] @ to_q.T

    def motor_torques(self, u: np.ndarray) -> np.ndarray:
        """[tau_ankle, tau_hip] from the convention's input (batches [..., 2])."""
        return u @ self.torque_map.T


def mass_gravity_abs(body: BodyParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M_abs, G_abs, J) in absolute tilts; J theta = sum_i m_i x_i (linearised)."""
    m1, m2 = body.lower_mass, body.upper_mass
    c1, c2, L1 = body.lower_com, body.upper_com, body.lower_length
    M = np.array(
        [
            [body.lower_pitch_inertia + m1 * c1**2 + m2 * L1**2, m2 * L1 * c2],
            [m2 * L1 * c2, body.upper_pitch_inertia + m2 * c2**2],
        ]
    )
    G = body.gravity * np.diag([m1 * c1 + m2 * L1, m2 * c2])
    J = np.array([m1 * c1 + m2 * L1, m2 * c2])
    return M, G, J


def servo_matrices(body: BodyParams, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Ks, Ds) [2, 2]: the hip servo's stiffness and damping in coordinates y (theta = P y)."""
    W = np.linalg.solve(S, P)  # q = W y
    Kj = np.diag([0.0, body.hip_servo_stiffness])
    Dj = np.diag([0.0, body.hip_servo_damping])
    return W.T @ Kj @ W, W.T @ Dj @ W


def zoh(Ac: np.ndarray, Bc: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation via the matrix exponential of [[Ac, Bc], [0, 0]]."""
    n, m = Bc.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n] = Ac
    block[:n, n:] = Bc
    E = scipy.linalg.expm(block * dt)
    return E[:n, :n], E[:n, n:]


def delay_predictor(
    Ac: np.ndarray, Bc: np.ndarray, dt: float, delay_steps: int, substeps: int
) -> tuple[np.ndarray, np.ndarray]:
    """The delay compensator's matrices: (A_h^d [n, n], G [P, n, m]), P = ceil(d / S).

    With (A_h, B_h) = zoh(Ac, Bc, dt) (one physics step), a measurement x_meas taken d steps
    before the control instant k S and the inputs held since, u(i) for physics steps i in
    [k S - d, k S), the linear model predicts x(k S) = A_h^d x_meas + sum_i A_h^(k S - 1 - i)
    B_h u(i). The input is constant over a control period, so the sum is over the P periods
    that overlap the window: step i = k S - 1 - m belongs to period k - 1 - floor(m / S), and
    G[j] = sum of A_h^m B_h over m in [0, d) with floor(m / S) = j multiplies u_{k-1-j}.
    """
    Ah, Bh = zoh(Ac, Bc, dt)
    n, m = Bh.shape
    d, S = int(delay_steps), int(substeps)
    G = np.zeros((-(-d // S), n, m))
    power = np.eye(n)
    for step in range(d):
        G[step // S] += power @ Bh
        power = Ah @ power
    return power, G


def predict(xp, Ad, G, x_meas, inputs):
    """The compensated state A_h^d x_meas + sum_j G[j] inputs[j] (inputs [P, m]: the inputs
    of the last P control periods, newest first; ``xp``: numpy or jax.numpy)."""
    return Ad @ x_meas + xp.einsum("pij,pj->i", G, inputs)


def linear_model(body: BodyParams, convention: str, dt: float) -> LinearModel:
    """The linear model of ``convention`` ("paper" or "joint") discretised at ``dt``."""
    if convention == "paper":
        P = np.eye(2)
        torque_map = np.array([[1.0, 1.0], [0.0, 1.0]])
    elif convention == "joint":
        P = S.copy()
        torque_map = np.eye(2)
    else:
        raise ValueError(f"convention must be 'paper' or 'joint', got {convention!r}")
    M_abs, G_abs, J_abs = mass_gravity_abs(body)
    M = P.T @ M_abs @ P
    G = P.T @ G_abs @ P
    Ks, Ds = servo_matrices(body, P)
    Minv = np.linalg.inv(M)
    Ac = np.block([[np.zeros((2, 2)), np.eye(2)], [Minv @ (G - Ks), -Minv @ Ds]])
    Bc = np.vstack([np.zeros((2, 2)), Minv])
    A, B = zoh(Ac, Bc, dt)

    J = J_abs @ P  # sum m_i x_i = J y
    total_weight = body.total_mass * body.gravity
    h = body.ankle_height
    # cop = -(tau_ankle + h J y'') / (M g), y'' = Minv ((G - Ks) y - Ds y' + u)
    cop_y = -h * (J @ Minv @ (G - Ks)) / total_weight
    cop_dy = h * (J @ Minv @ Ds) / total_weight
    cop_u = -(torque_map[0] + h * (J @ Minv)) / total_weight
    cop_d = -h * (J @ Minv) / total_weight
    cop_x = np.concatenate([cop_y, cop_dy])
    com_x = np.concatenate([J / body.total_mass, np.zeros(2)])
    return LinearModel(
        convention=convention,
        dt=dt,
        Ac=Ac,
        Bc=Bc,
        A=A,
        B=B,
        cop_x=cop_x,
        cop_u=cop_u,
        com_x=com_x,
        P=P,
        torque_map=torque_map,
        cop_d=cop_d,
    )
