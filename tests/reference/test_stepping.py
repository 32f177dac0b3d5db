"""The stepping pendulum (reference/stepping.py) against the closed form (measures/capture.py)
away from the boundaries: where the push is over or its CoP shift fits in the foot, a reactive
stepper needs the steps the closed form says, and cannot do with fewer."""

from __future__ import annotations

import numpy as np
import pytest

from mjx_balance.measures import capture
from mjx_balance.model.params import Config
from mjx_balance.reference.stepping import steps_to_capture

MODEL = capture.step_model(Config())
# 2 cm from a boundary: the reactive controller's CoP is not held at the edge while it steers,
# which costs it some capture point (measured by bisection on these pushes: its one- and two-step
# boundaries lie 0.07-0.38 mm inside the closed form's, and 15.5 mm for one step under the
# 40-N backward push still on for 0.5 s)
CLEAR = 0.02


def closed_form(xi: float, force: float, remaining: float) -> float:
    for n in (1, 2):
        if capture.margins(MODEL, xi, force, remaining, n)[0] >= 0:
            return float(n)
    return np.inf


def clear_of_boundaries(xi: float, force: float, remaining: float) -> bool:
    return all(
        abs(float(capture.margins(MODEL, xi, force, remaining, n)[0])) > CLEAR for n in (1, 2)
    )


@pytest.mark.parametrize("force, remaining", [(0.0, 0.0), (40.0, 0.3), (-40.0, 0.5)])
def test_a_reactive_stepper_needs_the_steps_of_the_closed_form(force, remaining):
    """From rest at capture points across the one- and two-step regions (and beyond), the
    pushed forwards or backwards: the same answer wherever the state is clear of a boundary;
    40 N shifts the CoP by 0.08 m, within the study's 0.3-m reach."""
    sign = -1.0 if force < 0 else 1.0
    seen = set()
    for xi in sign * np.linspace(0.16, 1.6, 37):
        if not clear_of_boundaries(xi, force, remaining):
            continue
        run = steps_to_capture(MODEL, xi, 0.0, force, remaining)
        expected = closed_form(xi, force, remaining)
        simulated = float(run.steps) if run.captured else np.inf
        assert simulated == expected, (xi, run)
        seen.add(expected)
    assert seen == {1.0, 2.0, np.inf}  # every region was tried
