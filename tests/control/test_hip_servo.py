"""The hip servo (BodyParams.hip_servo_*): a stiff passive spring-damper at the hip, so that the
hip motor can be switched off (the ankle-only study, sweeps/study_ankle_only.toml).

The servo is part of the plant: MuJoCo's joint stiffness and damping in the generated model
(mj_step integrates the damping implicitly, Euler with eulerdamp), the same in the batched MJX
rollout (which keeps those flags on for a model that has them), and exactly in the linear model
(tests/model/test_linear.py). K and D are the study's (see its TOML file for their derivation).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from margins import within

from mjx_balance import rollout
from mjx_balance.measures.outcomes import OUTCOMES
from mjx_balance.model.mjcf import build_model, indices, mjcf
from mjx_balance.model.params import BodyParams, Config, ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.runs import load_sweep
from mjx_balance.studies.catalog import sweeps_dir

STUDY = load_sweep(sweeps_dir() / "study_ankle_only.toml", Config()).config
K, D = STUDY.body.hip_servo_stiffness, STUDY.body.hip_servo_damping
# Static bound on the hip load over the study's grid (150 N at the upper CoM, 0.3 m above the
# hip, plus the upper body's gravity moment 103 N m/rad at 0.26 rad): ~72 N m.
HIP_LOAD_BOUND = 150.0 * 0.3 + 35.0 * 9.81 * 0.3 * 0.26  # N m


def test_study_uses_the_servo_with_the_hip_motor_off():
    assert K > 0 and D > 0
    assert STUDY.controller.input2_bounds == (0.0, 0.0)
    assert HIP_LOAD_BOUND / K < 5e-3  # a few milliradians at most


def test_servo_parameters_validated_and_default_model_unchanged():
    for name in ("hip_servo_stiffness", "hip_servo_damping"):
        with pytest.raises(ParameterError, match=name):
            BodyParams(**{name: -1.0})
        with pytest.raises(ParameterError, match=name):
            BodyParams(**{name: float("inf")})
    assert "stiffness" not in mjcf(BodyParams()) and "damping" not in mjcf(BodyParams())
    model = build_model(STUDY.body)
    hip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "hip")
    assert model.jnt_stiffness[hip] == K and model.dof_damping[model.jnt_dofadr[hip]] == D
    assert model.qpos_spring[model.jnt_qposadr[hip]] == 0.0
    # the batched rollout's model keeps exactly the servo's flags on, the default's off
    servo_flags = rollout.mj_model(STUDY).opt.disableflags
    default_flags = rollout.mj_model(Config()).opt.disableflags
    keep = (
        mujoco.mjtDisableBit.mjDSBL_EULERDAMP
        | mujoco.mjtDisableBit.mjDSBL_SPRING
        | mujoco.mjtDisableBit.mjDSBL_DAMPER
    )
    assert servo_flags & keep == 0 and default_flags & keep == keep
    assert servo_flags | keep == default_flags


@pytest.mark.parametrize("convention", ["joint", "paper"])
def test_reference_hip_held_by_the_servo_while_the_ankle_works(convention):
    """A 30 N, 0.1 s push (joint: recovered by 3 s); over the first 1.5 s the hip motor does
    nothing and the hip stays within the servo's static deflection bound while the ankle
    torque and the lean are clearly non-zero."""
    config = STUDY.replace(controller={"convention": convention}, scenario={"t_end": 3.0})
    summary, series = reference.simulate_scenario(config, 30.0, 0.1)
    first = series[series.time <= 1.5]
    assert np.abs(series["tau_hip"]).max() == 0.0 and summary["energy_hip"] == 0.0
    within(
        first["q_h"],
        0.0,
        atol=HIP_LOAD_BOUND / K,
        why="the servo's static deflection: the hip load bound over the stiffness",
    )
    assert np.abs(first["q_a"]).max() > 5e-3  # the push does lean the body
    assert np.abs(first["tau_ankle"]).max() > 5.0  # and the ankle works against it
    if convention == "joint":
        assert summary["outcome"] == "recovered"
        assert summary["peak_hip"] < 0.1 * summary["peak_ankle"]


# the servo body's own engine compile; the reference servo tests stay in the default run
@pytest.mark.slow
def test_batched_matches_reference_on_servo_body(float32):
    """MJX (float32, springs/dampers/implicit Euler damping on) + ADMM vs mj_step + OSQP.

    Its own compile: the servo body's model keeps other MJX flags on and the hip input's bounds
    (0, 0) are among the outcome rules' static thresholds, so the session's shared runner
    (conftest ``batch_runner``) cannot serve it."""
    config = STUDY.replace(controller={"convention": "joint"}, scenario={"t_end": 1.5})
    runner = rollout.BatchRunner(config, trajectories=True)
    forces, durations = np.array([0.0, 30.0, 50.0]), np.full(3, 0.1)
    summary = runner.run(forces, durations)
    ix = indices(runner.model)
    for b, force in enumerate(forces):
        ref, series = reference.simulate_scenario(config, force, durations[b])
        assert OUTCOMES[summary["outcome"][b]] == ref["outcome"]
        n = len(series)
        q = runner.last_trajectories["qpos"][b, :n][:, [ix.ankle_qpos, ix.hip_qpos]]
        diff = np.abs(q - series[["q_a", "q_h"]].to_numpy()).max(axis=0)
        print(f"\nservo body, F = {force} N: {ref['outcome']}, max |q_a, q_h diff| {diff} rad")
        within(
            q,
            series[["q_a", "q_h"]].to_numpy(),
            atol=5e-3,
            msg=force,
            why="the closed loop's agreement with the reference (test_rollout.ANGLE_TOL)",
        )


@pytest.mark.parametrize("convention", ["paper", "joint"])
def test_terminal_weight_uses_only_inputs_that_can_act(convention):
    """With the hip motor off, Q_f is the DARE of the ankle input alone, and the unconstrained
    MPC (first move of the condensed QP with u2 = 0) is a stable closed loop; with both motors
    on Q_f is the plain DARE of (A, B, Q, R)."""
    import scipy.linalg

    from mjx_balance.control.qp import build_qp
    from mjx_balance.model.params import Config

    servo = Config().replace(
        body={"hip_servo_stiffness": 2e4, "hip_servo_damping": 580.0},
        controller={"convention": convention, "input2_bounds": [0.0, 0.0]},
    )
    qp = build_qp(servo.controller, servo.body, servo.scenario.control_dt)
    lm = qp.linear
    Q, R = np.diag(servo.controller.q_diag), np.diag(servo.controller.r_diag)
    np.testing.assert_allclose(
        qp.Qf, scipy.linalg.solve_discrete_are(lm.A, lm.B[:, :1], Q, R[:1, :1]), rtol=1e-10
    )
    ankle = np.arange(0, qp.n, 2)
    gain = -np.linalg.solve(qp.H[np.ix_(ankle, ankle)], qp.F[ankle])[0]
    closed = lm.A + lm.B[:, :1] @ gain[None]
    assert max(abs(np.linalg.eigvals(closed))) < 1.0

    both = Config().replace(controller={"convention": convention})
    qp_both = build_qp(both.controller, both.body, both.scenario.control_dt)
    np.testing.assert_allclose(
        qp_both.Qf,
        scipy.linalg.solve_discrete_are(qp_both.linear.A, qp_both.linear.B, Q, R),
        rtol=1e-10,
    )
