"""Physically meaningless settings are refused, each with a message naming
the field and the rule; every shipped sweep definition and every default still loads."""

import math

import numpy as np
import pytest

from mjx_balance.model.params import (
    LENGTH_RANGE,
    MASS_RANGE,
    MAX_FRICTION,
    MAX_GRAVITY,
    MAX_PHYSICS_DT,
    MIN_GRAVITY,
    BodyParams,
    Config,
    ControllerParams,
    ParameterError,
    ScenarioParams,
)
from mjx_balance.model.config_files import load_config
from mjx_balance.reference.loop import simulate_scenario
from mjx_balance.runs import load_sweep
from mjx_balance.runs.definitions import sweeps_dir

SWEEPS = sorted(sweeps_dir().glob("*.toml"))  # the shipped definitions (package data)
MASSES = ("foot_mass", "lower_mass", "upper_mass")
LENGTHS = (
    "foot_length",
    "foot_width",
    "foot_thickness",
    "lower_length",
    "upper_length",
    "contact_radius",
)


def body(**values) -> BodyParams:
    """BodyParams with ``values``; a segment's CoM is kept on a shortened segment."""
    for segment in ("lower", "upper"):
        length = values.get(f"{segment}_length")
        if length is not None and f"{segment}_com" not in values:
            values[f"{segment}_com"] = min(getattr(BodyParams(), f"{segment}_com"), length)
    return BodyParams(**values)


@pytest.mark.parametrize("path", SWEEPS, ids=lambda p: p.name)
def test_every_shipped_sweep_definition_loads(path):
    assert len(SWEEPS) >= 15
    definition = load_sweep(path, Config())
    assert isinstance(definition.config, Config)


def test_the_defaults_lie_inside_every_range():
    b, s = BodyParams(), ScenarioParams()
    assert all(MASS_RANGE[0] <= getattr(b, name) <= MASS_RANGE[1] for name in MASSES)
    assert all(LENGTH_RANGE[0] <= getattr(b, name) <= LENGTH_RANGE[1] for name in LENGTHS)
    assert b.gravity <= MAX_GRAVITY and s.physics_dt <= MAX_PHYSICS_DT


# ---- time steps ----------------------------------------------------------------------------


def test_physics_dt_is_at_most_half_the_contact_time_constant():
    assert ScenarioParams(physics_dt=MAX_PHYSICS_DT, control_dt=0.01).physics_dt == 0.01
    for dt in (0.02, 1.0):  # physics_dt = control_dt = 1.0
        with pytest.raises(ParameterError, match=r"scenario\.physics_dt = .*must be <= 0\.01 s"):
            ScenarioParams(physics_dt=dt, control_dt=dt)


def test_physics_dt_from_a_file(tmp_path):
    path = tmp_path / "coarse.toml"
    path.write_text("[scenario]\nphysics_dt = 1.0\ncontrol_dt = 1.0\n")
    with pytest.raises(ParameterError, match=r"coarse\.toml: scenario\.physics_dt = 1\.0"):
        load_config(path)


def test_control_dt_is_a_whole_multiple_of_physics_dt():
    with pytest.raises(ParameterError, match=r"scenario\.control_dt .*whole multiple"):
        ScenarioParams(physics_dt=0.004, control_dt=0.01)


# ---- masses, lengths, gravity --------------------------------------------------------------


@pytest.mark.parametrize(
    "name, limits, rule",
    [
        *((name, MASS_RANGE, r"\[0\.001, 10000\] kg") for name in MASSES),
        *((name, LENGTH_RANGE, r"\[0\.001, 10\] m") for name in LENGTHS),
    ],
)
def test_masses_and_lengths_lie_in_the_plausible_range(name, limits, rule):
    for value in limits:
        assert getattr(body(**{name: value}), name) == value
    for value in (0.9 * limits[0], 1.1 * limits[1], 1e308):
        with pytest.raises(ParameterError, match=rf"body\.{name} = .*{rule}"):
            body(**{name: value})


def test_negative_masses_and_lengths_still_say_positive():
    with pytest.raises(ParameterError, match=r"body\.lower_mass = -30\.0: must be > 0"):
        BodyParams(lower_mass=-30.0)


def test_gravity_and_ankle_height_ranges():
    assert BodyParams(gravity=MAX_GRAVITY).gravity == MAX_GRAVITY
    with pytest.raises(
        ParameterError, match=r"body\.gravity = 1000000\.0: must lie in \[0\.1, 100\]"
    ):
        BodyParams(gravity=1e6)
    assert BodyParams(gravity=MIN_GRAVITY).gravity == MIN_GRAVITY
    with pytest.raises(ParameterError, match=r"body\.gravity = 1e-300: must lie in"):
        BodyParams(gravity=1e-300)
    assert BodyParams(ankle_height=LENGTH_RANGE[1]).ankle_height == LENGTH_RANGE[1]
    with pytest.raises(ParameterError, match=r"body\.ankle_height = 11\.0: must lie in \[0, 10\]"):
        BodyParams(ankle_height=11.0)


