"""CoM velocity, extrapolated CoM and margin of stability (docs/model.md, "CoM velocity and the
margin of stability"; Hof et al. 2005): the formulas on hand-worked states in every path's
implementation, the margin at rest and before a fall, and the batched engine's lean sampling
against the reference."""

import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from margins import within
from support import ENGINE_SLOTS

from mjx_balance.measures import metrics, outcomes
from mjx_balance.model.mjcf import build_model, indices
from mjx_balance.model.params import Config
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import physics, sensing

CONFIG = Config().replace(scenario={"t_end": 2.0})
BODY = CONFIG.body
# The default body by hand (docs/model.md, "Body"): the ankle axis at the foot frame's origin
# (ankle_height 0), the foot's CoM 0.01 m above it (half its thickness), the lower body's
# 0.5 m, the upper body's 1.0 + 0.3 = 1.3 m; the hip axis 1.0 m above the ankle.
MASS = 1.3 + 30.0 + 35.0
L_HAND = (1.3 * 0.01 + 30.0 * 0.5 + 35.0 * 1.3) / MASS  # 0.912715 m
V_PER_ANKLE = (30.0 * 0.5 + 35.0 * 1.3) / MASS  # m/s of CoM per rad/s of ankle: 0.912519
V_PER_HIP = 35.0 * (1.3 - 1.0) / MASS  # 0.158371


def test_margin_formula_by_hand():
    """XcoM = x + v / omega0, toe margin toe - XcoM, heel margin XcoM - heel, on numbers worked
    by hand: x = 0.02 m, v = 0.3 m/s, l = 0.9 m, g = 9.81 m/s^2 -> omega0 = sqrt(10.9) =
    3.301515 /s, v / omega0 = 0.090867 m, XcoM = 0.110867 m; feet edges -0.15, 0.15 m."""
    omega0 = math.sqrt(9.81 / 0.9)
    xcom, toe, heel = outcomes.stability_margins(
        np, np.array(0.02), np.array(0.3), np.array(-0.15), np.array(0.15), omega0
    )
    within(
        [xcom, toe, heel],
        [0.110867, 0.039133, 0.260867],
        atol=1e-6,
        why="six-digit hand arithmetic",
    )
    # backwards: x = -0.02, v = -0.3 mirrors it (the heel margin is the toe margin's mirror)
    xcom_b, toe_b, heel_b = outcomes.stability_margins(np, -0.02, -0.3, -0.15, 0.15, omega0)
    within(
        [xcom_b, toe_b, heel_b],
        [-0.110867, 0.260867, 0.039133],
        atol=1e-6,
        why="six-digit hand arithmetic",
    )
    # the edges: the back pair's smallest x, the front pair's largest (model.LOAD_CELLS order:
    # front left, front right, back left, back right)
    heel_x, toe_x = outcomes.support_edges(np, np.array([0.14, 0.15, -0.15, -0.14]))
    assert (heel_x, toe_x) == (-0.15, 0.15)


def _rest_model():
    model = build_model(BODY, CONFIG.scenario.physics_dt)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, indices(model)


def _qvel(model, ix) -> np.ndarray:
    """qvel with the ankle at 1 rad/s, the hip at -2 rad/s and the foot sliding at 0.1 m/s:
    by hand v_com = 0.912519 - 2 x 0.158371 + 0.1 = 0.695777 m/s."""
    qvel = np.zeros(model.nv)
    foot_x = model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "foot_x")]
    qvel[ix.ankle_dof], qvel[ix.hip_dof], qvel[foot_x] = 1.0, -2.0, 0.1
    return qvel


def test_com_velocity_and_pendulum_by_hand():
    """At upright rest each joint moves the CoM by its lever: an ankle rate w moves the lower
    and upper bodies' CoMs (0.5 m, 1.3 m above the axis) at 0.5 w and 1.3 w forward; the hip
    the upper body's at 0.3 w; the foot's slide all of it. The reference (float64 CoM
    Jacobian) and the batched kernel (float32, joint axes and anchors) both give it, and the
    pendulum length l is the CoM's height above the ankle."""
    within(V_PER_ANKLE - 2 * V_PER_HIP + 0.1, 0.695777, atol=1e-6, why="hand arithmetic")
    model, data, ix = _rest_model()
    data.qvel[:] = _qvel(model, ix)
    within(
        metrics.com_velocity(model, data, ix.foot_body),
        0.695777,
        atol=1e-6,
        why="six-digit hand arithmetic (float64 Jacobian)",
    )
    omega0 = metrics.pendulum_frequency(model, ix.foot_body, ix.ankle_dof)
    within(BODY.gravity / omega0**2, L_HAND, rtol=1e-9, why="float64 kinematics")
    within(L_HAND, 0.912715, atol=1e-6, why="six-digit hand arithmetic")

    mjm = physics.mj_model(CONFIG)
    with jax.enable_x64(False):
        d0 = physics.rest_data(mjm)
        sn = sensing.sensors(mjm, d0)
        mx = physics.mjx_model(mjm)
        v = sensing.com_velocity(mx, d0, sn, jnp.asarray(_qvel(mjm, indices(mjm)), jnp.float32))
        ar = SimpleNamespace(mx=mx, d0=d0)
        w = float(sensing.pendulum_frequency(ar, sn))
    # float32: the levers (<= 1.3 m) and masses rounded (eps 1.2e-7 relative each), a 5-term
    # sum: 10 eps of the 0.7 m/s result and its terms (<= 1.2 m/s) is < 2e-6
    within(
        float(v),
        0.695777,
        atol=2e-6 + 1e-6,
        why="float32 rounding of a 5-term Jacobian product (comment) plus 6-digit hand value",
    )
    within(
        w,
        math.sqrt(BODY.gravity / L_HAND),
        rtol=1e-5,
        why="float32 CoM height and a square root (a few eps)",
    )


