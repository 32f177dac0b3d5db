"""Scenario features of the reference loop: sensorimotor delay and push height.

controller_delay = D: the controller at t_k sees the joint state of t_k - D (the rest state
before t = 0); the plant runs on. push_body = "hip": the push force acts at the hip joint point
instead of the upper body's CoM.
"""

import mujoco
import numpy as np
import pytest
from margins import within

from mjx_balance.control.osqp_mpc import ReferenceMPC
from mjx_balance.control.qp import build_qp
from mjx_balance.model.mjcf import build_model, indices
from mjx_balance.model.params import Config
from mjx_balance.reference.loop import push_wrench, simulate_scenario

SHORT = {"t_end": 1.0}


def _run(force=40.0, duration=0.1, **scenario):
    return simulate_scenario(Config().replace(scenario={**SHORT, **scenario}), force, duration)


def test_zero_delay_is_the_undelayed_loop():
    base_summary, base = _run()
    summary, frame = _run(controller_delay=0.0)
    np.testing.assert_array_equal(
        frame[["q_a", "q_h", "tau_ankle", "tau_hip"]].to_numpy(),
        base[["q_a", "q_h", "tau_ankle", "tau_hip"]].to_numpy(),
    )
    assert summary["energy_total"] == base_summary["energy_total"]


@pytest.mark.parametrize("delay", [0.02, 0.05])
def test_delayed_controller_responds_later(delay):
    """Until t_k >= D the controller sees the rest state, so its torque is (numerically) zero;
    the undelayed controller reacts at the first control instant after push onset."""
    _, base = _run()
    _, frame = _run(controller_delay=delay)
    control_dt, dt = 0.01, 0.002
    first_base = base.time[base.tau_hip.abs() > 1e-3].min()
    first_delayed = frame.time[frame.tau_hip.abs() > 1e-3].min()
    assert first_base == pytest.approx(control_dt + dt)  # torque of t_1 = 0.01, sampled at +dt
    # t_k - D must be > 0: first reacting instant k = D / control_dt + 1
    assert first_delayed == pytest.approx(delay + control_dt + dt)
    # the plant ran on meanwhile: same push, no torque, so the same motion as without control
    assert (frame.time <= delay).sum() == round(delay / dt)
    assert not np.allclose(frame.q_a.to_numpy()[-100:], base.q_a.to_numpy()[-100:])


def test_delayed_measurement_is_the_state_of_t_minus_delay():
    """Replaying the delayed run: the input at t_k is the MPC's answer to the recorded joint
    state of t_k - D (OSQP at eps 1e-8, a feasible push, so warm starts do not matter)."""
    delay, dt = 0.03, 0.002
    config = Config().replace(scenario={**SHORT, "controller_delay": delay})
    _, frame = simulate_scenario(config, 20.0, 0.1)
    mpc = ReferenceMPC(build_qp(config.controller, config.body, 0.01), config.controller)
    lm = mpc.qp.linear
    samples = frame.set_index(np.round(frame.time / dt).astype(int))
    for k in range(0, 60):
        u_recorded = samples.loc[k * 5 + 1, ["u1", "u2"]].to_numpy(float)  # held over t_k..
        s = k * 5 - round(delay / dt)
        if s <= 0:
            q, dq = np.zeros(2), np.zeros(2)
        else:
            q = samples.loc[s, ["q_a", "q_h"]].to_numpy(float)
            dq = samples.loc[s, ["dq_a", "dq_h"]].to_numpy(float)
        u, _, ok, _ = mpc.solve(lm.state_from_joints(q, dq))
        assert ok
        np.testing.assert_allclose(u, u_recorded, atol=1e-4 * max(1.0, np.abs(u).max()))


def test_push_wrench_acts_at_the_chosen_point():
    """xfrc_applied is applied at the body's CoM; the hip wrench must equal the force applied
    at the hip point (on the upper or the lower body), and exert no hip joint torque."""
    model = build_model()
    ix = indices(model)
    data = mujoco.MjData(model)
    data.qpos[[ix.ankle_qpos, ix.hip_qpos, ix.foot_pitch]] = [0.2, 0.5, 0.01]
    mujoco.mj_forward(model, data)
    F = 75.0
    force = np.array([F, 0.0, 0.0])
    hip_point = data.xpos[ix.upper_body].copy()
    lower_frame = data.xmat[ix.lower_body].reshape(3, 3)
    lower_hip_point = data.xpos[ix.lower_body] + lower_frame @ [0, 0, 1.0]  # top of the rod
    np.testing.assert_allclose(hip_point, lower_hip_point, atol=1e-12)

    def generalised(wrench):  # what MuJoCo does with xfrc_applied (at xipos)
        out = np.zeros(model.nv)
        mujoco.mj_applyFT(
            model, data, wrench[:3], wrench[3:], data.xipos[ix.upper_body], ix.upper_body, out
        )
        return out

    def at_point(point, body):
        out = np.zeros(model.nv)
        mujoco.mj_applyFT(model, data, force, np.zeros(3), point, body, out)
        return out

    upper = push_wrench(data, ix.upper_body, F, "upper")
    np.testing.assert_array_equal(upper, [F, 0, 0, 0, 0, 0])
    hip = push_wrench(data, ix.upper_body, F, "hip")
    np.testing.assert_allclose(hip[:3], force)
    np.testing.assert_allclose(generalised(hip), at_point(hip_point, ix.upper_body), atol=1e-9)
    np.testing.assert_allclose(generalised(hip), at_point(hip_point, ix.lower_body), atol=1e-9)
    within(
        generalised(hip)[ix.hip_dof],
        0.0,
        atol=1e-9,
        why="a force through the hip joint has no hip moment: float64 round-off of 75 N x ~1 m",
    )
    assert abs(generalised(upper)[ix.hip_dof]) > 1.0  # at the CoM it does turn the hip
    with pytest.raises(ValueError):
        push_wrench(data, ix.upper_body, F, "head")


def test_hip_push_changes_the_response():
    upper_summary, upper = _run(force=60.0)
    hip_summary, hip = _run(force=60.0, push_body="hip")
    # through the hip axis the push does not flex the hip directly: less hip flexion
    assert hip_summary["peak_hip"] < upper_summary["peak_hip"]
    assert hip_summary["peak_ankle"] != upper_summary["peak_ankle"]
    assert not np.allclose(hip.q_h.to_numpy()[:100], upper.q_h.to_numpy()[:100])
