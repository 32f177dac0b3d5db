"""The people protocols on the batched engine against the scalar reference (slow: each body and
loading compiles an engine of its own): the ramped waist pull at the hip of the older human
body, the human body's lean and release (its foot with the ankle off the sole's centre, its rate
limit, latency and relaxed start), and the scorecard's folder."""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest
from margins import within
from support import AdmmMPC, assert_cells_like_the_reference

from mjx_balance.measures import units
from mjx_balance.model.params import ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner
from mjx_balance.studies import people, pull

pytestmark = pytest.mark.slow


def _runner(config, slots=4):
    return BatchRunner(
        config, physics="mjx", slots=slots, early_stop=False, devices=jax.local_devices()[:1]
    )


def test_the_ramped_pull_runs_as_the_reference():
    """Pulls at the hip rising over 2 s, then held to 5 s, of the older human body: the MJX
    engine and the reference loop with the same float32 ADMM give the same outcomes, fall
    samples and energies (within the float32 loop's rounding), some held and some not (so the
    check can fail); the same pulls applied at once are not the same runs."""
    config = pull.pulled(people.human_config("human_older"), 2.0).replace(scenario={"t_end": 5.0})
    cells = [(f, 5.0) for f in (15.0, 30.0, 60.0, -20.0)]
    runner = _runner(config)
    forces, durations = np.array(cells).T
    frame = runner.run_frame(forces, durations)
    outcomes = assert_cells_like_the_reference(config, frame, cells, AdmmMPC(runner))
    assert "fell" in outcomes and set(outcomes) - {"fell"}
    step = _runner(config.replace(scenario={"push_ramp": 0.0})).run_frame(forces, durations)
    assert not np.allclose(step["energy_ankle"], frame["energy_ankle"])  # the ramp is applied


def test_the_human_lean_runs_as_the_reference():
    """The human body's lean and release with the ankle strategy (its foot's sole from 0.114 m
    behind to 0.144 m ahead of the ankle, the rate limit, the 0.1-s onset, the relaxed start):
    the same outcomes and fall samples on the MJX engine and the reference; both outcomes
    occur."""
    config = people.ankle_strategy(people.human_config("human")).replace(scenario={"t_end": 3.0})
    leans = np.radians([2.0, 4.0, 6.0, 9.0])
    inits = np.zeros((leans.size, 4))
    inits[:, 0] = leans
    zeros = np.zeros(leans.size)
    runner = _runner(config)
    out = runner.run_frame(zeros, zeros, inits)
    mpc = AdmmMPC(runner)
    for b, init in enumerate(inits):
        ref = reference.simulate_scenario(config, 0.0, 0.0, record=False, mpc=mpc, initial=init)[0]
        assert ref["outcome"] == out["outcome"].iloc[b], np.degrees(init[0])
        within(
            out["fall_time"].iloc[b],
            ref["fall_time"],
            atol=1e-12,
            why="the same fall sample (both compute its time as k dt)",
        )
    assert {"recovered", "fell"} <= set(out["outcome"])


def test_the_people_folder_scores_every_row(tmp_path):
    """``run_people`` (``mjx-balance people``) at coarse brackets: people.csv has every people
    row with its kind, our value where predicted or an input, and a reason wherever it is not a
    predicted agreement; people_limits.csv every body's limits; a manifest with both bodies;
    every column with a unit."""
    out = tmp_path / "people"
    card = people.run_people(out, lean_resolution=1.0, pull_resolution=10.0, say=lambda _: None)
    written = pd.read_csv(out / people.PEOPLE_CSV, keep_default_na=False)
    assert list(written["measure"]) == list(card["measure"])
    predicted = card[card.kind == "predicted"]
    assert predicted["ours"].notna().all() and len(predicted) >= 9
    assert (card[card.kind == "not modelled"]["ours"].isna()).all()
    not_agreeing = card[card.agrees.ne(True)]
    assert (not_agreeing["reason"].str.len() > 0).all()
    limits = pd.read_csv(out / people.PEOPLE_LIMITS_CSV)
    assert set(limits["body"]) == {*people.BODIES, *people.WOMEN}
    assert set(limits["protocol"]) == {"lean", "pull", "pull_step"}
    women = limits[limits["body"].isin(list(people.WOMEN))]
    assert set(women["protocol"]) == {"lean"}  # lean and release only
    for name in (people.PEOPLE_CSV, people.PEOPLE_LIMITS_CSV):
        assert units.unknown(pd.read_csv(out / name).columns) == [], name
    assert (out / people.PEOPLE_FIGURE).stat().st_size > 0
    with pytest.raises(ParameterError, match="resolution"):
        people.run_people(tmp_path / "bad", pull_resolution=0.0)
    assert not (tmp_path / "bad").exists()


def test_the_pull_folder_holds_the_limits_and_refuses_another_configuration(tmp_path):
    """``mb.waist_pull(out=)`` (``mjx-balance pull``): pull.csv is the limits' row, every column
    with a unit; a ramp beyond the window is refused before the folder is made; another
    configuration is refused by the folder."""
    import mjx_balance as mb

    config = people.human_config("human_older").replace(scenario={"t_end": 4.0})
    out = tmp_path / "pull"
    frame = mb.waist_pull(config, resolution=10.0, ramp=2.0, out=out)
    written = pd.read_csv(out / pull.PULL_CSV)
    assert list(written.columns) == list(frame.columns) and len(written) == 1
    assert units.unknown(written.columns) == []
    assert written["ramp_s"].iloc[0] == 2.0 and written["forward_n"].iloc[0] > 0
    with pytest.raises(ParameterError, match="push_ramp"):
        mb.waist_pull(config, ramp=5.0, out=tmp_path / "bad")
    assert not (tmp_path / "bad").exists()
    with pytest.raises(ParameterError, match="different configuration"):
        mb.waist_pull(config.replace(scenario={"t_end": 5.0}), resolution=10.0, out=out)
