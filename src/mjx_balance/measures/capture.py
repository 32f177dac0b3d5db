"""Would a step have saved it? Capturability of a run that fell with its feet in place
(docs/model.md, "Stepping: capturability").

The feet-in-place run is simulated (MuJoCo, the MPC); the step is not. At the *decision
instant*, the first sample at which the feet in place can no longer hold the capture point
(:func:`hold_margin` < 0, the push's remaining part counted; else the fall sample of
``outcomes.falls``: the foot pitches, a heel or toe lifts, a state leaves its bound), the body is
reduced to the linear inverted pendulum (LIPM) at its CoM height above the ankle, whose
divergent component is the instantaneous capture point xi = x + v / omega0 (the extrapolated
CoM of the margin of stability, ``outcomes.stability_margins``). Its dynamics under a centre of
pressure p and a horizontal push F (per unit mass f, its moment about the ankle written as a
force at the CoM) are

    dxi/dt = omega0 (xi - p) + f / omega0 = omega0 (xi - (p - f / omega0^2)),

so over an interval where p and f are constant, xi - c grows as exp(omega0 t), c = p - f /
omega0^2. The body is N-step capturable (Koolen et al. 2012, Int J Robot Res 31(9),
doi:10.1177/0278364912452673) when some CoP path inside the stance foot and N steps, each
landing ``step_time`` after the previous one at most ``step_length`` ahead, bring xi to rest
over a foot once the push is over. Because xi's growth only slows as p moves ahead, the best
path holds p at the front edge of the foot it stands on and steps as far as allowed; the state
is N-step capturable iff then, at the later of the last landing and the push's end, xi lies
behind the front edge of the last foot. xi there is exp(omega0 T) xi0 + C (affine in the
decision instant's xi0), so the N-step *margin* is the distance from xi0 to the largest xi0 that
passes: positive inside the N-step capture region. Without a push this is the finite-foot LIPM's
recursion d_N = (d_{N-1} - r + l) exp(-omega0 dt_s) + r, d_0 = r (tests/measures/test_capture.py
checks it).

The CoP's reach r ahead of (behind) the ankle is the least of the sole's edge, the MPC's CoP
bound and what the ankle's torque bound can hold, tau / (M g) (docs/model.md, "Linear
model"): a weak ankle cannot bring the CoP to the toe, after a step as before it.

Everything here is host-side numpy over arrays of scenarios, float64; the batched paths and the
scalar reference record the decision instant's xi (the kernel's accumulator ``decision_xcom``,
the reference's XcoM series) and call :func:`columns`.
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np

from ..model.linear import linear_model
from ..model.params import push_steps
from .outcomes import DIVERGED, FELL

# The most steps :func:`columns` tries; a run that two steps do not capture gets inf.
MAX_STEPS = 2
# Step-count columns: 0 (no fall), 1, 2, or inf (not within MAX_STEPS); NaN: diverged.
STEP_COLUMNS = ("steps_needed", "capture_margin", "decision_time")


class StepModel(NamedTuple):
    """The LIPM of one configuration (SI units; positions ahead of the stance ankle)."""

    omega0: float  # 1/s, sqrt(g / CoM height above the ankle), as the margin of stability's
    cop_back: float  # m (< 0): the CoP's reach behind the ankle
    cop_front: float  # m (> 0): its reach ahead of the ankle
    step_length: float  # m: the longest step, ankle to ankle
    step_time: float  # s: from the decision instant (or a landing) to the next landing
    push_gain: float  # 1/kg: f = push_gain F (the push's moment about the ankle, at the CoM)
    physics_dt: float  # s: the push lasts ceil(T / dt - 1e-9) physics steps, as simulated

    def data(self) -> tuple[float, float, float, float, float]:
        """(cop_back, cop_front, push_gain, omega0, physics_dt): what :func:`hold_margin`
        reads, as the batched kernel carries it (``kernel.Arrays.capture``)."""
        return self.cop_back, self.cop_front, self.push_gain, self.omega0, self.physics_dt


def com_height(body: Any) -> float:
    """The whole-body CoM's height above the ankle axis at upright rest [m]: the foot's CoM
    half its thickness above the sole, the segments' along the vertical body (model/mjcf.py);
    what ``rollout.sensing.pendulum_frequency`` measures on the model."""
    foot = body.foot_mass * (body.foot_thickness / 2 - body.ankle_height)
    lower = body.lower_mass * body.lower_com
    upper = body.upper_mass * (body.lower_length + body.upper_com)
    return (foot + lower + upper) / body.total_mass


@functools.lru_cache(maxsize=256)
def step_model(config: Any) -> StepModel:
    """The :class:`StepModel` of a configuration (cached: configurations are frozen)."""
    body, ctrl, sc = config.body, config.controller, config.scenario
    z0 = com_height(body)
    weight = body.total_mass * body.gravity
    tm = linear_model(body, ctrl.convention, sc.control_dt).torque_map[0]
    (a1, b1), (a2, b2) = ctrl.input1_bounds, ctrl.input2_bounds
    if body.hip_servo_stiffness > 0:  # the servo holds the hip; the motors give the ankle's
        a2 = b2 = 0.0  # torque alone (studies/lean.py)
    corners = [tm[0] * u1 + tm[1] * u2 for u1 in (a1, b1) for u2 in (a2, b2)]
    heel, toe = body.sole_edges
    # cop = -tau_ankle / (M g): a forward CoP asks a negative (plantarflexing) ankle torque
    front = min(toe, ctrl.cop_bounds[1], -min(corners) / weight)
    back = max(heel, ctrl.cop_bounds[0], -max(corners) / weight)
    push_height = body.ankle_height + body.lower_length
    if sc.push_body == "upper":
        push_height += body.upper_com
    return StepModel(
        omega0=math.sqrt(body.gravity / z0),
        cop_back=float(back),
        cop_front=float(front),
        step_length=float(body.step_length * body.height),
        step_time=float(body.step_time),
        push_gain=push_height / (z0 * body.total_mass),
        physics_dt=sc.physics_dt,
    )


def facing(xp: Any, xcom: Any, back: Any, front: Any) -> tuple[Any, Any, Any]:
    """(direction, front edge, back edge) of a fall, mirrored so that it runs forwards: +1
    where the capture point ``xcom`` lies ahead of the middle of the CoP's reach [``back``,
    ``front``] (a forward fall: steps forward, the front edge ahead), -1 behind (a backward
    fall: the heel's reach as the front edge, steps backward). numpy or jax.numpy (``xp``)."""
    ahead = xcom >= 0.5 * (back + front)
    return xp.where(ahead, 1.0, -1.0), xp.where(ahead, front, -back), xp.where(ahead, back, -front)


def saved(recovered: Any, steps_needed: Any, within: int | None) -> np.ndarray:
    """Which runs count as recovered: in place (``recovered``, bool), or, with ``within`` not
    None, with at most that many steps (``steps_needed``; a run that did not fall needs none).
    The one rule of the one-step boundaries, tables, lean limits and probability maps;
    ``steps_needed`` is not read (may be None) when ``within`` is None."""
    ok = np.asarray(recovered, bool)
    if within is None:
        return ok
    if steps_needed is None:
        raise KeyError("steps_needed: the runs lack the capture columns")
    return ok | (np.asarray(steps_needed, np.float64) <= within)


def hold_margin(xp: Any, xcom: Any, force: Any, remaining: Any, data: Any) -> Any:
    """The 0-step capture margin [m] (:func:`margins` with no step, written once for numpy
    and jax.numpy): how far the capture point ``xcom`` lies inside what the stance foot can
    still hold with the push ``force`` on for ``remaining`` [s] more, edge - shift (1 -
    exp(-omega0 remaining)) - xi in the fall's direction. Negative: the feet in place cannot
    hold it; the first such sample is the decision instant. ``data``: StepModel.data()."""
    gain, w = data[2], data[3]
    direction, edge, _ = facing(xp, xcom, data[0], data[1])
    shift = direction * gain * force / w**2
    return edge - shift * (1 - xp.exp(-w * xp.maximum(remaining, 0 * remaining))) - direction * xcom


def margins(
    model: StepModel, xcom: Any, force: Any, remaining: Any, steps: int
) -> tuple[np.ndarray, np.ndarray]:
    """(margin [m], direction) of capture with ``steps`` steps from the decision instant's
    capture point ``xcom`` [m, ahead of the ankle], the push ``force`` [N] still on for
    ``remaining`` [s]: margin >= 0 inside the capture region; direction +1 where xi lies ahead
    of the middle of the CoP's reach (a forward fall: steps forward, the front edges), -1
    behind (mirrored). Arrays broadcast; NaN xcom gives NaN."""
    xcom = np.asarray(xcom, np.float64)
    force, remaining = np.broadcast_arrays(
        np.asarray(force, np.float64), np.maximum(np.asarray(remaining, np.float64), 0.0)
    )
    xcom, force, remaining = np.broadcast_arrays(xcom, force, remaining)
    w, dt, length = model.omega0, model.step_time, model.step_length
    direction, reach, _ = facing(np, xcom, model.cop_back, model.cop_front)
    shift = direction * model.push_gain * force / w**2  # the push as a CoP offset, m
    landings = dt * np.arange(1, steps + 1)
    cuts = np.sort(
        np.concatenate(
            [
                np.zeros(xcom.shape + (1,)),
                np.broadcast_to(landings, xcom.shape + (steps,)),
                remaining[..., None],
            ],
            axis=-1,
        ),
        axis=-1,
    )
    end = np.maximum(steps * dt, remaining)
    cuts = np.minimum(cuts, end[..., None])
    offset = np.zeros(xcom.shape)  # xi at ``end`` from xi0 = 0 (the affine map's constant)
    for j in range(cuts.shape[-1] - 1):
        a, b = cuts[..., j], cuts[..., j + 1]
        foot = np.minimum(np.floor(a / dt + 1e-9), steps) if steps else np.zeros(a.shape)
        centre = foot * length + reach - np.where(a < remaining, shift, 0.0)
        offset = centre + (offset - centre) * np.exp(w * (b - a))
    limit = (steps * length + reach - offset) * np.exp(-w * end)
    return limit - direction * xcom, direction


def columns(
    model: StepModel, outcome: Any, decision_time: Any, xcom: Any, force: Any, duration: Any
) -> dict[str, np.ndarray]:
    """The capture columns of each run (arrays over runs): ``steps_needed`` 0 for a run that
    did not fall (recovered, or standing unsettled at t_end); for a fall, the fewest steps (1
    or 2) whose capture margin at the decision instant (``decision_time``, ``xcom`` its capture
    point) is >= 0, inf where two do not capture; NaN for a diverged run. ``capture_margin``:
    the one-step margin [m] of a fall; ``decision_time`` [s] of a fall (NaN otherwise).
    ``force``, ``duration``: the push (its part after the decision instant acts on the
    pendulum)."""
    outcome = np.asarray(outcome)
    fell = outcome == FELL
    at = np.where(fell, np.asarray(decision_time, np.float64), 0.0)
    remaining = push_steps(duration, model.physics_dt) * model.physics_dt - at
    xi = np.where(fell, np.asarray(xcom, np.float64), 0.0)
    needed = np.where(fell, math.inf, 0.0)
    one = np.full(outcome.shape, math.nan)
    for n in range(MAX_STEPS, 0, -1):
        margin, _ = margins(model, xi, force, remaining, n)
        needed = np.where(fell & (margin >= 0), float(n), needed)
        if n == 1:
            one = np.where(fell, margin, math.nan)
    needed = np.where((fell & ~np.isfinite(xi)) | (outcome == DIVERGED), math.nan, needed)
    return {
        "steps_needed": needed,
        "capture_margin": one,
        "decision_time": np.where(fell, at, math.nan),
    }


def decision_index(xcom: np.ndarray, force: float, duration: float, model: StepModel, end: int):
    """The decision sample of a series that fell at sample ``end - 1`` (the scalar reference):
    the first sample whose :func:`hold_margin` is negative, else the fall sample. ``xcom`` [n]:
    the capture point after each physics step i (t = (i + 1) dt)."""
    i = np.arange(end)
    remaining = (push_steps(duration, model.physics_dt) - i - 1) * model.physics_dt
    lost = hold_margin(np, np.asarray(xcom, np.float64)[:end], force, remaining, model.data()) < 0
    return int(np.flatnonzero(lost)[0]) if lost.any() else end - 1
