"""A subject's age and sex (model/ageing.py, Subject.age): a man of the human body's mass at the
young group's age is sweeps/human.toml and at the older group's sweeps/human_older.toml; between
them each number moves linearly, beyond them it stays; a woman's strength is 0.66 of a man's; a
subject without an age is what it was. Cohorts take ages from a grid, a CSV column or a
population's distribution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjx_balance.model import ageing
from mjx_balance.model.params import ParameterError
from mjx_balance.model.subject import Subject, parse_subject
from mjx_balance.studies import members
from mjx_balance.studies.people import human_config

MAN = (1.741, 73.0)  # de Leva's reference man: the human bodies' own mass, strength factor 1


def _timing(config):
    c = config.controller
    return (
        *c.input1_bounds,
        *c.input2_bounds,
        *c.input_rates,
        config.scenario.controller_delay,
        config.body.step_time,
    )


@pytest.mark.parametrize(("age", "body"), [(24.0, "human"), (77.0, "human_older")])
def test_a_man_at_each_groups_age_is_that_shipped_body(age, body):
    """Each shipped body's strength, rate, onset and step time from the subject's age; the
    older file writes its rate to 0.1 N m/s (372 x 0.695 = 258.54), hence that tolerance."""
    ours = _timing(Subject(*MAN, age=age).config(human_config("human")))
    shipped = _timing(human_config(body))
    assert np.allclose(ours, shipped, rtol=0, atol=0.05), (ours, shipped)
    assert ours[:4] == pytest.approx(shipped[:4], rel=1e-12)  # the bounds as printed


def test_between_the_groups_linear_and_beyond_them_flat():
    base = human_config("human")
    values = {a: _timing(Subject(*MAN, age=a).config(base)) for a in (18, 24, 50.5, 77, 110)}
    assert values[18] == values[24] and values[77] == values[110]
    middle = (np.array(values[24]) + np.array(values[77])) / 2
    # the middle age's bounds and rates are the mean of the ends'; the delay is on the grid
    assert np.allclose(values[50.5][:6], middle[:6], rtol=1e-12)
    assert values[50.5][7] == pytest.approx(middle[7], rel=1e-12)
    assert values[50.5][6] == pytest.approx(0.112)  # 0.1 + 0.011, on the 2-ms step's grid


@pytest.mark.parametrize("age", [20.0, 33.3, 41.0, 59.9, 70.0, 90.0])
def test_the_onset_lies_on_the_physics_steps_grid(age):
    config = Subject(*MAN, age=age).config(human_config("human"))
    steps = config.scenario.controller_delay / config.scenario.physics_dt
    assert math.isclose(steps, round(steps), abs_tol=1e-9)
    exact = 0.1 + ageing.ONSET_OLDER * ageing.share(age)
    assert abs(config.scenario.controller_delay - exact) <= config.scenario.physics_dt / 2 + 1e-12


def test_a_woman_has_two_thirds_of_a_mans_strength():
    """de Leva's reference woman (61.9 kg) at the young age: 0.66 of the reference man's
    bounds and rate (the mass scaling and the sex factor together)."""
    woman = Subject(1.735, 61.9, "female", age=24.0).config(human_config("human"))
    man = human_config("human")
    for field in ("input1_bounds", "input2_bounds", "input_rates"):
        ours = np.array(getattr(woman.controller, field))
        assert np.allclose(ours, 0.66 * np.array(getattr(man.controller, field)), rtol=1e-12)


def test_without_an_age_a_subject_is_what_it_was():
    base = human_config("human")
    subject = Subject(1.62, 58.0, "female")
    assert "age" not in subject.to_dict() and "age" not in subject.describe()
    config = subject.config(base)
    assert config.scenario == base.scenario and config.body.step_time == base.body.step_time
    scale = 58.0 / base.body.total_mass  # the mass alone scales the bounds
    assert config.controller.input1_bounds == pytest.approx(
        [v * scale for v in base.controller.input1_bounds], rel=1e-12
    )


@pytest.mark.parametrize("age", [17.9, 111.0, float("nan"), float("inf"), "old"])
def test_an_age_out_of_range_is_refused(age):
    with pytest.raises(ParameterError, match="age"):
        Subject(*MAN, age=age)


def test_the_age_from_the_flag_a_csv_file_and_a_grid(tmp_path):
    assert parse_subject("height=1.7,mass=70,age=68").age == 68.0
    with pytest.raises(ParameterError, match="age"):
        parse_subject("height=1.7,mass=70,age=12")
    path = tmp_path / "s.csv"
    path.write_text("id,height,mass,sex,age\na,1.7,70,male,30\nb,1.6,60,female,\n")
    read = {m.id: m.subject for m in members.read_subjects(path)}
    assert read["a"].age == 30.0 and read["b"].age is None
    grid = members.subject_grid([1.7], [70.0], ["male", "female"], ages=[25.0, 75.0])
    assert [(m.subject.sex, m.subject.age) for m in grid] == [
        ("male", 25.0),
        ("male", 75.0),
        ("female", 25.0),
        ("female", 75.0),
    ]


def test_a_populations_ages():
    """Ages drawn after the body, truncated to the range, the same seed the same ages; without
    an age distribution the population is the one drawn before ages existed (no age drawn)."""
    drawn = members.population(200, 3, age_mean=70.0, age_sd=30.0)
    ages = np.array([m.subject.age for m in drawn])
    assert ages.min() >= ageing.AGE_RANGE[0] and ages.max() <= ageing.AGE_RANGE[1]
    assert 60 < ages.mean() < 80 and ages.std() > 10
    again = members.population(200, 3, age_mean=70.0, age_sd=30.0)
    assert [m.subject for m in again] == [m.subject for m in drawn]
    plain = members.population(5, 3)
    assert all(m.subject.age is None for m in plain)
    fixed = members.population(5, 3, age_mean=40.0)
    assert {m.subject.age for m in fixed} == {40.0}
    with pytest.raises(ParameterError, match="age_mean"):
        members.population(5, 3, age_mean=5.0)