@pytest.fixture(scope="module")
def runs():
    """Reference (OSQP) runs: rest, a push it recovers from, a forward and a backward push
    that fall."""
    return {
        key: reference.simulate_scenario(CONFIG, *key)
        for key in ((0.0, 0.1), (50.0, 0.1), (140.0, 0.1), (-150.0, 0.3))
    }


def test_margin_at_rest_is_half_the_foot(runs):
    """No push: XcoM stays over the ankle and the margin is the toe cells' distance, half the
    cells' span (foot_length / 2 = 0.15 m)."""
    summary, frame = runs[(0.0, 0.1)]
    within(
        frame["mos"].to_numpy(),
        BODY.foot_length / 2,
        atol=1e-6,
        why="rest: the contact solve's jitter moves the CoM by far less than 1 um",
    )
    within(summary["mos_min"], BODY.foot_length / 2, atol=1e-6, why="the same")
    within(
        [summary["com_vel_min"], summary["com_vel_max"]],
        [0.0, 0.0],
        atol=1e-6,
        why="rest: no motion beyond the contact solve's jitter",
    )
    # the time series' columns follow the definition: xcom = com + com_vel / omega0 with
    # omega0 = sqrt(g / l) from the hand-worked l
    xcom = frame["com"] + frame["com_vel"] / math.sqrt(BODY.gravity / L_HAND)
    within(frame["xcom"].to_numpy(), xcom.to_numpy(), atol=1e-12, why="float64 round-off")


@pytest.mark.parametrize("force,duration,edge", [(140.0, 0.1, "toe"), (-150.0, 0.3, "heel")])
def test_margin_falls_below_zero_before_a_fall(runs, force, duration, edge):
    """A push the body does not survive drives the XcoM past the foot's edge in the push's
    direction (toe for forward, heel for backward) at or before the fall sample."""
    summary, frame = runs[(force, duration)]
    assert summary["outcome"] == "fell"
    fall = summary["fall_time"]
    negative = frame.loc[frame["mos"] < 0, "time"]
    assert len(negative) and negative.iloc[0] <= fall + 1e-12
    print(
        f"{force} N x {duration} s: MoS < 0 from {negative.iloc[0]:.3f} s, fall at "
        f"{fall:.3f} s ({summary['fall_cause']}); mos_min {summary['mos_min']:.4f} m at "
        f"{summary['mos_min_time']:.3f} s; com_vel [{summary['com_vel_min']:.3f}, "
        f"{summary['com_vel_max']:.3f}] m/s"
    )
    assert summary["mos_min"] < 0 and summary["mos_min_time"] <= fall + 1e-12
    # the margin is the push direction's edge, which moves with the foot: by its slide foot_x
    # and, turned by its pitch about the sole's centre, by at most its 0.15 m half-length (plus
    # the cells' 5 mm radius) times |pitch|
    margin = (
        BODY.foot_length / 2 - frame["xcom"]
        if edge == "toe"
        else frame["xcom"] + BODY.foot_length / 2
    )
    moved = frame["foot_x"].abs() + (BODY.foot_length / 2 + 0.005) * frame["foot_pitch"].abs()
    assert (np.abs(frame["mos"] - margin) <= moved + 1e-9).all()


# the engine at full length over every case; the by-hand measures stay in the default run
@pytest.mark.slow
def test_batched_lean_sampling_agrees_with_the_reference(runs):
    """The batched engine without trajectories (the sweeps' path) reads a sample's positions
    from the next step's start and its rates from the sample itself: its CoM velocity and
    margin agree with the reference as test_rollout's summaries do, and its falls pass the toe
    edge too (the batched ADMM's falls differ from OSQP's after the first infeasible QP,
    docs/model.md, so only the sign is compared there)."""
    from mjx_balance.rollout import BatchRunner

    keys = list(runs)
    forces, durations = np.array(keys).T
    with jax.enable_x64(False):
        runner = BatchRunner(
            CONFIG, early_stop=False, slots=ENGINE_SLOTS, devices=jax.local_devices()[:1]
        )
        assert not runner.trajectories
        mine = runner.run(forces, durations)
    rest = BODY.foot_length / 2
    for b, key in enumerate(keys):
        ref = runs[key][0]
        print(
            f"{key}: mos_min {mine['mos_min'][b]:.6f} vs {ref['mos_min']:.6f} at "
            f"{mine['mos_min_time'][b]:.3f} vs {ref['mos_min_time']:.3f} s; com_vel "
            f"[{mine['com_vel_min'][b]:.5f}, {mine['com_vel_max'][b]:.5f}] vs "
            f"[{ref['com_vel_min']:.5f}, {ref['com_vel_max']:.5f}]"
        )
        if ref["outcome"] == "fell":
            assert mine["mos_min"][b] < 0
            assert mine["mos_min_time"][b] <= mine["fall_time"][b] + 1e-9
            continue
        for name in ("com_vel_min", "com_vel_max"):
            within(
                mine[name][b],
                ref[name],
                rtol=0.05,
                atol=1e-4,
                msg=(key, name),
                why="ADMM (eps 1e-4 scaled) vs OSQP (1e-8) and float32 contacts "
                "(test_rollout's recovered-run rule)",
            )
        within(
            rest - mine["mos_min"][b],
            rest - ref["mos_min"],
            rtol=0.05,
            atol=1e-4,
            msg=key,
            why="the same rule, on the margin's dip from rest",
        )
