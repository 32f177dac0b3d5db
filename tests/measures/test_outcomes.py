"""The outcome rules of outcomes.py, one function per rule, without compiling a closed loop.

The scalar reference calls each rule with ``xp = numpy`` on float64 series and the batched
kernel with ``xp = jax.numpy`` on float32 samples inside jit (with ``jax_enable_x64`` off, as
sweeps run). So every rule is fed the same hand-made samples in each of those namespaces and
dtypes and must give the answer written next to the sample, which is also the same answer
everywhere. The samples sit on both sides of every threshold, by margins far above float32
rounding at their scale (~1e-9 at 0.05, ~2e-6 at 20), so a rule that moved its threshold or
compared the wrong quantity gives another answer.

Edges. A fall needs a value strictly beyond its limit and the settle band includes its edges,
so a sample exactly at a limit is compared too where the rule compares the sample itself (the
limit, a python float, is weakly typed in both numpy >= 2 and JAX, so the comparison happens in
the sample's dtype). Derived quantities (bound excess, foot pitch + ankle angle) are not probed
at their exact edge: float32 and float64 round 0.55 - 0.5 to opposite sides of 0.05.
"""

from __future__ import annotations

import contextlib
import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from margins import within

from mjx_balance.measures import outcomes
from mjx_balance.measures.outcomes import (
    DIVERGED,
    FELL,
    NOT_SETTLED,
    OUTCOMES,
    RECOVERED,
    SATURATION_TOL,
    SUMMARY_COLUMNS,
    Limits,
)
from mjx_balance.model.params import ControllerParams, ScenarioParams

LIMITS = Limits.from_params(ScenarioParams(), ControllerParams())


class Namespace:
    """One way of calling a rule: the array namespace, the dtype of the samples, and for JAX
    whether x64 is on (the test session) or off (as sweeps run) and the call is jitted."""

    def __init__(self, name: str, xp, dtype, x64: bool = True, jit: bool = False):
        self.name, self.xp, self.dtype, self.x64, self.jit = name, xp, dtype, x64, jit

    def __repr__(self) -> str:
        return self.name

    def call(self, rule, *arrays, **static):
        """rule(xp, *arrays, **static) on the arrays cast to this dtype, as numpy."""
        context = contextlib.nullcontext() if self.x64 else jax.enable_x64(False)
        with context:
            args = [
                self.xp.asarray(np.asarray(a, self.dtype))
                if np.asarray(a).dtype != bool
                else self.xp.asarray(a)
                for a in arrays
            ]
            for a in args:
                if a.dtype != bool:
                    assert a.dtype == self.dtype  # no silent promotion of the samples

            def fn(*a):
                return rule(self.xp, *a, **static)

            if self.jit:
                fn = jax.jit(fn)
            return np.asarray(fn(*args))


NAMESPACES = [
    Namespace("numpy-float64", np, np.float64),
    Namespace("numpy-float32", np, np.float32),
    Namespace("jax-float64", jnp, np.float64),
    Namespace("jax-float32", jnp, np.float32),
    Namespace("jax-float32-x64off-jit", jnp, np.float32, x64=False, jit=True),
]


@pytest.fixture(params=NAMESPACES, ids=repr)
def ns(request) -> Namespace:
    return request.param


def test_limits_from_params_maps_every_field():
    scenario = ScenarioParams(
        foot_pitch_limit=0.06,
        foot_lift_limit=0.004,
        bound_violation_limit=0.07,
        lower_tilt_limit=0.45,
        settle_angle_tol=0.02,
        settle_rate_tol=0.03,
    )
    controller = ControllerParams(
        state1_bounds=(-0.2, 0.4),
        state2_bounds=(-0.3, 1.2),
        input1_bounds=(-15.0, 25.0),
        input2_bounds=(-90.0, 80.0),
    )
    assert Limits.from_params(scenario, controller) == Limits(
        foot_pitch_limit=0.06,
        foot_lift_limit=0.004,
        bound_violation_limit=0.07,
        lower_tilt_limit=0.45,
        settle_angle_tol=0.02,
        settle_rate_tol=0.03,
        state_lower=(-0.2, -0.3),
        state_upper=(0.4, 1.2),
        input_lower=(-15.0, -90.0),
        input_upper=(25.0, 80.0),
    )
    hash(LIMITS)  # static under jit


# --- bound excess ----------------------------------------------------------------------------

