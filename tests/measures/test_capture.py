"""Capturability (measures/capture.py): the N-step margins against the finite-foot recursion and
against an independent integration of the pendulum, the 0-step margin written once for both
array libraries, the step model of a configuration, and the columns of a run."""

from __future__ import annotations

import math

import numpy as np
import pytest
from margins import within

from mjx_balance.measures import capture
from mjx_balance.measures.outcomes import DIVERGED, FELL, NOT_SETTLED, RECOVERED
from mjx_balance.model.params import BodyParams, Config, ParameterError

MODEL = capture.StepModel(
    omega0=3.3,
    cop_back=-0.08,
    cop_front=0.14,
    step_length=0.7,
    step_time=0.35,
    push_gain=0.02,
    physics_dt=0.002,
)


def koolen(model: capture.StepModel, n: int) -> float:
    """d_N of the LIPM with a finite foot (Koolen et al. 2012, Int J Robot Res 31(9)): d_0 = r,
    d_N = (d_{N-1} - r + l) exp(-omega0 dt_s) + r (forward, r the front reach)."""
    r, d = model.cop_front, model.cop_front
    for _ in range(n):
        d = (d - r + model.step_length) * math.exp(-model.omega0 * model.step_time) + r
    return d


@pytest.mark.parametrize("n", [0, 1, 2])
def test_margins_without_a_push_are_koolens_recursion(n):
    xi = np.array([0.05, 0.1, 0.3, 0.6])  # ahead of the reach's middle, 0.03 m: forward
    margin, direction = capture.margins(MODEL, xi, 0.0, 0.0, n)
    assert (direction == 1).all()
    within(margin, koolen(MODEL, n) - xi, atol=1e-12, why="the same closed form, float64")


def simulated(model, xi0, force, remaining, n, dt=1e-5):
    """xi at the later of the last landing and the push's end, integrated by explicit Euler
    with the CoP at the front edge of the foot stood on and steps of step_length every
    step_time (the strategy the closed form assumes), and the last foot's front edge."""
    f = model.push_gain * force
    end = max(n * model.step_time, remaining)
    xi, t = xi0, 0.0
    while t < end - dt / 2:
        feet = min(int((t + 1e-12) / model.step_time), n)
        p = feet * model.step_length + model.cop_front
        push = f if t < remaining else 0.0
        xi += dt * (model.omega0 * (xi - p) + push / model.omega0)
        t += dt
    return xi, n * model.step_length + model.cop_front


@pytest.mark.parametrize(
    "n, force, remaining", [(0, 60.0, 0.4), (1, 60.0, 0.2), (1, 40.0, 1.0), (2, 80.0, 0.5)]
)
def test_margins_with_a_push_match_an_integrated_pendulum(n, force, remaining):
    """At the margin's boundary xi0* = xi0 + margin the integrated capture point ends on the
    last foot's front edge; 1 cm inside it ends behind, 1 cm outside ahead."""
    xi0 = 0.05
    margin, _ = capture.margins(MODEL, xi0, force, remaining, n)
    boundary = xi0 + float(margin)
    end, edge = simulated(MODEL, boundary, force, remaining, n)
    # Euler's error in xi over ~1 s at omega0 3.3 with dt 1e-5: ~omega0^2 t dt |xi| e^(omega0 t)
    within(end, edge, atol=5e-3, why="explicit Euler at dt = 1e-5 s over <= 1 s (comment)")
    assert simulated(MODEL, boundary - 0.01, force, remaining, n)[0] < edge
    assert simulated(MODEL, boundary + 0.01, force, remaining, n)[0] > edge


def test_hold_margin_is_the_zero_step_margin_in_both_directions():
    rng = np.random.default_rng(0)
    xi = rng.uniform(-0.4, 0.4, 200)
    force = rng.uniform(-120, 120, 200)
    remaining = rng.uniform(-0.2, 1.5, 200)  # negative: the push is over
    zero, _ = capture.margins(MODEL, xi, force, remaining, 0)
    within(
        capture.hold_margin(np, xi, force, remaining, MODEL.data()),
        zero,
        atol=1e-12,
        why="two forms of one closed form, float64",
    )


def test_a_backward_fall_is_the_forward_one_mirrored():
    symmetric = MODEL._replace(cop_back=-MODEL.cop_front)
    for n in (0, 1, 2):
        ahead, d1 = capture.margins(symmetric, 0.2, 50.0, 0.3, n)
        behind, d2 = capture.margins(symmetric, -0.2, -50.0, 0.3, n)
        assert d1 == 1 and d2 == -1
        within(ahead, behind, atol=1e-12, why="mirror images, float64")


