"""Certified recovery: states from which the closed loop provably stays settled.

A sweep stops a scenario as soon as its outcome is decided. A fall decides itself; a recovery is
decided when the rest of the window cannot change the summary. This module derives, from the
controller alone, the test :func:`certified` for that, exact for the linear model, with a
margin for what the linear model leaves out.

The argument. P is the MPC's terminal weight (``qp.Qf``, the DARE solution for (A, B, Q, R))
and K the matching LQR gain K = (R + BᵀPB)⁻¹BᵀPA, so V(x) = xᵀPx decreases along
x⁺ = (A - BK)x: V(x⁺) = V(x) - xᵀ(Q + KᵀRK)x, and every level set E(c) = {xᵀPx <= c} is
invariant under u = -Kx. Over E(c) a linear function gᵀx ranges over ±sqrt(c gᵀP⁻¹g).

1. The MPC is the LQR. Along the LQR prediction from x every QP row (inputs, state bounds, CoP,
   CoM over the horizon) is a linear function of x; ``qp_level`` is the largest c for which all
   of them stay strictly inside their bounds on E(c). With the DARE terminal weight the
   unconstrained MPC equals the LQR, and here the LQR sequence is feasible, so it is the QP's
   minimiser: the MPC applies u = -Kx now and, by invariance, at every later instant.
2. The future is predicted exactly (linear model, u held over a period, ZOH solution at every
   physics sample j dt): ``rows`` give joint angles, joint rates, motor torques, CoP and CoM
   relative to rest at each sample of the next ``PREDICTED_PERIODS`` periods, and after those the
   state lies in E(V(Acl^k0 x)), which bounds every quantity through ``tail_reach``.
3. The summary is final if the predicted future stays inside the settle band (no sample leaves
   it: recovered, settle time final) and inside the peaks already recorded (joint angles,
   motor torques). The linear model has no foot; its pitch follows the CoP (measured bound
   :data:`PITCH_PER_COP`, :data:`PITCH_FLOOR`), and the running peak foot pitch must exceed
   what the predicted CoP allows.
4. CoP and CoM extremes are not required to be final: on the side the push drove them they
   are (the body returns to rest), but on the other side the full run's extreme is set near
   rest in the seconds an early stop skips (the CoP settles from either side), within the
   predicted CoP and CoM range (the difference measured: docs/engine.md, 0.1 mm).
5. Near-zero pushes. Standing still, the closed loop jitters (the float32 contacts, the ADMM's
   finite accuracy), and the check's bounds from a jittering state, with their margins, stay
   above the peaks of a push of a few newtons or less: it would never be certified (the foot
   pitch's bound never falls below PITCH_FLOOR, above what such a push rocks the foot). So a
   peak whose predicted future stays below the quantity's noise floor (:data:`ANGLE_FLOOR`,
   :data:`TORQUE_FLOOR`, and for the foot pitch the bound of a CoP within :data:`COP_FLOOR`;
   the floors lie above what the bounds read at rest) is not required to be final: the certified
   value may lie below the full run's, by less than the floor, and only where the recorded peak
   is itself below the floor (a push that moves a quantity beyond its floor keeps that peak
   exact). A push of 0 N is over from its start (:func:`push_over`): it adds nothing to the
   physics, whatever its duration.

Margins for the real plant (contact, nonlinearity, the ADMM's accuracy, float32): predicted
values must stay within MARGIN of their limit, and V may grow by GROWTH in the QP test and the
tail. The room actually used is measured by ``python -m mjx_balance.rollout.margins`` (full-length
runs of certified scenarios; docs/engine.md gives the figures).

After certification the remaining control periods are counted in ``control_periods`` (every QP
is solved, no input saturates); energies and work go on as the linear prediction says for its
2 s (up to t_end), what comes later is left out (measured: docs/engine.md); the ADMM iteration
total counts the periods run. No certificate with a controller delay or a hip servo (the
argument does not hold as stated), nor with a rate limit on the inputs (the LQR law may change
faster than it allows): those scenarios run to t_end.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..model.linear import S as JOINT_TO_ABS
from ..model.linear import zoh
from .qp import CondensedQP

# Model error allowed for: a prediction must stay within MARGIN of each limit (the real plant
# may exceed the linear prediction by a factor 1 / MARGIN), and V may grow by GROWTH.
MARGIN = 0.5
GROWTH = 4.0
# Control periods predicted row by row before the tail is bounded by the level set.
PREDICTED_PERIODS = 200
# A scenario is checked every CHECK_EVERY control periods of its own (k = CHECK_EVERY, 2
# CHECK_EVERY, ...): the check costs about 40 % of a period at rest on a CPU.
CHECK_EVERY = 5
# The foot is not in the linear model. Its pitch (rocking on the compliant contacts) follows the
# CoP: |pitch| <= PITCH_PER_COP |CoP - rest| + PITCH_FLOOR on every sample of recovering runs,
# measured (largest ratio 0.021 rad/m, largest pitch with the CoP within 0.1 mm of rest 8.8e-6
# rad, over pushes of 5-80 N both ways; ``python -m mjx_balance.rollout.margins``), with margin.
PITCH_PER_COP = 0.03
PITCH_FLOOR = 2e-5
# Noise floors of the running peaks. Standing unpushed, the closed loop is not exactly at rest
# (the float32 contacts, the ADMM's finite accuracy), and the check's own bounds on the future,
# evaluated at rest, read up to 1.3e-5 rad (joint angles), 0.063 N m (motor torques) and 8.1e-5 m
# (CoP excursion) over a 0-N run of the whole window (the default body and five cohort
# subjects: ``python docs/scripts/near_zero.py noise``). Below its floor a running peak is not
# required to be final (:func:`check`, rule 5 of the module docstring). The floors are those
# figures with a factor of about 2 for bodies and slot counts not measured.
ANGLE_FLOOR = 3e-5  # rad
TORQUE_FLOOR = 0.15  # N m
COP_FLOOR = 2e-4  # m

# Quantities predicted (columns of Certificate.rows): joint angles, joint rates, motor torques,
# CoP and CoM relative to rest, the convention's angles and inputs.
TAIL_FIELDS = (
    "energy_ankle",
    "energy_hip",
    "work_ankle",
    "work_hip",
    "energy_u1",
    "energy_u2",
    "work_u1",
    "work_u2",
)
QUANTITIES = (
    "q_ankle",
    "q_hip",
    "dq_ankle",
    "dq_hip",
    "tau_ankle",
    "tau_hip",
    "cop",
    "com",
    "y1",
    "y2",
    "u1",
    "u2",
)


class Certificate(NamedTuple):
    """What :func:`certified` needs (arrays; cast to the working dtype by the caller)."""

    rows: np.ndarray  # [n, 12, 4] the quantities at every physics sample of the prediction
    tail: np.ndarray  # [4, 4] P_tail = (Acl^k0)ᵀ P Acl^k0
    tail_reach: np.ndarray  # [12] largest |quantity| over a period from E(1)
    to_q: np.ndarray  # [2, 2] joint angles from the convention's angles
    P: np.ndarray  # [4, 4] V(x) = xᵀPx
    qp_level: float  # V(x) <= qp_level: no QP constraint is ever active (linear model)
    band: np.ndarray  # [4] settle tolerances of q_ankle, q_hip, dq_ankle, dq_hip
    rest: np.ndarray  # [2] CoP and CoM at rest (world x, m; equal in static equilibrium)
    pitch_per_cop: float
    pitch_floor: float
    floor: np.ndarray  # [12] noise floors of the running peaks (0 where no peak is kept)
    # 1: a passed check stops the scenario (early stopping); 0: no check ever passes (full
    # length). Data, so that both modes run one compiled program.
    stops: Any = 1.0


def lqr_gain(qp: CondensedQP, r_diag) -> np.ndarray:
    """K [2, 4] of the LQR whose cost-to-go is qp.Qf; inputs bounded to [0, 0] get 0."""
    lm = qp.linear
    free = [i for i in range(2) if not (qp.input_lower[i] == 0.0 and qp.input_upper[i] == 0.0)]
    P, A, B = qp.Qf, lm.A, lm.B[:, free]
    R = np.diag(r_diag)[np.ix_(free, free)]
    K = np.zeros((2, 4))
    K[free] = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    return K


def _reach(rows: np.ndarray, P_inv: np.ndarray) -> np.ndarray:
    """sqrt(gᵀP⁻¹g) for each row g (last axis): the range of gᵀx over E(1)."""
    return np.sqrt(np.einsum("...i,ij,...j->...", rows, P_inv, rows))


def build(
    qp: CondensedQP,
    controller,
    scenario,
    *,
    rest: tuple[float, float],
    periods: int = PREDICTED_PERIODS,
) -> Certificate:
    """The certificate of a controller (float64 numpy); see the module docstring."""
    lm = qp.linear
    K = lqr_gain(qp, controller.r_diag)
    P = qp.Qf
    P_inv = np.linalg.inv(P)
    Acl = lm.A - lm.B @ K
    # QP rows along the LQR prediction from x: z = L x, rows E + C L, inside their bounds on
    # E(qp_level). (A row's value at rest is 0.)
    L, M = [], np.eye(4)
    for _ in range(qp.horizon):
        L.append(-K @ M)
        M = Acl @ M
    qp_rows = qp.E + qp.C @ np.vstack(L)
    limit = np.minimum(qp.upper0, -qp.lower0)
    reach = _reach(qp_rows, P_inv)
    use = np.isfinite(limit) & (reach > 0)
    if (limit[use] <= 0).any():
        raise ValueError("a constraint of the QP is active at rest: no certificate")
    qp_level = float(np.min((limit[use] / reach[use]) ** 2))

    # The quantities at sample j of a period that starts in x (u = -K x held): x_j = M_j x.
    to_q = np.linalg.solve(JOINT_TO_ABS, lm.P)  # joint angles q = to_q @ y
    per_sample: list[np.ndarray] | np.ndarray  # the samples' matrices, then stacked
    per_sample = []
    for j in range(1, scenario.substeps + 1):
        Aj, Bj = zoh(lm.Ac, lm.Bc, j * scenario.physics_dt)
        Mj = Aj - Bj @ K
        per_sample.append(
            np.vstack(
                [
                    to_q @ Mj[:2],
                    to_q @ Mj[2:],
                    -lm.torque_map @ K,
                    (lm.cop_x @ Mj - lm.cop_u @ K)[None],
                    (lm.com_x @ Mj)[None],
                    Mj[:2],
                    -K,
                ]
            )
        )
    per_sample = np.stack(per_sample)  # [S, 12, 4]
    rows, power = [], np.eye(4)
    for _ in range(periods):
        rows.append(per_sample @ power)
        power = Acl @ power
    return Certificate(
        rows=np.concatenate(rows),
        tail=power.T @ P @ power,
        tail_reach=_reach(per_sample, P_inv).max(axis=0),
        to_q=to_q,
        P=P,
        qp_level=qp_level,
        band=np.array([scenario.settle_angle_tol] * 2 + [scenario.settle_rate_tol] * 2),
        rest=np.asarray(rest, float),
        pitch_per_cop=PITCH_PER_COP,
        pitch_floor=PITCH_FLOOR,
        floor=noise_floors(),
    )


def noise_floors() -> np.ndarray:
    """[12] the floors of the quantities (:data:`QUANTITIES`) whose peaks the summary keeps:
    joint angles, motor torques, and the CoP's through the foot pitch (0 elsewhere)."""
    floor = np.zeros(len(QUANTITIES))
    floor[[0, 1]] = ANGLE_FLOOR
    floor[[4, 5]] = TORQUE_FLOOR
    floor[6] = COP_FLOOR
    return floor


