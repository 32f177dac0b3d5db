"""The outcome rules of one push scenario and the summary schema, written once.

Every rule here is a function of an array namespace ``xp`` (``numpy`` or ``jax.numpy``): the
scalar reference (``metrics.summarize``, numpy, on whole sample series) and the batched closed
loop (``rollout.kernel``, JAX, one sample at a time inside the scan) call the same functions,
so the two paths cannot drift apart. Only elementwise operations and reductions over the last
axis are used, so a rule applies to one sample or to a series of them alike.

Samples. A sample is taken after every physics step i = 0..n-1, at time t = (i+1) dt: joint
angles q = (q_a, q_h) and rates dq, the convention state x (4), the foot pitch, the lowest
point of each load-cell sphere, and the inputs u held during step i.

Fall. The first sample where the foot pitches beyond ``foot_pitch_limit``, a load-cell sphere's
lowest point rises above ``foot_lift_limit``, a position state x[0] or x[1] leaves its bound by
more than ``bound_violation_limit``, or the lower body's absolute tilt |foot_pitch + q_a| exceeds
``lower_tilt_limit``.

Settled. Every joint angle within ``settle_angle_tol`` and every joint rate within
``settle_rate_tol``. A scenario that neither falls nor diverges is ``recovered`` when its last
sample (at t_end) is in the band, else ``not_settled``.

Fall cause. The rule that fired at the fall sample, in the order of :data:`FALL_CAUSES`
(foot pitch, heel lift, toe lift, state bound, lower-body tilt) when several fire at once;
``non_finite`` for a diverged run; empty for a run that neither fell nor diverged. The heel
cells are the back pair of ``model.mjcf.LOAD_CELLS``, the toe cells the front pair.

Outcome codes: ``OUTCOMES[code]``; diverged (a non-finite state, torque or solver output) takes
precedence over fell, which takes precedence over the settle band.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping, NamedTuple

import numpy as np
import pandas as pd

if TYPE_CHECKING:  # (annotations only)
    import jax

OUTCOMES = ("recovered", "not_settled", "fell", "diverged")
RECOVERED, NOT_SETTLED, FELL, DIVERGED = range(4)

# Why a run ended (column ``fall_cause``): FALL_CAUSES[code]; code 0 (empty) for a run that
# neither fell nor diverged. Codes 1..5 are the fall rules in the order they are tested.
FALL_CAUSES = ("", "foot_pitch", "heel_lift", "toe_lift", "state_bound", "lower_tilt", "non_finite")
NO_CAUSE, NON_FINITE = 0, 6
# Load cells in model.LOAD_CELLS order: front left, front right, back left, back right.
TOE_CELLS, HEEL_CELLS = slice(0, 2), slice(2, 4)

# An input counts as saturated within SATURATION_TOL of its range from a bound.
SATURATION_TOL = 1e-6

# One summary row per scenario, in this order, in every path (reference, batched, sweeps).
SUMMARY_COLUMNS = [
    "force",
    "duration",
    "convention",
    "outcome",
    "settle_time",
    "fall_time",
    "peak_ankle",
    "peak_hip",
    "peak_foot_pitch",
    "cop_min",
    "cop_max",
    "com_min",
    "com_max",
    "peak_tau_ankle",
    "peak_tau_hip",
    "ankle_saturation_fraction",
    "hip_saturation_fraction",
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "work_ankle",
    "work_hip",
    "energy_u1",
    "energy_u2",
    "work_u1",
    "work_u2",
    "study_energy_u1",
    "study_energy_u2",
    "study_energy_total",
    "nonconverged_solves",
    "max_residual",
    "max_bound_violation",
    "fall_cause",
    "first_infeasible_time",
    "com_vel_min",
    "com_vel_max",
    "mos_min",
    "mos_min_time",
    "steps_needed",
    "capture_margin",
    "decision_time",
]


class Limits(NamedTuple):
    """The thresholds of the rules (python floats: hashable, static under jit)."""

    foot_pitch_limit: float
    foot_lift_limit: float
    bound_violation_limit: float
    lower_tilt_limit: float
    settle_angle_tol: float
    settle_rate_tol: float
    # (the bounds: a traced array inside the batched kernel, None in its static copy there)
    state_lower: tuple[float, float] | jax.Array | None  # bounds of x[0], x[1]
    state_upper: tuple[float, float] | jax.Array | None
    input_lower: tuple[float, float] | jax.Array | None  # bounds of u[0], u[1]
    input_upper: tuple[float, float] | jax.Array | None

    @classmethod
    def from_params(cls, scenario: Any, controller: Any) -> "Limits":
        """From ``ScenarioParams`` (thresholds) and ``ControllerParams`` (bounds)."""
        (s1l, s1h), (s2l, s2h) = controller.state_bounds
        (u1l, u1h), (u2l, u2h) = controller.input_bounds
        return cls(
            foot_pitch_limit=scenario.foot_pitch_limit,
            foot_lift_limit=scenario.foot_lift_limit,
            bound_violation_limit=scenario.bound_violation_limit,
            lower_tilt_limit=scenario.lower_tilt_limit,
            settle_angle_tol=scenario.settle_angle_tol,
            settle_rate_tol=scenario.settle_rate_tol,
            state_lower=(s1l, s2l),
            state_upper=(s1h, s2h),
            input_lower=(u1l, u2l),
            input_upper=(u1h, u2h),
        )


def bound_excess(xp: Any, x: Any, limits: Limits) -> Any:
    """Largest excess of x[0], x[1] beyond their state bounds, >= 0. x: [..., 4] -> [...]."""
    lower = xp.asarray(limits.state_lower, dtype=x.dtype)
    upper = xp.asarray(limits.state_upper, dtype=x.dtype)
    pos = x[..., :2]
    return xp.max(xp.maximum(xp.maximum(lower - pos, pos - upper), 0), axis=-1)


def fall_rules(
    xp: Any, foot_pitch: Any, cell_low_z: Any, excess: Any, q_ankle: Any, limits: Limits
) -> list[Any]:
    """The five fall rules of a sample (or a series), in FALL_CAUSES order (codes 1..5):
    foot pitch, heel lift, toe lift, state bound, lower-body tilt. foot_pitch, excess, q_ankle:
    [...]; cell_low_z: [..., 4] -> five bool arrays [...]."""
    return [
        xp.abs(foot_pitch) > limits.foot_pitch_limit,
        xp.max(cell_low_z[..., HEEL_CELLS], axis=-1) > limits.foot_lift_limit,
        xp.max(cell_low_z[..., TOE_CELLS], axis=-1) > limits.foot_lift_limit,
        excess > limits.bound_violation_limit,
        xp.abs(foot_pitch + q_ankle) > limits.lower_tilt_limit,
    ]


def falls(
    xp: Any, foot_pitch: Any, cell_low_z: Any, excess: Any, q_ankle: Any, limits: Limits
) -> Any:
    """The fall test of a sample (or a series): any of :func:`fall_rules`. -> bool [...]."""
    rules = fall_rules(xp, foot_pitch, cell_low_z, excess, q_ankle, limits)
    out = rules[0]
    for rule in rules[1:]:
        out = out | rule
    return out


def fall_cause(
    xp: Any, foot_pitch: Any, cell_low_z: Any, excess: Any, q_ankle: Any, limits: Limits
) -> Any:
    """The first rule of :func:`fall_rules` that fires (code 1..5 into FALL_CAUSES), NO_CAUSE
    (0) where none does. -> int [...]."""
    rules = fall_rules(xp, foot_pitch, cell_low_z, excess, q_ankle, limits)
    code = xp.zeros(xp.shape(rules[0]), dtype=xp.int32)
    for c, rule in reversed(list(enumerate(rules, start=1))):
        code = xp.where(rule, c, code)
    return code


def stability_margins(
    xp: Any, com: Any, com_vel: Any, heel: Any, toe: Any, omega0: Any
) -> tuple[Any, Any, Any]:
    """The extrapolated centre of mass and the margins of stability (Hof et al. 2005, J Biomech
    38:1-8; docs/model.md): XcoM = com + com_vel / omega0, the toe margin toe - XcoM and the
    heel margin XcoM - heel (both positive while XcoM lies over the foot). com, com_vel, heel,
    toe: [...] (heel, toe: the back and front load cells' x) -> (xcom, mos_toe, mos_heel)."""
    xcom = com + com_vel / omega0
    return xcom, toe - xcom, xcom - heel


def support_edges(xp: Any, cell_x: Any) -> tuple[Any, Any]:
    """The base of support's edges (heel, toe): the smallest x of the back (heel) load-cell
    centres and the largest x of the front (toe) ones. cell_x: [..., 4] -> ([...], [...])."""
    return xp.min(cell_x[..., HEEL_CELLS], axis=-1), xp.max(cell_x[..., TOE_CELLS], axis=-1)


def in_settle_band(xp: Any, q: Any, dq: Any, limits: Limits) -> Any:
    """Joint angles and rates within the settle band. q, dq: [..., 2] -> bool [...]."""
    return xp.all(xp.abs(q) <= limits.settle_angle_tol, axis=-1) & xp.all(
        xp.abs(dq) <= limits.settle_rate_tol, axis=-1
    )


def at_input_bound(xp: Any, u: Any, limits: Limits) -> Any:
    """Each input within SATURATION_TOL of its range from a bound. u: [..., 2] -> bool [..., 2]."""
    lower = xp.asarray(limits.input_lower, dtype=u.dtype)
    upper = xp.asarray(limits.input_upper, dtype=u.dtype)
    tol = SATURATION_TOL * (upper - lower)
    return (u <= lower + tol) | (u >= upper - tol)


def classify(xp: Any, diverged: Any, fell: Any, settled: Any) -> Any:
    """Outcome codes (indices into OUTCOMES) from the three flags (arrays or scalars)."""
    return xp.where(
        diverged, DIVERGED, xp.where(fell, FELL, xp.where(settled, RECOVERED, NOT_SETTLED))
    )


def summary_frame(
    result: pd.DataFrame | Mapping[str, Any], convention: str, *, extra: bool = True
) -> pd.DataFrame:
    """Summary rows as a table: SUMMARY_COLUMNS in order (then any other columns of
    ``result`` when ``extra``), outcome as strings.

    ``result``: a DataFrame or a dict of equal-length columns, with outcome as strings or as
    integer codes; ``convention`` fills the column when ``result`` lacks it. Raises
    RuntimeError for a missing column or an unknown outcome.
    """
    frame = (
        result.copy()
        if isinstance(result, pd.DataFrame)
        else pd.DataFrame({k: np.asarray(v) for k, v in result.items()})
    )
    if "convention" not in frame:
        frame["convention"] = convention
    missing = [c for c in SUMMARY_COLUMNS if c not in frame]
    if missing:
        raise RuntimeError(f"summary lacks column(s) {', '.join(missing)}")
    if pd.api.types.is_numeric_dtype(frame["outcome"]):
        codes = frame["outcome"].to_numpy()
        if np.any((codes < 0) | (codes >= len(OUTCOMES))):
            raise RuntimeError(f"summary has outcome codes outside 0..{len(OUTCOMES) - 1}")
        frame["outcome"] = np.asarray(OUTCOMES, dtype=object)[codes.astype(int)]
    bad = set(frame["outcome"]) - set(OUTCOMES)
    if bad:
        raise RuntimeError(f"summary has unknown outcome(s) {sorted(bad)}")
    frame["outcome"] = frame["outcome"].astype(str)
    if pd.api.types.is_numeric_dtype(frame["fall_cause"]):
        codes = frame["fall_cause"].to_numpy()
        if np.any((codes < 0) | (codes >= len(FALL_CAUSES))):
            raise RuntimeError(f"summary has fall_cause codes outside 0..{len(FALL_CAUSES) - 1}")
        frame["fall_cause"] = np.asarray(FALL_CAUSES, dtype=object)[codes.astype(int)]
    frame["fall_cause"] = frame["fall_cause"].fillna("").astype(str)
    frame["convention"] = frame["convention"].astype(str)
    others = [c for c in frame.columns if c not in SUMMARY_COLUMNS] if extra else []
    return frame[SUMMARY_COLUMNS + others].reset_index(drop=True)


# -- a run that is not a result -----------------------------------------------------------------

# A run whose scenarios are half or more ``diverged`` (the controller's or the physics' numbers
# left the finite range: a NaN, an overflow, MuJoCo's bad-value reset) is not a map of
# recovery: a figure of it shows a region that does not exist. Such a run ends as a failure.
DIVERGED_LIMIT = 0.5


class NotAResult(RuntimeError):
    """Half or more of a run's scenarios diverged (:data:`DIVERGED_LIMIT`)."""


def diverged_share(outcomes) -> float:
    """The share of ``outcomes`` (names, or codes of :data:`OUTCOMES`) that diverged."""
    values = list(outcomes)
    if not values:
        return 0.0
    hits = sum(1 for v in values if v == "diverged" or (not isinstance(v, str) and v == DIVERGED))
    return hits / len(values)


def check_results(outcomes, what: str) -> None:
    """Raise :class:`NotAResult` (one line naming the likely causes) when
    :data:`DIVERGED_LIMIT` or more of ``outcomes`` diverged."""
    values = list(outcomes)
    share = diverged_share(values)
    if share >= DIVERGED_LIMIT:
        raise NotAResult(
            f"{share:.0%} of the {len(values)} {what} diverged (the numbers left the finite "
            "range), so these are not results; likely cause: the controller's settings for "
            "this body (horizon x control_dt, the ADMM's rho and tolerances, extreme weights "
            "or bounds) or the physics step (docs/reliability.md)"
        )
