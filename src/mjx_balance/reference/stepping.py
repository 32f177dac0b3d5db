"""A reduced model that takes the step: the check of the capture columns by simulation
(docs/beyond.md, "Stepping"; measures/capture.py is the closed form it checks).

From the full model's CoM state at a run's decision instant (the reference's recorded series),
the linear inverted pendulum (the same omega0, CoP reach, push and step as
``capture.step_model``) is simulated with a stepping controller instead of the closed form's
best strategy:

- stance: the CoP drives the capture point xi to a hold point xi* (a the stance ankle, f the
  push per unit mass, s = f / omega0^2 its CoP shift), p = xi + s + (xi - xi*) (gain 1),
  clipped to the reach; xi* is as near the reach's middle as keeps the holding CoP xi* + s
  ``MARGIN`` of the reach inside either edge, so that a push whose shift fits in the foot
  leaves xi held when it ends;
- the first step starts at the decision instant (the feet in place can no longer hold xi,
  by the instant's definition); a further step starts when, after a landing, the CoP that
  would hold xi (xi + f / omega0^2) lies outside the foot's reach, forwards or backwards (a
  reactive stepper: it does not know when the push will end, as the closed form does);
- a step lands ``step_time`` after it starts, the new ankle placed so that the capture point
  at the landing instant is the new foot's hold point, at most ``step_length`` away, forwards
  or backwards (an instantaneous support change);
- the body is captured when, after the push and the last landing, xi and v settle over the
  last foot (``SETTLED``) within ``AFTER`` seconds.

Between control instants the pendulum moves exactly (piecewise-constant p and f: x - c moves as
cosh / sinh of omega0 t, c = p - f / omega0^2), so the only differences from the closed form are
the controller's: its CoP is not held at the edge, and its later steps react instead of being
planned.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..measures.capture import MAX_STEPS, StepModel, facing
from ..model.params import push_steps

DT = 0.002  # s: the controller's period (the physics step of the full model)
MARGIN = 0.1  # the share of the CoP's reach the controller keeps to spare at each edge
AFTER = 3.0  # s: the time the pendulum has after the push and the last landing to settle
SETTLED = (0.01, 0.01)  # (m, m/s): |xi - ankle| and |v| of a captured pendulum


class SteppingRun(NamedTuple):
    """The reduced model's run: steps taken, captured or not, the last ankle [m]."""

    steps: int
    captured: bool
    ankle: float


def steps_to_capture(
    model: StepModel, x: float, v: float, force: float, remaining: float
) -> SteppingRun:
    """Simulate the stepping pendulum from CoM x [m, ahead of the stance ankle] and velocity v
    [m/s] at the decision instant, the push ``force`` [N] on for ``remaining`` [s] more (see
    the module docstring). A fall backwards is mirrored (the heel's reach, steps backwards)."""
    w = model.omega0
    direction, front, back = (
        float(e) for e in facing(np, x + v / w, model.cop_back, model.cop_front)
    )
    middle, margin = 0.5 * (front + back), MARGIN * (front - back)

    def hold_point(shift: float) -> float:
        """Where xi is held (ahead of the ankle) under a push whose CoP shift is ``shift``: the
        CoP xi + shift within the reach with ``margin`` to spare, xi as near the reach's middle
        as that allows (so that it is held when the push ends, if the shift fits)."""
        return min(max(middle, back - shift + margin), front - shift - margin)

    x, v, f = direction * x, direction * v, direction * model.push_gain * force
    ankle, steps, t = 0.0, 0, 0.0
    swing_end: float | None = model.step_time  # the first step starts now (module docstring)
    quiet_from: float | None = None
    end = max(remaining, 0.0) + MAX_STEPS * model.step_time + AFTER
    while t < end:
        push = f if t < remaining else 0.0
        if swing_end is not None and t >= swing_end - 1e-12:  # landing
            # the new foot where the capture point is its hold point (below)
            xi = x + v / w
            need = xi - hold_point(push / w**2)
            ankle = min(ankle + model.step_length, max(ankle - model.step_length, need))
            steps, swing_end = steps + 1, None
        xi = x + v / w
        held = xi + push / w**2  # the CoP that holds xi
        if swing_end is None and not ankle + back <= held <= ankle + front and steps < MAX_STEPS:
            swing_end = t + model.step_time  # no CoP of this foot holds xi: step again
        target = ankle + hold_point(push / w**2)
        p = min(max(xi + (xi - target) + push / w**2, ankle + back), ankle + front)
        c = p - push / w**2
        y = x - c
        ch, sh = math.cosh(w * DT), math.sinh(w * DT)
        x, v = c + y * ch + v / w * sh, y * w * sh + v * ch
        t += DT
        calm = abs(x + v / w - ankle - middle) <= SETTLED[0] and abs(v) <= SETTLED[1]
        if calm and t >= remaining and swing_end is None:
            quiet_from = t if quiet_from is None else quiet_from
            if t - quiet_from >= 0.5:
                return SteppingRun(steps, True, direction * ankle)
        else:
            quiet_from = None
        if abs(x - ankle) > 2 * model.step_length + 1.0:  # long gone: a fall
            break
    return SteppingRun(steps, False, direction * ankle)


def simulated_steps(model: StepModel, frame, force: float, duration: float, at: float) -> float:
    """The reduced model's answer for a reference run (its time series ``frame``, with ``com``
    and ``com_vel``) decided at ``at`` [s]: the steps it took when captured, inf otherwise."""
    time = frame["time"].to_numpy()
    i = int(np.argmin(np.abs(time - at)))
    remaining = push_steps(duration, model.physics_dt) * model.physics_dt - time[i]
    run = steps_to_capture(
        model, float(frame["com"].iloc[i]), float(frame["com_vel"].iloc[i]), force, remaining
    )
    return float(run.steps) if run.captured else math.inf
