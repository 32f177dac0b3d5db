"""Linear model vs MuJoCo: finite differences, ZOH discretisation, the CoP map under a held lean."""

import mujoco
import numpy as np
import pytest
import scipy.signal
from margins import within

from mjx_balance.model.linear import S, linear_model
from mjx_balance.model.mjcf import build_model
from mjx_balance.model.params import BodyParams, Config
from mjx_balance.reference.loop import simulate_scenario

CONVENTIONS = ("paper", "joint")


def fd_joint_jacobians(
    body: BodyParams, h: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Central differences of mj_forward's qacc on the fixed-foot model at upright rest.

    Returns (dqacc/dq [2, 2], dqacc/ddq [2, 2], dqacc/dctrl [2, 2]) in joint coordinates.
    """
    model = build_model(body, foot="fixed")
    data = mujoco.MjData(model)
    assert model.nq == 2 and model.nu == 2

    def qacc(q, dq, ctrl):
        data.qpos[:], data.qvel[:], data.ctrl[:] = q, dq, ctrl
        mujoco.mj_forward(model, data)
        return data.qacc.copy()

    zero = np.zeros(2)
    jac = []
    for slot in range(3):
        cols = []
        for j in range(2):
            step = np.zeros(2)
            step[j] = h
            args_p = [zero, zero, zero]
            args_m = [zero, zero, zero]
            args_p[slot], args_m[slot] = step, -step
            cols.append((qacc(*args_p) - qacc(*args_m)) / (2 * h))
        jac.append(np.array(cols).T)
    return tuple(jac)


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize(
    "body",
    [
        BodyParams(),
        BodyParams(lower_mass=40.0, upper_length=0.8, upper_com=0.35),
        BodyParams(hip_servo_stiffness=2.0e4, hip_servo_damping=580.0),
    ],
    ids=["default", "scaled", "hip_servo"],
)
def test_linearisation_matches_finite_differences(convention, body):
    """mj_forward's qacc includes the joint spring and damper (passive forces), so the servo
    body checks the stiffness and the velocity (damping) block of Ac as well."""
    lm = linear_model(body, convention, 0.01)
    d_q, d_dq, d_ctrl = fd_joint_jacobians(body)
    # convention coordinates y = T q with T = P^-1 S; inputs ctrl = torque_map u
    T = np.linalg.solve(lm.P, S)
    Tinv = np.linalg.inv(T)
    Ac_fd = np.block([[np.zeros((2, 2)), np.eye(2)], [T @ d_q @ Tinv, T @ d_dq @ Tinv]])
    Bc_fd = np.vstack([np.zeros((2, 2)), T @ d_ctrl @ lm.torque_map])
    why = (
        "central differences, h = 1e-6: truncation h^2 |third derivative| / 6 and "
        "cancellation eps_float64 |qacc| / h, both below 1e-9 relative"
    )
    within(rel_err(lm.Ac[2:], Ac_fd[2:]), 0.0, atol=1e-5, why=why)
    within(rel_err(lm.Bc[2:], Bc_fd[2:]), 0.0, atol=1e-5, why=why)
    np.testing.assert_array_equal(lm.Ac[:2], Ac_fd[:2])
    np.testing.assert_array_equal(lm.Bc[:2], Bc_fd[:2])


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_zoh_matches_scipy(convention):
    lm = linear_model(BodyParams(), convention, 0.01)
    A, B, *_ = scipy.signal.cont2discrete(
        (lm.Ac, lm.Bc, np.eye(4), np.zeros((4, 2))), 0.01, method="zoh"
    )
    np.testing.assert_allclose(lm.A, A, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lm.B, B, rtol=1e-12, atol=1e-12)


def test_zoh_matches_fine_euler():
    lm = linear_model(BodyParams(), "paper", 0.01)
    x0 = np.array([0.02, -0.01, 0.1, 0.05])
    u = np.array([3.0, -5.0])
    n = 20000
    h = 0.01 / n
    x = x0.copy()
    for _ in range(n):
        x = x + h * (lm.Ac @ x + lm.Bc @ u)
    np.testing.assert_allclose(lm.A @ x0 + lm.B @ u, x, rtol=1e-4, atol=1e-9)


def test_state_and_torque_maps():
    q, dq = np.array([0.1, 0.2]), np.array([-0.3, 0.4])
    paper = linear_model(BodyParams(), "paper", 0.01)
    joint = linear_model(BodyParams(), "joint", 0.01)
    np.testing.assert_allclose(paper.state_from_joints(q, dq), [0.1, 0.3, -0.3, 0.1])
    np.testing.assert_allclose(joint.state_from_joints(q, dq), [0.1, 0.2, -0.3, 0.4])
    np.testing.assert_allclose(paper.motor_torques(np.array([2.0, 5.0])), [7.0, 5.0])
    np.testing.assert_allclose(joint.motor_torques(np.array([2.0, 5.0])), [2.0, 5.0])


@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize("push", [5.0, -5.0])
def test_linear_cop_map_matches_load_cells(convention, push):
    """The MPC holds the body leaning against a steady push (the push lasts the whole run).

    Without integral action the controller settles at an offset lean whose holding ankle torque
    balances gravity and the push; the load-cell CoP then has to match the linear CoP map at
    the applied input. The measured CoP is in world x while the map is relative to the ankle,
    and under a steady push the foot creeps forward on MuJoCo's soft friction (~0.1 mm/s), so
    the foot's x is subtracted. Tolerance 10 um: in statics with the ankle at sole height the
    map -tau_ankle / Fz is exact; what remains is soft-contact geometry (the sole sinks ~0.3 mm
    and pitches ~2e-4 rad on the compliant contacts), observed ~1.3 um.
    """
    config = Config().replace(controller={"convention": convention}, scenario={"t_end": 1.5})
    _, frame = simulate_scenario(config, push, 1.5)
    last = frame.iloc[-1]
    assert abs(last.dq_a) < 0.01 and abs(last.dq_h) < 0.02  # held (slow drift only)
    assert np.sign(last.q_a) == np.sign(push) and abs(last.q_a) > 0.005  # visibly leaning
    lm = linear_model(config.body, convention, config.scenario.control_dt)
    x = last[["x1", "x2", "x3", "x4"]].to_numpy(float)
    u = last[["u1", "u2"]].to_numpy(float)
    cop_linear = lm.cop_x @ x + lm.cop_u @ u
    assert abs(last.cop) > 0.015  # the lean moves the CoP measurably
    within(
        last.cop - last.foot_x,
        cop_linear,
        atol=1e-5,
        why="the map is exact in statics; the compliant contacts' geometry (sole sinking "
        "~0.3 mm, pitching ~2e-4 rad) moves the CoP by ~1 um",
    )
