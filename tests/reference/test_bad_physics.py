"""Pushes the physics cannot take: the reference reports `diverged`."""

import math

from mjx_balance.model.params import Config
from mjx_balance.reference.loop import simulate_scenario


def short(t_end: float) -> Config:
    return Config().replace(scenario={"t_end": t_end})


def test_absurd_push_diverges_at_the_step_mujoco_warns():
    # 1e12 N on 35 kg: MuJoCo warns "Nan, Inf or huge value in QACC" and resets the data to rest;
    # carrying on from there used to report `recovered`, settle time 0.
    summary, frame = simulate_scenario(short(0.5), 1e12, 0.1)
    assert summary["outcome"] == "diverged"
    assert len(frame) < 50  # stopped within the push (0.1 s = 50 steps), not run on from rest


def test_normal_push_still_recovers():
    summary, _ = simulate_scenario(short(3.0), 20.0, 0.1)
    assert summary["outcome"] == "recovered"
    assert math.isnan(summary["fall_time"])
