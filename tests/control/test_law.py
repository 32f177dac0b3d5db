"""Controllers behind one interface (control/law.py; docs/model.md, "Bring your own
controller"): the configuration's kind and options, the built-in LQR and PD designs, a user's
factory refused in one line when it fails, and every law on the batched path against the same
law in the scalar reference."""

from __future__ import annotations

import numpy as np
import pytest
from margins import within

from mjx_balance.control import law
from mjx_balance.model.config_files import config_from_dict, dumps_config
from mjx_balance.model.linear import S, linear_model, mass_gravity_abs
from mjx_balance.model.params import Config, ParameterError


def test_kind_and_options_round_trip_and_stay_out_of_the_mpcs_files():
    # the MPC's configuration files read as before: no kind, no options written
    assert "kind" not in dumps_config(Config())
    config = config_from_dict(
        {"controller": {"kind": "law_examples:integral_lqr", "options": {"ki": 2}}}
    )
    assert config.controller.options == (("ki", 2),)
    import tomllib

    assert config_from_dict(tomllib.loads(dumps_config(config))) == config


@pytest.mark.parametrize(
    "controller, words",
    [
        ({"kind": "foo"}, "controller.kind"),
        ({"kind": "lqr", "options": {"a": 1}}, "controller.options"),
        ({"kind": "pd", "offset_free": True}, "controller.offset_free"),
        ({"kind": "a:b", "options": {"a": {"x": 1}}}, "controller.options"),
    ],
)
def test_a_bad_kind_or_option_is_refused_by_name(controller, words):
    with pytest.raises(ParameterError, match=words):
        config_from_dict({"controller": controller})


@pytest.mark.parametrize(
    "kind, words",
    [
        ("no_such_module_x:make", "cannot import no_such_module_x"),
        ("law_examples:nothing", "has no function nothing"),
        ("law_examples:broken", "the factory failed: RuntimeError: no weights here"),
        ("law_examples:not_a_controller", "returned dict"),
        ("law_examples:three_inputs", "u of shape \\(3,\\), not 2 inputs"),
        ("law_examples:branching", "JAX cannot trace its law: TracerBoolConversionError"),
        ("law_examples:growing_state", "a state of another structure, shape or dtype"),
    ],
)
def test_a_users_factory_that_fails_is_named_in_one_line(kind, words):
    config = Config().replace(controller={"kind": kind})
    with pytest.raises(ParameterError, match=words) as caught:
        law.controller_of(config)
    assert "\n" not in str(caught.value)


def test_lqr_is_the_riccati_fixed_point_of_the_mpcs_model_and_weights():
    """The gain against the Riccati difference equation iterated to its fixed point (an
    independent computation: the DARE's stabilising solution is that iteration's limit, reached
    geometrically; 3000 control periods = 30 s is far past the slowest closed-loop mode)."""
    config = Config()
    ctrl = config.controller
    lm = linear_model(config.body, ctrl.convention, config.scenario.control_dt)
    Q, R = np.diag(ctrl.q_diag), np.diag(ctrl.r_diag)
    P = Q.copy()
    for _ in range(3000):
        K = np.linalg.solve(R + lm.B.T @ P @ lm.B, lm.B.T @ P @ lm.A)
        P = Q + lm.A.T @ P @ (lm.A - lm.B @ K)
    gain = law.lqr(config).params["gain"]
    within(gain, K, rtol=1e-6, atol=1e-6 * np.abs(K).max(), why="the iteration's convergence")
    assert np.abs(np.linalg.eigvals(lm.A - lm.B @ gain)).max() < 1  # stabilising


@pytest.mark.parametrize("convention", ["paper", "joint"])
def test_pd_cancels_gravity_and_is_critically_damped_at_each_joint(convention):
    """In joint coordinates the PD's torques are -(G + Kp) q - Kd dq with Kp, Kd diagonal, so
    the linear body's closed loop M q'' = -Kp q - Kd dq: Kd_i^2 = 4 M_ii Kp_i (critical
    damping) and Kp_i = M_ii w^2 with w twice the falling rate; both conventions give the same
    joint torques."""
    config = Config().replace(controller={"convention": convention})
    lm = linear_model(config.body, convention, config.scenario.control_dt)
    M_abs, G_abs, _ = mass_gravity_abs(config.body)
    M, G = S.T @ M_abs @ S, S.T @ G_abs @ S
    gain = law.pd(config).params["gain"]
    # joint torques of a joint state (q, dq): u = -gain x(q, dq), tau = torque_map u
    joint_gain = (
        lm.torque_map
        @ gain
        @ np.block(
            [
                [np.linalg.solve(lm.P, S), np.zeros((2, 2))],
                [np.zeros((2, 2)), np.linalg.solve(lm.P, S)],
            ]
        )
    )
    Kp, Kd = joint_gain[:, :2] - G, joint_gain[:, 2:]
    rate = np.sqrt(np.max(np.linalg.eigvals(np.linalg.solve(M, G)).real))
    bound = 1e-9 * np.abs(joint_gain).max()  # float64 rounding of the products above
    within(Kp, np.diag(np.diag(M) * (2 * rate) ** 2), atol=bound, why="float64 rounding")
    within(Kd**2, 4 * np.diag(np.diag(M)) * Kp, atol=bound * np.abs(Kd).max(), why="rounding")