# x = (x1, x2, dx1, dx2); default bounds x1 in [-0.26, 0.5], x2 in [-0.35, 1.4]
EXCESS_SAMPLES = [
    ([0.0, 0.0, 0.0, 0.0], 0.0),
    ([0.49, 1.39, 50.0, -50.0], 0.0),  # inside; rates are not bounded
    ([0.6, 0.0, 0.0, 0.0], 0.1),  # x1 above its upper bound
    ([-0.36, 0.0, 0.0, 0.0], 0.1),  # x1 below its lower bound
    ([0.0, 1.45, 0.0, 0.0], 0.05),  # x2 above
    ([0.0, -0.55, 0.0, 0.0], 0.2),  # x2 below
    ([0.53, -0.42, 0.0, 0.0], 0.07),  # both: the larger excess
]


def test_bound_excess(ns):
    x = np.array([s for s, _ in EXCESS_SAMPLES])
    expected = np.array([e for _, e in EXCESS_SAMPLES])
    got = ns.call(outcomes.bound_excess, x, limits=LIMITS)
    assert got.shape == (len(EXCESS_SAMPLES),) and got.dtype == ns.dtype
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)
    one = ns.call(outcomes.bound_excess, x[6], limits=LIMITS)  # one sample: [4] -> []
    assert one.shape == ()
    within(
        float(one),
        0.07,
        atol=1e-6,
        why="a difference of ~0.5-rad numbers, rounded in float32 at most (6e-8)",
    )


# --- the fall test ---------------------------------------------------------------------------

UP = dict(foot_pitch=0.0, cell_low_z=[-3e-4] * 4, excess=0.0, q_ankle=0.0)  # resting, sunk


def fall_sample(**changes):
    return {**UP, **changes}


# (sample, falls): each cause alone on both sides of its limit (defaults: foot pitch 0.05 rad,
# lift 5 mm, bound excess 0.05 rad, lower-body tilt |foot pitch + q_ankle| 0.5 rad)
FALL_SAMPLES = [
    (fall_sample(), False),
    (fall_sample(foot_pitch=0.0501), True),
    (fall_sample(foot_pitch=0.0499), False),
    (fall_sample(foot_pitch=-0.0501), True),
    (fall_sample(foot_pitch=-0.0499), False),
    (fall_sample(foot_pitch=0.05), False),  # strictly beyond
    (fall_sample(cell_low_z=[-3e-4, -3e-4, 0.0051, -3e-4]), True),  # one corner lifts
    (fall_sample(cell_low_z=[0.0049, 0.0049, 0.0049, 0.0049]), False),
    (fall_sample(cell_low_z=[-3e-4, 0.005, -3e-4, -3e-4]), False),  # strictly above
    (fall_sample(cell_low_z=[-0.02, -0.02, -0.02, -0.02]), False),  # sinking is no fall
    (fall_sample(excess=0.0501), True),
    (fall_sample(excess=0.0499), False),
    (fall_sample(q_ankle=0.5001), True),
    (fall_sample(q_ankle=0.4999), False),
    (fall_sample(q_ankle=-0.5001), True),
    (fall_sample(q_ankle=-0.4999), False),
    # the lower body's absolute tilt, not the joint angle: a pitched foot adds to it ...
    (fall_sample(foot_pitch=0.04, q_ankle=0.4601), True),
    (fall_sample(foot_pitch=0.04, q_ankle=0.4599), False),
    # ... or takes from it (q_ankle alone beyond 0.5, the tilt 0.48)
    (fall_sample(foot_pitch=-0.04, q_ankle=0.52), False),
]


def _fall_arrays(samples):
    keys = ("foot_pitch", "cell_low_z", "excess", "q_ankle")
    return [np.array([s[k] for s, _ in samples]) for k in keys]


def test_falls_each_cause_alone(ns):
    got = ns.call(outcomes.falls, *_fall_arrays(FALL_SAMPLES), limits=LIMITS)
    expected = np.array([f for _, f in FALL_SAMPLES])
    assert got.dtype == bool and got.shape == expected.shape
    np.testing.assert_array_equal(got, expected)


def test_falls_on_one_sample(ns):
    """Shape [] in, [] out (the kernel calls it per sample)."""
    arrays = _fall_arrays(FALL_SAMPLES)
    for i in (0, 1, 6, 16, 18):
        one = ns.call(outcomes.falls, *(a[i] for a in arrays), limits=LIMITS)
        assert one.shape == () and bool(one) == FALL_SAMPLES[i][1], FALL_SAMPLES[i]