def test_more_steps_capture_more():
    xi = np.linspace(0.05, 1.0, 11)
    m = [capture.margins(MODEL, xi, 30.0, 0.5, n)[0] for n in (0, 1, 2)]
    assert (m[0] < m[1]).all() and (m[1] < m[2]).all()


def test_columns_of_each_outcome():
    outcome = np.array([RECOVERED, NOT_SETTLED, FELL, FELL, FELL, DIVERGED])
    # three falls from the decision instant: just held by one step, by two, by none
    d1, d2 = koolen(MODEL, 1), koolen(MODEL, 2)
    xi = np.array([np.nan, np.nan, d1 - 1e-3, d2 - 1e-3, d2 + 1e-3, np.nan])
    when = np.array([np.nan, np.nan, 0.5, 0.5, 0.5, np.nan])
    cols = capture.columns(MODEL, outcome, when, xi, np.zeros(6), np.full(6, 0.1))
    np.testing.assert_array_equal(cols["steps_needed"], [0, 0, 1, 2, math.inf, math.nan])
    within(cols["capture_margin"][2:5], d1 - xi[2:5], atol=1e-12, why="float64")
    assert np.isnan(cols["capture_margin"][[0, 1, 5]]).all()
    np.testing.assert_array_equal(cols["decision_time"], [np.nan, np.nan, 0.5, 0.5, 0.5, np.nan])


def test_the_push_still_on_after_the_decision_counts():
    """The same capture point needs more steps while the push goes on: a 60-N push with 0.3 s
    left moves the one-step boundary back by its shift's growth over the swing."""
    d1 = koolen(MODEL, 1)
    cols = capture.columns(
        MODEL,
        np.array([FELL, FELL]),
        np.array([0.2, 0.2]),
        np.array([d1 - 0.01, d1 - 0.01]),
        np.array([60.0, 60.0]),
        np.array([0.2, 0.5]),  # over at the decision instant / 0.3 s still on
    )
    np.testing.assert_array_equal(cols["steps_needed"], [1, 2])


def test_step_model_of_the_study_body_and_the_joint_convention():
    """The study's paper convention lets the ankle reach +-120 N m (tau1 + tau2): the sole's
    +-0.15 m bind; the joint convention's +-20 N m ankle holds the CoP within 20 / (M g)."""
    paper = capture.step_model(Config())
    assert (paper.cop_back, paper.cop_front) == (-0.15, 0.15)
    joint = capture.step_model(Config().replace(controller={"convention": "joint"}))
    weight = BodyParams().total_mass * BodyParams().gravity
    within(joint.cop_front, 20.0 / weight, atol=1e-15, why="float64")
    within(joint.cop_back, -20.0 / weight, atol=1e-15, why="float64")
    body = BodyParams()
    assert paper.step_length == body.step_length * (body.lower_length + body.upper_length)
    assert paper.step_time == body.step_time


def test_omega0_is_the_models_pendulum_frequency():
    """The margin of stability's omega0 (metrics.pendulum_frequency, read on the MuJoCo model)
    and the step model's (from the body's numbers) are one quantity."""
    from mjx_balance.measures import metrics
    from mjx_balance.model import mjcf

    for changes in ({}, {"ankle_height": 0.05, "foot_thickness": 0.04}):
        config = Config().replace(body=changes)
        model = mjcf.build_model(config.body)
        ix = mjcf.indices(model)
        within(
            capture.step_model(config).omega0,
            metrics.pendulum_frequency(model, ix.foot_body, ix.ankle_dof),
            rtol=1e-8,
            why="the MJCF writes the body's numbers to 9 significant digits",
        )


@pytest.mark.parametrize("name, value", [("step_length", -0.1), ("step_time", 0.0)])
def test_step_parameters_out_of_range_are_refused(name, value):
    with pytest.raises(ParameterError, match=f"body.{name}"):
        BodyParams(**{name: value})


def test_the_default_step_is_left_out_of_files():
    """A configuration at the default step reads as before the step existed (its manifest and
    its folders unchanged)."""
    assert "step_length" not in Config().to_dict()["body"]
    assert Config().replace(body={"step_time": 0.5}).to_dict()["body"]["step_time"] == 0.5
