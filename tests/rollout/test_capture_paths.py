"""The capture columns (measures/capture.py: steps_needed, capture_margin, decision_time) on the
batched MJX path against the scalar reference with its own OSQP controller: the decision
instant comes before the first infeasible QP, where the two closed loops still agree (their
falls, after it, are 0.1-0.35 s apart: docs/model.md, "Stepping: capturability")."""

from __future__ import annotations

import numpy as np
import pytest
from margins import capture_window, within

from mjx_balance import reference

pytestmark = pytest.mark.usefixtures("float32_module")  # x64 off (conftest)

# falls forwards and backwards, short and long pushes, one still on at the decision instant
PUSHES = [(60.0, 0.5), (100.0, 1.0), (-60.0, 0.5), (30.0, 1.5)]


def test_capture_columns_match_the_reference(batch_runner):
    forces, durations = np.array(PUSHES).T
    mine = batch_runner.run_frame(forces, durations)
    for b, (force, duration) in enumerate(PUSHES):
        ref, frame = reference.simulate_scenario(batch_runner.config, force, duration)
        print(
            f"{force:6.1f} N {duration} s: fall {mine.fall_time[b]:.3f} vs {ref['fall_time']:.3f}"
            f" s, decision {mine.decision_time[b]:.3f} vs {ref['decision_time']:.3f} s, "
            f"steps {mine.steps_needed[b]} vs {ref['steps_needed']}, margin "
            f"{mine.capture_margin[b]:.5f} vs {ref['capture_margin']:.5f} m"
        )
        assert mine.outcome[b] == ref["outcome"] == "fell"
        assert ref["decision_time"] < ref["first_infeasible_time"] + 1e-9
        within(
            mine.decision_time[b],
            ref["decision_time"],
            atol=0.01,
            msg=force,
            why="the first sample past a threshold: test_rollout's recovered-run agreement "
            "(5 % of the CoM's excursion) moves a crossing at >= 0.1 m/s by <= 5 samples",
        )
        low, high = capture_window(
            batch_runner.config, frame, force, duration, ref["decision_time"], 5
        )
        within(
            np.clip(mine.capture_margin[b], low, high),
            mine.capture_margin[b],
            atol=1e-3,
            msg=force,
            why="the margin at a sample within 0.01 s of the reference's decision (above), "
            "up to the CoM's 5 % agreement of test_rollout on a <= 0.02 m excursion",
        )
        assert mine.steps_needed[b] == ref["steps_needed"]


def test_a_recovery_needs_no_step(batch_runner):
    frame = batch_runner.run_frame([0.0, 20.0], [0.1, 0.1])
    assert (frame.outcome == "recovered").all()
    assert (frame.steps_needed == 0).all()
    assert frame.capture_margin.isna().all() and frame.decision_time.isna().all()