def push_over(step, n_push, force):
    """Whether no physics step from ``step`` on is pushed: the push of ``n_push`` steps has
    ended, or its force is zero (a push of 0 N is no push, whatever its duration: the physics
    adds nothing in either case)."""
    return (step >= n_push) | (force == 0)


def applies(config) -> bool:
    """Whether a configuration has a certificate (no controller delay, no hip servo, not the
    offset-free controller, whose observer and target are outside the certified loop, no rate
    limit, which the LQR law of the argument does not obey) and is the MPC's (control/law.py:
    another controller's loop is not the one certified)."""
    body = config.body
    return (
        config.controller.kind == "mpc"
        and config.scenario.delay_steps == 0
        and body.hip_servo_stiffness == 0
        and body.hip_servo_damping == 0
        and not config.controller.offset_free
        and config.controller.input_rates is None
    )


def check(xp, cert: Certificate, x, acc, push_over, samples_left):
    """Whether a scenario is decided as recovered, and the integrals of its predicted future
    (:func:`tail_integrals`), for array namespace ``xp`` (numpy or jax.numpy).

    x: [4] the convention state at the next control instant; acc: the running accumulators
    (``rollout.kernel.Accumulators``); push_over: the push acts in no later physics step
    (:func:`push_over`);
    samples_left: physics samples before t_end (the integrals stop there).
    """
    pred = xp.einsum("nqi,i->nq", cert.rows, x)  # [n, 12]
    tail = xp.sqrt(GROWTH * (x @ cert.tail @ x)) * cert.tail_reach  # [12]
    high = xp.maximum(pred.max(axis=0), tail) / MARGIN  # largest future value, with margin
    low = xp.minimum(pred.min(axis=0), -tail) / MARGIN
    size = xp.maximum(high, -low)
    band = (size[:4] <= cert.band).all()
    # a peak is final if the future stays below it, or if the future stays below its noise
    # floor (rule 5: the full run's peak then differs by less than the floor)
    floor = cert.floor
    pitch_floor = cert.pitch_per_cop * floor[6] + cert.pitch_floor
    peaks = (
        (size[0] <= xp.maximum(acc.peak_ankle, floor[0]))
        & (size[1] <= xp.maximum(acc.peak_hip, floor[1]))
        & (size[4] <= xp.maximum(acc.peak_tau_ankle, floor[4]))
        & (size[5] <= xp.maximum(acc.peak_tau_hip, floor[5]))
        & (
            cert.pitch_per_cop * size[6] + cert.pitch_floor
            <= xp.maximum(acc.peak_foot_pitch, pitch_floor)
        )
    )
    qp_free = GROWTH * (x @ cert.P @ x) <= cert.qp_level
    # (the current sample is in the band whenever the prediction is, for the default model; kept
    # as a guard for others)
    ok = push_over & acc.alive & acc.in_band & band & peaks & qp_free & (cert.stops != 0)
    return ok, tail_integrals(xp, cert, x, pred, samples_left)