def test_a_huge_mass_in_a_file_is_refused(tmp_path):
    path = tmp_path / "heavy.toml"
    path.write_text("[body]\nupper_mass = 1e308\n")
    with pytest.raises(ParameterError, match=r"heavy\.toml: body\.upper_mass = 1e\+308"):
        load_config(path)


# ---- booleans are not numbers, lists hold numbers ------------------------------------------


@pytest.mark.parametrize(
    "make,field,rule",
    [
        (lambda: ControllerParams(q_diag=(True, 1, 1, 1)), "q_diag", "a list of numbers"),
        (lambda: ControllerParams(r_diag=(0.1, False)), "r_diag", "a list of numbers"),
        (
            lambda: ControllerParams(input1_bounds=(False, True)),
            "input1_bounds",
            "a list of numbers",
        ),
        (lambda: ControllerParams(q_diag=("a", 1, 1, 1)), "q_diag", "a list of numbers"),
        (lambda: ControllerParams(input1_bounds=([1, 2], 3)), "input1_bounds", "a list of numbers"),
        (lambda: ControllerParams(q_diag=1e3), "q_diag", "a list of numbers"),
        (lambda: ControllerParams(horizon=True), "horizon", "a number"),
        (lambda: ControllerParams(osqp_eps="1e-8"), "osqp_eps", "a number"),
        (
            lambda: ControllerParams(admm_stop_on_infeasible=1),
            "admm_stop_on_infeasible",
            "true or false",
        ),
        (lambda: ControllerParams(convention=1), "convention", "a string"),
        (lambda: BodyParams(foot_mass=True), "foot_mass", "a number"),
        (lambda: ScenarioParams(force=True), "force", "a number"),
        (lambda: ScenarioParams(push_body=None), "push_body", "a string"),
    ],
)
def test_types_are_checked_on_construction(make, field, rule):
    with pytest.raises(ParameterError, match=rf"\.{field} = .*: must be .*{rule}"):
        make()


@pytest.mark.parametrize(
    "text,field",
    [
        ("[controller]\nq_diag = [true, 1, 1, 1]\n", "q_diag"),
        ('[controller]\nq_diag = ["a", 1, 1, 1]\n', "q_diag"),
        ("[controller]\ninput1_bounds = [[1, 2], 3]\n", "input1_bounds"),
        ("[controller]\ncop_bounds = [[-0.1], [0.1]]\n", "cop_bounds"),
        ("[controller]\nr_diag = [0.1, false]\n", "r_diag"),
    ],
)
def test_lists_in_a_file_hold_numbers(tmp_path, text, field):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ParameterError, match=rf"controller\.{field} = .*must be a list of numbers"):
        load_config(path)


def test_numpy_numbers_are_numbers():
    controller = ControllerParams(q_diag=tuple(np.float32(v) for v in (1e3, 1e3, 1.0, 1.0)))
    assert controller.q_diag == (1e3, 1e3, 1.0, 1.0)
    assert BodyParams(lower_mass=np.float64(31.0)).lower_mass == 31.0
    with pytest.raises(ParameterError, match=r"body\.lower_mass = .*finite"):
        BodyParams(lower_mass=np.float32(math.nan))


# ---- the file itself -----------------------------------------------------------------------


def test_a_folder_or_binary_file_is_not_a_configuration(tmp_path):
    with pytest.raises(ParameterError, match="a folder, not a configuration file"):
        load_config(tmp_path)
    path = tmp_path / "binary.toml"
    path.write_bytes(b"\xff\xfe[body]\n")
    with pytest.raises(ParameterError, match=r"binary\.toml: not UTF-8 text \(byte 0\)"):
        load_config(path)


def test_friction_above_two_is_refused():
    """At friction 2.5 the upright body no longer settles at rest and at 3.5 it falls with no
    push (pyramidal contacts soften with friction; measured with the reference): refused."""
    assert BodyParams(friction=2.0).friction == 2.0
    with pytest.raises(ParameterError, match=r"body\.friction = 2\.5: must be <= 2"):
        BodyParams(friction=2.5)


def test_at_the_friction_limit_the_body_stands():
    """The limit is where the reference still holds upright rest (no push, 1 s)."""
    config = Config().replace(body={"friction": MAX_FRICTION}, scenario={"t_end": 1.0})
    summary, _ = simulate_scenario(config, 0.0, 0.0, record=False)
    assert summary["outcome"] == "recovered"


@pytest.mark.parametrize("field", ["settle_angle_tol", "settle_rate_tol", "t_end"])
@pytest.mark.parametrize("value", [0.0, -0.01, float("nan")])
def test_the_definition_of_recovery_is_validated(field, value):
    """The settle band and the window (docs/study.md varies them) are checked like the rest."""
    with pytest.raises(ParameterError, match=f"scenario.{field}"):
        Config().replace(scenario={field: value})