def test_a_factory_function_is_recorded_by_its_import_name_and_a_lambda_refused():
    import law_examples

    from mjx_balance import api

    config = api.as_config(None, controller=law_examples.integral_lqr)
    assert config.controller.kind == "law_examples:integral_lqr"
    assert law.controller_of(config).law.name == "integral"
    with pytest.raises(ParameterError, match="module-level factory function"):
        api.as_config(None, controller=lambda config: law.lqr(config))


def test_compare_names_each_controller_and_crosses_configurations():
    from mjx_balance.studies.compare import with_controllers

    kinds = ["mpc", "lqr", "law_examples:integral_lqr"]
    one = with_controllers({"base": Config()}, kinds)
    assert list(one) == ["mpc", "lqr", "integral_lqr"]
    assert [c.controller.kind for c in one.values()] == kinds
    two = with_controllers({"a": Config(), "b": Config()}, ["mpc", "pd"])
    assert list(two) == ["a-mpc", "a-pd", "b-mpc", "b-pd"]


def test_the_shipped_policy_imitates_the_mpc_as_its_fit_reported(float32):
    """The MLP's input against the MPC's (OSQP, cold) at states drawn as the fit drew its box
    states (uniform within 2 x_scale of upright). docs/scripts/fit_policy.py printed, for its
    358 held-out box states, a median error of 2.0e-2 of each input's bound: 60 fresh draws
    (about 100 errors of solved QPs) are held to 1.5 times it, since a sample median of that
    many values scatters by about 15 % of it. (Not the largest error: the fit's tail is
    long, 0.17 at the 99th percentile, and a fresh draw's largest is not bounded by it.)"""
    import jax.numpy as jnp

    from mjx_balance.control import policy
    from mjx_balance.reference import loop as reference

    config = Config()
    made = policy.mlp(config)
    params = law.cast(made.params, jnp.float32)
    x_scale, u_scale = np.asarray(made.params["x_scale"]), np.asarray(made.params["u_scale"])
    mpc = reference.reference_mpc(config.controller, config.body, config.scenario.control_dt)
    rng = np.random.default_rng(1)
    errors = []
    for x in rng.uniform(-2, 2, size=(60, 4)) * x_scale:
        mpc.reset()
        u, _, ok, _ = mpc.solve(x)
        if ok:
            mine = np.asarray(policy.forward(params, jnp.asarray(x, jnp.float32)))
            errors.append(np.abs(mine - u) / u_scale)
    errors = np.array(errors)
    assert len(errors) >= 30  # most box states are solvable QPs
    assert np.median(errors) <= 1.5 * 2.0e-2, np.median(errors)


def test_a_policy_file_of_another_convention_or_shape_is_refused_in_one_line(tmp_path):
    from mjx_balance.control import policy

    with pytest.raises(ParameterError, match="fitted in the paper convention"):
        policy.mlp(Config().replace(controller={"convention": "joint"}))
    bad = tmp_path / "bad.npz"
    np.savez(bad, w0=np.zeros((2, 4)))
    with pytest.raises(ParameterError, match="expected x_scale"):
        policy.mlp(Config(), weights=str(bad))
    with pytest.raises(ParameterError, match="cannot be read"):
        policy.mlp(Config(), weights=str(tmp_path / "missing.npz"))


def test_compare_rows_name_the_controller_and_its_mean_settle_time():
    import pandas as pd

    from mjx_balance.studies.compare import mean_settle_time

    region = pd.DataFrame(
        {
            "force": [0.0, 10.0, 20.0],
            "duration": [0.1, 0.1, 0.1],
            "outcome": ["recovered", "recovered", "fell"],
            "settle_time": [0.0, 0.8, float("nan")],
        }
    )
    assert mean_settle_time(region) == 0.4  # the recovered cells' mean; the fall left out
    assert np.isnan(mean_settle_time(region[region.outcome == "fell"]))