def tail_integrals(xp, cert: Certificate, x, pred, samples_left) -> dict:
    """The energies and work of the predicted future ``pred`` (``PREDICTED_PERIODS`` periods
    from x), in the accumulators' definitions: sum |tau Δq| and tau Δq per joint, sum |u Δy|
    and u Δy per input (``metrics.increments``), up to ``samples_left`` samples (t_end). Added to a
    certified scenario's accumulators in place of the steps it does not run; what comes after
    the prediction is left out (measured: docs/engine.md)."""
    q = xp.concatenate([(cert.to_q @ x[:2])[None], pred[:, 0:2]])
    y = xp.concatenate([x[None, :2], pred[:, 8:10]])
    before_end = (xp.arange(pred.shape[0]) < samples_left)[:, None]
    power = xp.where(before_end, pred[:, 4:6] * (q[1:] - q[:-1]), 0)
    power_u = xp.where(before_end, pred[:, 10:12] * (y[1:] - y[:-1]), 0)
    return {
        "energy_ankle": xp.abs(power[:, 0]).sum(),
        "energy_hip": xp.abs(power[:, 1]).sum(),
        "work_ankle": power[:, 0].sum(),
        "work_hip": power[:, 1].sum(),
        "energy_u1": xp.abs(power_u[:, 0]).sum(),
        "energy_u2": xp.abs(power_u[:, 1]).sum(),
        "work_u1": power_u[:, 0].sum(),
        "work_u2": power_u[:, 1].sum(),
    }
