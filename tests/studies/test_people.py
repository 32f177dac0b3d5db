"""The people scorecard's parts without an engine (studies/thresholds.py, pull.py, people.py):
the threshold search against a known threshold, the waist pull's forces and units against a
stand-in runner, the scorecard's rows against the people reference, the human bodies' numbers
against their sources. The engine runs them in the slow run (test_people_engine.py)."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from mjx_balance.figures.people import people_figure
from mjx_balance.measures import units
from mjx_balance.measures.outcomes import FELL, RECOVERED
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.model.subject import segments
from mjx_balance.studies import people, pull, thresholds
from mjx_balance.studies.lean import LeanLimits
from mjx_balance.studies.references import read_people


@pytest.mark.parametrize("limit", [0.0, 3.3, 17.0, 29.99])
def test_the_threshold_search_brackets_a_known_threshold(limit):
    """Values up to ``limit`` pass: the search ends with low <= limit < high, high - low within
    the resolution, in no more scenarios than planned, every call of SCAN values."""
    calls = []

    def passes(values):
        calls.append(len(values))
        return values <= limit, 2 * values

    found = thresholds.largest_passing(passes, 30.0, 0.05)
    assert found.low <= limit < found.high and found.width <= 0.05
    assert found.peak == 2 * found.low
    assert found.runs == sum(calls) <= thresholds.planned_runs(30.0, 0.05)
    assert set(calls) == {thresholds.SCAN}


def test_the_threshold_search_says_beyond_and_at_zero():
    beyond = thresholds.largest_passing(lambda v: (v <= 99.0, v), 30.0, 0.05)
    assert beyond.low == 30.0 and math.isinf(beyond.high) and beyond.width == 0.0
    none = thresholds.largest_passing(lambda v: (v < 0.0, v), 30.0, 0.05)
    assert none.low == 0.0 and none.high == 0.0 and math.isnan(none.peak)


class Pulls:
    """A stand-in batch runner: a pull is held up to ``forward`` N forward and ``backward`` N
    backward; its peak ankle torque is |F| x the hip height."""

    def __init__(self, config, forward, backward):
        self.config = config
        self.limits = (forward, backward)
        self.seen = []

    def run(self, forces, durations, inits=None):
        forces = np.asarray(forces)
        self.seen.append((forces.copy(), np.asarray(durations).copy()))
        limit = np.where(forces >= 0, self.limits[0], self.limits[1])
        held = np.abs(forces) <= limit
        return {
            "outcome": np.where(held, RECOVERED, FELL),
            "peak_tau_ankle": np.abs(forces) * self.config.body.lower_length,
        }


def test_the_waist_pull_holds_the_whole_window_at_the_hip_both_ways():
    config = Config()
    runner = Pulls(pull.pulled(config), forward=61.3, backward=22.7)
    limits = pull.pull_limits(config, resolution=0.5, ramp=2.0, runner=runner)
    assert limits.ramp_s == 2.0 and runner.config.scenario.push_ramp == 0.0  # the stand-in's
    weight = config.body.total_mass * config.body.gravity
    assert limits.weight_n == weight
    assert limits.forward_n <= 61.3 < limits.forward_n + 0.5
    assert limits.backward_n <= 22.7 < limits.backward_n + 0.5
    assert limits.forward_pct == 100 * limits.forward_n / weight
    assert limits.backward_pct == 100 * limits.backward_n / weight
    assert limits.peak_ankle_torque_forward == limits.forward_n * config.body.lower_length
    assert limits.scenarios == sum(f.size for f, _ in runner.seen)
    assert limits.scenarios <= pull.planned_pulls(config, 0.5)
    signs = {np.sign(f[f != 0]).max() for f, _ in runner.seen} | {
        np.sign(f[f != 0]).min() for f, _ in runner.seen
    }
    assert signs == {1.0, -1.0}  # both directions pulled
    t_end = config.scenario.t_end
    assert all((d == t_end).all() for _, d in runner.seen)  # held for the whole window
    assert pull.pulled(config).scenario.push_body == "hip"
    assert pull.pulled(config, 3.0).scenario.push_ramp == 3.0
    assert units.unknown(limits.row()) == []


@pytest.mark.parametrize("resolution", [0.0, 11.0, True, "1"])
def test_a_bad_pull_resolution_is_refused(resolution):
    with pytest.raises(ParameterError, match="resolution"):
        pull.pull_limits(Config(), resolution=resolution, runner=object())


def _results(dynamic, peak, forward_pct):
    """Stand-in results of both bodies (only the fields the scorecard reads matter)."""
    lean = LeanLimits(9.0, 12.0, 9.0, dynamic, 0.05, peak, 48, one_step_deg=20.0)
    weight = 700.0
    pulls = pull.PullLimits(
        5.0, forward_pct * weight / 100, forward_pct, 10.0, 10 / 7, 0.5, weight, 50.0, 20.0, 96
    )
    out = {}
    for body in people.BODIES:
        config = people.human_config(body)
        out[body] = people.BodyResults(config, lean, pulls, pulls)
    for body in people.WOMEN:  # lean and release only
        out[body] = people.BodyResults(people.human_config(body), lean, None, None)
    return out


def test_every_people_row_has_a_kind_and_the_scorecard_scores_by_hand():
    ref = read_people()
    assert set(people.ROWS) == set(ref["measure"])  # every row, none made up
    assert {r.kind for r in people.ROWS.values()} <= set(people.KINDS)
    card = people.scorecard(_results(dynamic=5.0, peak=300.0, forward_pct=12.0))
    assert list(card["measure"]) == list(ref["measure"])
    assert units.unknown(card.columns) == []
    rows = card.set_index("measure")
    dyn = rows.loc["lean_release_max_angle_young"]
    assert dyn["ours"] == 5.0 and dyn["agrees"] == (5.9 - 2.2 <= 5.0 <= 5.9 + 2.2)
    torque = rows.loc["lean_release_peak_ankle_torque_young"]
    assert torque["agrees"] == (116 - 64 <= 300 <= 116 + 64)  # False: a reason must be given
    assert not torque["agrees"] and isinstance(torque["reason"], str)
    fallers = rows.loc["waist_pull_step_threshold_older_fallers"]
    assert fallers["ours"] == 12.0 and fallers["agrees"] == (7.5 - 2.8 <= 12.0 <= 7.5 + 2.8)
    # inputs are shown, never scored; rows not modelled have no value
    latency = rows.loc["lean_release_torque_onset_latency_young"]
    config = people.human_config("human")
    assert latency["kind"] == "input" and pd.isna(latency["agrees"])
    assert latency["ours"] == 1000 * config.scenario.controller_delay
    platform = rows.loc["platform_translation_max_no_step_young"]
    assert platform["kind"] == "not modelled" and math.isnan(platform["ours"])
    # the women's single-step rows: the women's bodies, their subject in the settings
    women = rows.loc["lean_release_single_step_max_angle_older_women"]
    assert women["kind"] == "predicted" and women["body"] == "human_older_women"
    assert women["ours"] == 20.0 and "sex=female,age=73.7" in women["settings"]
    # a single step: the one-step lean limit, a predicted row without an SD, never agreeing
    step = rows.loc["lean_release_single_step_max_angle_young_men"]
    assert step["kind"] == "predicted" and step["ours"] == 20.0 and step["agrees"] is False
    assert step["reason"].startswith("no SD")


def test_every_row_we_do_not_predict_says_why():
    """An input or a row not modelled always carries its reason (people.csv's ``reason``); a
    predicted row's reason is the measured one, shown only when it does not agree."""
    reasons = read_people().set_index("measure")["reason"].fillna("")
    for measure, row in people.ROWS.items():
        if row.kind != "predicted":
            assert reasons[measure].startswith(("an input", "not modelled")), measure


def test_the_womens_bodies_are_de_levas_reference_woman_at_the_studys_ages():
    """Wojcik et al. 1999's young (25.0 yr) and older (73.7 yr) women: de Leva's reference
    woman's segments on the young man's body, strength and timing by age and sex."""
    expected = segments(1.735, 61.9, "female")
    young, older = (people.human_config(name) for name in people.WOMEN)
    for config in (young, older):
        for key, value in expected.items():
            assert math.isclose(getattr(config.body, key), value, rel_tol=1e-12), key
    assert young.controller.input1_bounds[0] < older.controller.input1_bounds[0] < 0  # weaker
    assert young.scenario.controller_delay < older.scenario.controller_delay


def test_the_human_body_is_de_levas_reference_man():
    """``sweeps/human.toml``'s segments are those of de Leva's (1996) reference male sample
    (1.741 m, 73.0 kg) through the segment table, as its comment says (written out so that a
    subject scales from them); the older body has the same segments."""
    expected = segments(1.741, 73.0, "male")
    for name in people.BODIES:
        body = people.human_config(name).body
        for key, value in expected.items():
            assert math.isclose(getattr(body, key), value, rel_tol=1e-12), (name, key)


def test_the_scorecard_figure_draws_every_scored_row():
    card = people.scorecard(_results(dynamic=5.0, peak=300.0, forward_pct=12.0))
    fig = people_figure(card)
    labels = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    scored = card[card.kind.isin(("predicted", "input")) & card.published_sd.notna()]
    assert len(labels) == len(scored)
    # the predicted rows without an SD (the single-step limits) are given in the title
    title = fig.axes[0].get_title()
    assert "single step max angle young men: ours 20 vs 32.5 deg" in title
    plt.close(fig)


def test_the_ankle_moves_along_the_sole():
    """``body.ankle_position``: the sole and its load cells move under the ankle (the study's
    0.5 leaves the model's text as it was); refused off the sole; left out of files at 0.5."""
    import mujoco

    from mjx_balance.model.mjcf import LOAD_CELLS, build_model, mjcf
    from mjx_balance.model.params import BodyParams

    assert "ankle_position" not in Config().to_dict()["body"]
    assert mjcf(BodyParams(ankle_position=0.5)) == mjcf(BodyParams())
    body = BodyParams(foot_length=0.26, ankle_position=0.25)
    assert body.sole_edges == (-0.065, 0.195)
    model = build_model(body)
    xs = [
        model.geom_pos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n)][0] for n in LOAD_CELLS
    ]
    assert np.allclose(xs, [0.195, 0.195, -0.065, -0.065], atol=1e-6)  # the text's 6 digits
    for bad in (0.0, 0.99, -0.1):
        with pytest.raises(ParameterError, match="ankle_position"):
            BodyParams(ankle_position=bad)


def test_a_push_ramp_rises_then_holds():
    """``scenario.push_ramp``: the share of the force at physics step i is (i + 1) / R up to 1
    (R = push_ramp / dt); 0 is a step (share 1 throughout); refused outside [0, t_end]; left
    out of files at 0."""
    assert "push_ramp" not in Config().to_dict()["scenario"]
    sc = Config().replace(scenario={"push_ramp": 0.01}).scenario  # 5 steps of 2 ms
    assert sc.ramp_steps == 5
    assert [sc.ramp_factor(i) for i in range(7)] == [0.2, 0.4, 0.6, 0.8, 1.0, 1.0, 1.0]
    assert Config().scenario.ramp_factor(0) == 1.0
    for bad in (-0.1, 13.0):
        with pytest.raises(ParameterError, match="push_ramp"):
            Config().replace(scenario={"push_ramp": bad})


def test_the_table_points_the_people_reference_to_its_command(capsys):
    from mjx_balance.cli.main import build_parser

    with pytest.raises(SystemExit) as exit_info:
        build_parser().parse_args(["table", "--reference", "people", "--out", "x"])
    assert exit_info.value.code == 2
    assert "mjx-balance people" in capsys.readouterr().err