def test_falls_follows_the_limits():
    """Other limits move the thresholds (not constants in the rule)."""
    strict = LIMITS._replace(
        foot_pitch_limit=0.01,
        foot_lift_limit=0.001,
        bound_violation_limit=0.01,
        lower_tilt_limit=0.2,
    )
    got = outcomes.falls(
        np,
        np.array([0.02, 0.0, 0.0, 0.0]),
        np.array([[0.0] * 4, [0.002, 0, 0, 0], [0.0] * 4, [0.0] * 4]),
        np.array([0.0, 0.0, 0.02, 0.0]),
        np.array([0.0, 0.0, 0.0, 0.25]),
        strict,
    )
    np.testing.assert_array_equal(got, [True, True, True, True])


@pytest.mark.parametrize("xp", [np, jnp], ids=["numpy", "jax"])
def test_fall_cause_names_the_first_rule_in_order(xp):
    """One sample per rule (foot pitch, heel lift, toe lift, state bound, lower tilt), one
    where none fires, and one where every rule fires (the first in FALL_CAUSES order wins)."""
    lift = LIMITS.foot_lift_limit * 2
    pitch = np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5])
    cells = np.zeros((7, 4))
    cells[1, 2:] = lift  # back (heel) cells up
    cells[2, :2] = lift  # front (toe) cells up
    cells[6] = lift
    excess = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
    ankle = np.array([-0.5, 0.0, 0.0, 0.0, 3.0, 0.0, 3.0])  # pitch + ankle = 0 in row 0
    got = np.asarray(
        outcomes.fall_cause(xp, *(xp.asarray(a) for a in (pitch, cells, excess, ankle)), LIMITS)
    )
    names = [outcomes.FALL_CAUSES[c] for c in got]
    assert names == [
        "foot_pitch",
        "heel_lift",
        "toe_lift",
        "state_bound",
        "lower_tilt",
        "",
        "foot_pitch",
    ]
    np.testing.assert_array_equal(
        outcomes.falls(np, pitch, cells, excess, ankle, LIMITS), got != outcomes.NO_CAUSE
    )


# --- the settle band -------------------------------------------------------------------------

# (q, dq, in band): defaults 0.01 rad and 0.05 rad/s, edges included
BAND_SAMPLES = [
    ([0.0, 0.0], [0.0, 0.0], True),
    ([0.0099, -0.0099], [0.0499, -0.0499], True),
    ([0.01, -0.01], [0.05, -0.05], True),  # the edges are in
    ([0.0101, 0.0], [0.0, 0.0], False),
    ([-0.0101, 0.0], [0.0, 0.0], False),
    ([0.0, 0.0101], [0.0, 0.0], False),
    ([0.0, -0.0101], [0.0, 0.0], False),
    ([0.0, 0.0], [0.0501, 0.0], False),
    ([0.0, 0.0], [0.0, -0.0501], False),
    ([0.0, 0.0], [0.02, 0.0], True),  # a rate above the angle tolerance is fine
]


def test_in_settle_band(ns):
    q = np.array([s[0] for s in BAND_SAMPLES])
    dq = np.array([s[1] for s in BAND_SAMPLES])
    got = ns.call(outcomes.in_settle_band, q, dq, limits=LIMITS)
    np.testing.assert_array_equal(got, [s[2] for s in BAND_SAMPLES])
    assert ns.call(outcomes.in_settle_band, q[3], dq[3], limits=LIMITS).shape == ()


# --- saturation ------------------------------------------------------------------------------

# tolerance SATURATION_TOL of each range: 4e-5 N m for u1 in [-20, 20], 2e-4 for u2 in
# [-100, 100]; margins of 1e-5 and 5e-5 around them
TOL1, TOL2 = SATURATION_TOL * 40.0, SATURATION_TOL * 200.0
SATURATION_SAMPLES = [
    ([0.0, 0.0], [False, False]),
    ([20.0, 100.0], [True, True]),
    ([-20.0, -100.0], [True, True]),
    ([20.0 - TOL1 + 1e-5, 100.0 - TOL2 + 5e-5], [True, True]),
    ([20.0 - TOL1 - 1e-5, 100.0 - TOL2 - 5e-5], [False, False]),
    ([-20.0 + TOL1 - 1e-5, -100.0 + TOL2 - 5e-5], [True, True]),
    ([-20.0 + TOL1 + 1e-5, -100.0 + TOL2 + 5e-5], [False, False]),
    ([25.0, -150.0], [True, True]),  # beyond a bound counts (an unclipped input)
    ([19.0, 99.0], [False, False]),
    ([20.0, 0.0], [True, False]),  # each input on its own
]


