"""Parameter validation, TOML round trip, and the shipped default model."""

import math
from importlib import resources

import pytest

from mjx_balance.model.mjcf import default_model_path, mjcf
from mjx_balance.model.params import (
    BodyParams,
    Config,
    ControllerParams,
    ParameterError,
    ScenarioParams,
)
from mjx_balance.model.config_files import (
    config_from_dict,
    dumps_config,
    load_config,
    run_config,
)


@pytest.mark.parametrize(
    "make,field",
    [
        (lambda: BodyParams(lower_mass=-30.0), "lower_mass"),
        (lambda: BodyParams(foot_mass=0.0), "foot_mass"),
        (lambda: BodyParams(upper_length=-0.6), "upper_length"),
        (lambda: BodyParams(lower_length=-1.0), "lower_length"),
        (lambda: BodyParams(upper_com=0.7), "upper_com"),
        (lambda: ControllerParams(horizon=0), "horizon"),
        (lambda: ControllerParams(horizon=-3), "horizon"),
        (lambda: ControllerParams(input1_bounds=(20.0, -20.0)), "input1_bounds"),
        (lambda: ControllerParams(state2_bounds=(1.4, -0.35)), "state2_bounds"),
        (lambda: ControllerParams(cop_bounds=(0.15, -0.15)), "cop_bounds"),
        (lambda: ControllerParams(com_bounds=(0.2, 0.1)), "com_bounds"),
        (lambda: ScenarioParams(control_dt=0.005), "control_dt"),
        (lambda: ScenarioParams(physics_dt=0.003), "control_dt"),
        (lambda: ScenarioParams(duration=-0.1), "duration"),
        (lambda: BodyParams(lower_mass=math.nan), "lower_mass"),
        (lambda: BodyParams(gravity=math.inf), "gravity"),
        (lambda: ControllerParams(q_diag=(1e3, math.inf, 1e3, 1e3)), "q_diag"),
        (lambda: ScenarioParams(force=math.nan), "force"),
        (lambda: ControllerParams(convention="absolute"), "convention"),
    ],
)
def test_bad_values_raise_naming_the_field(make, field):
    with pytest.raises(ParameterError, match=field):
        make()


@pytest.mark.parametrize(
    "text,field",
    [
        ("[body]\nlower_mass = -30.0\n", "lower_mass"),
        ("[body]\nlower_mass = nan\n", "lower_mass"),
        ("[scenario]\nforce = inf\n", "force"),
        ("[controller]\nhorizon = 0\n", "horizon"),
        ("[controller]\ninput2_bounds = [100.0, -100.0]\n", "input2_bounds"),
        ("[scenario]\ncontrol_dt = 0.007\n", "control_dt"),
        ("[body]\nlower_mas = 30.0\n", "lower_mas"),
        ("[controllers]\nhorizon = 10\n", "controllers"),
        ('[controller]\nhorizon = "ten"\n', "horizon"),
        ("[controller]\nhorizon = true\n", "horizon"),  # a bool is not a number
        ("[controller]\nadmm_stop_on_infeasible = 1\n", "admm_stop_on_infeasible"),
        ('[controller]\nadmm_stop_on_infeasible = "yes"\n', "admm_stop_on_infeasible"),
    ],
)
def test_bad_toml_raises_naming_the_field(tmp_path, text, field):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ParameterError, match=field):
        load_config(path)


def test_unknown_keys_list_the_known_ones():
    with pytest.raises(ParameterError, match="known keys"):
        config_from_dict({"scenario": {"t_stop": 3.0}})


def test_missing_file_is_a_parameter_error(tmp_path):
    with pytest.raises(ParameterError, match="not found"):
        load_config(tmp_path / "nope.toml")


def test_toml_round_trip(tmp_path):
    config = Config().replace(
        body={"lower_mass": 42.5, "upper_com": 0.25},
        controller={
            "convention": "joint",
            "horizon": 15,
            "q_diag": [1e4, 1e3, 10.0, 1.0],
            "osqp_eps": 1e-9,
        },
        scenario={"force": 80.0, "duration": 0.25, "t_end": 4.0, "push_body": "hip"},
    )
    path = tmp_path / "config.toml"
    path.write_text(dumps_config(config))
    assert load_config(path) == config
    assert config_from_dict(config.to_dict()) == config
    path.write_text(dumps_config(Config()))
    assert load_config(path) == Config()
    assert "[controller]" in dumps_config(config)


def test_partial_toml_takes_defaults(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text("[scenario]\nt_end = 2\n")
    config = load_config(path)
    assert config.scenario.t_end == 2.0
    assert config.body == BodyParams() and config.controller == ControllerParams()


def test_run_config_file_then_convention(tmp_path):
    """A run's configuration (what every command loads): the file or the defaults, then
    --convention on top; None keeps the file's."""
    path = tmp_path / "run.toml"
    path.write_text(
        '[controller]\nconvention = "joint"\nadmm_stop_on_infeasible = true\n'
        "[scenario]\nt_end = 3\n"
    )
    assert run_config() == Config()
    assert run_config(None, "joint") == Config().replace(controller={"convention": "joint"})
    from_file = run_config(path)
    assert from_file.controller.convention == "joint" and from_file.scenario.t_end == 3.0
    assert from_file.controller.admm_stop_on_infeasible is True
    assert run_config(path, None) == from_file
    assert run_config(path, "paper") == from_file.replace(controller={"convention": "paper"})
    with pytest.raises(ParameterError, match="convention"):
        run_config(path, "absolute")


def test_replace_validates():
    with pytest.raises(ParameterError, match="horizon"):
        Config().replace(controller={"horizon": 0})
    assert Config().replace(controller={"convention": "joint"}).controller.convention == "joint"


def test_shipped_model_is_the_generated_default():
    shipped = (resources.files("mjx_balance") / "data" / "balance.xml").read_text()
    assert shipped == mjcf()
    with open(default_model_path()) as fh:
        assert fh.read() == mjcf()


def test_a_sweep_definition_as_a_plain_config_says_where_it_goes(tmp_path):
    """A file with a [sweep] table given where a configuration goes (``--config``,
    ``load_config``) is refused with the command that runs it, not as an unknown section; a
    shipped configuration is found by name."""
    from mjx_balance.model.config_files import load_config
    from mjx_balance.runs.definitions import find_sweep

    path = tmp_path / "grid.toml"
    path.write_text('[sweep]\nforces = "0:10:10"\n[scenario]\nt_end = 2.0\n')
    with pytest.raises(ParameterError, match="sweep --sweep grid"):
        load_config(path)
    assert load_config(find_sweep("human")).body.ankle_position == 0.4415