def test_at_input_bound(ns):
    u = np.array([s for s, _ in SATURATION_SAMPLES])
    got = ns.call(outcomes.at_input_bound, u, limits=LIMITS)
    assert got.shape == u.shape
    np.testing.assert_array_equal(got, [e for _, e in SATURATION_SAMPLES])


def test_at_input_bound_of_a_switched_off_input():
    """An input with bounds (0, 0) (the ankle-only study's hip motor) is always at its bound:
    the tolerance is relative to the range, so it is zero there."""
    off = LIMITS._replace(input_lower=(-20.0, 0.0), input_upper=(20.0, 0.0))
    got = outcomes.at_input_bound(np, np.array([[1.0, 0.0], [20.0, 0.0]]), off)
    np.testing.assert_array_equal(got, [[False, True], [True, True]])


# --- classification --------------------------------------------------------------------------


def _expected_code(diverged: bool, fell: bool, settled: bool) -> int:
    if diverged:
        return DIVERGED
    if fell:
        return FELL
    return RECOVERED if settled else NOT_SETTLED


def test_classify_precedence(ns):
    """diverged > fell > settle band, over all eight flag combinations."""
    flags = np.array(list(itertools.product([False, True], repeat=3)))
    got = ns.call(outcomes.classify, flags[:, 0], flags[:, 1], flags[:, 2])
    np.testing.assert_array_equal(got, [_expected_code(*f) for f in flags])
    assert [OUTCOMES[c] for c in (RECOVERED, NOT_SETTLED, FELL, DIVERGED)] == [
        "recovered",
        "not_settled",
        "fell",
        "diverged",
    ]


def test_classify_python_scalars():
    """As metrics.summarize calls it: python bools in, one code out."""
    for d, f, s in itertools.product([False, True], repeat=3):
        assert int(outcomes.classify(np, d, f, s)) == _expected_code(d, f, s)


# --- summary_frame ---------------------------------------------------------------------------


def _summary(outcome, **extra) -> dict:
    n = len(outcome)
    cols = {c: np.arange(n, dtype=float) + 0.5 for c in SUMMARY_COLUMNS if c != "convention"}
    cols["outcome"] = outcome
    cols.update(extra)
    return cols


def test_summary_frame_codes_to_strings_in_column_order():
    codes = np.array([RECOVERED, NOT_SETTLED, FELL, DIVERGED, FELL], np.int32)
    frame = outcomes.summary_frame(_summary(codes, admm_iterations=np.arange(5)), "joint")
    assert list(frame["outcome"]) == ["recovered", "not_settled", "fell", "diverged", "fell"]
    assert list(frame.columns) == SUMMARY_COLUMNS + ["admm_iterations"]
    assert (frame["convention"] == "joint").all()
    np.testing.assert_array_equal(frame["admm_iterations"], np.arange(5))
    np.testing.assert_array_equal(frame["force"], np.arange(5) + 0.5)
    lean = outcomes.summary_frame(
        _summary(codes, admm_iterations=np.arange(5)), "joint", extra=False
    )
    assert list(lean.columns) == SUMMARY_COLUMNS


def test_summary_frame_keeps_strings_and_a_frames_convention():
    frame = pd.DataFrame(_summary(["fell", "recovered"]))[::-1]  # index 1, 0
    frame["convention"] = "paper"
    out = outcomes.summary_frame(frame, "joint")
    assert list(out["outcome"]) == ["recovered", "fell"]
    assert list(out.index) == [0, 1]
    assert (out["convention"] == "paper").all()  # the frame's own, not the argument


def test_summary_frame_missing_column_raises():
    summary = _summary(np.array([0, 2]))
    del summary["energy_hip"], summary["fall_time"]
    with pytest.raises(RuntimeError, match="fall_time, energy_hip"):
        outcomes.summary_frame(summary, "paper")


@pytest.mark.parametrize(
    "outcome",
    [np.array([0, 4]), np.array([-1, 0]), ["fell", "fallen"]],
    ids=["code-too-large", "negative-code", "unknown-string"],
)
def test_summary_frame_unknown_outcome_raises(outcome):
    with pytest.raises(RuntimeError, match="outcome"):
        outcomes.summary_frame(_summary(outcome), "paper")
