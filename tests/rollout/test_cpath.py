"""The MuJoCo C physics path (rollout/cpath.py): its measurements, its agreement with the scalar
reference and with the MJX path, and that no result depends on threads, slots or order.

The C path runs the reference's physics (the same MJCF, MuJoCo's default solver options,
float64) and the batched path's controller, so against the reference run with that controller
(``AdmmMPC``) it is the same closed loop up to round-off: the float32 torque map, the contact
solver's warm start recovered from two velocities, and the last sample of each period read from
float32 kinematics. Tolerances below are set from those, not from what a run happened to give.
"""

import jax
import margins
import mujoco
import numpy as np
import pytest
from margins import within
from support import CERTIFIED_INTEGRALS, AdmmMPC, assert_certified_like_full_length

from mjx_balance.control.certificate import PITCH_PER_COP
from mjx_balance.measures import metrics, outcomes
from mjx_balance.model.mjcf import build_model, indices
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner, cpath
from mjx_balance.runs.batch import LazyBatch, resume_engine

CONFIG = Config().replace(scenario={"t_end": 2.0})
# recovered (0, 20 N), falls by several rules (heel/toe lift, state bound), and not settled (a
# push that ends at t_end): every outcome but divergence, which
# test_a_reset_simulation_is_divergence covers
CELLS = [
    (0.0, 0.1),
    (20.0, 0.1),
    (50.0, 0.3),
    (150.0, 0.1),
    (200.0, 0.1),
    (-150.0, 0.3),
    (80.0, 0.5),
    (8.0, 2.0),
]


pytestmark = pytest.mark.usefixtures("float32_module")  # x64 off (conftest)


@pytest.fixture(scope="module")
def c_runner():
    """The C path for CONFIG on one JAX device, 4 slots, 2 MuJoCo threads (compiled once)."""
    runner = BatchRunner(
        CONFIG, physics="c", slots=4, threads=2, early_stop=False, devices=jax.local_devices()[:1]
    )
    runner.prepare()
    return runner


@pytest.fixture(scope="module")
def c_frame(c_runner):
    forces, durations = np.array(CELLS).T
    return c_runner.run_frame(forces, durations)


def test_sensors_and_warm_start_reproduce_mj_step():
    """Advancing with ``mujoco.rollout`` period by period (sensors, recovered warm start) gives
    the states and samples that a plain ``mj_step`` loop with the reference's readings gives."""
    c = cpath.CPhysics(CONFIG, threads=2)
    model = build_model(CONFIG.body, CONFIG.scenario.physics_dt)  # the reference's model
    ix = indices(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    S, periods = c.substeps, 60
    torques = np.array([-4.0, 1.5])
    push = np.full((1, S), 60.0)
    state, warm = c.rest[None].copy(), c.rest_warm[None].copy()
    worst = 0.0
    for k in range(periods):
        f = push if k < 20 else 0 * push
        states, sens = c.advance(state, warm, torques[None], f)
        rows, last_q = c.samples(states, sens)
        for j in range(S):
            data.ctrl[:] = torques
            data.xfrc_applied[ix.upper_body, 0] = f[0, j]
            mujoco.mj_step(model, data)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            q = data.qpos[[ix.ankle_qpos, ix.hip_qpos]]
            worst = max(worst, np.abs(rows[0, j, cpath.Q] - q).max())
            cop = metrics.load_cell_cop(model, data, ix.cell_geoms)[0]
            within(
                rows[0, j, cpath.COP],
                cop,
                rtol=1e-6,
                atol=1e-9,
                msg=(k, j),
                why="the same contact solve from warm starts that differ by round-off, "
                "each converged to MuJoCo's solver tolerance (1e-8)",
            )
            if j < S - 1:  # the last sample's positions come from the next call's kinematics
                np.testing.assert_allclose(
                    rows[0, j, cpath.CELLS],
                    metrics.cell_heights(model, data, ix.cell_geoms),
                    atol=1e-9,
                )
                within(
                    rows[0, j, cpath.COM],
                    metrics.whole_body_com(data, ix.foot_body),
                    atol=1e-9,
                    why="the same float64 kinematics of states equal to ~1e-9",
                )
                within(
                    rows[0, j, cpath.VCOM],
                    metrics.com_velocity(model, data, ix.foot_body),
                    atol=1e-8,
                    msg=(k, j),
                    why="the same float64 CoM velocity (subtree momentum vs CoM Jacobian "
                    "x qvel) of states equal to ~1e-9, rates through the contact "
                    "solve's tolerance (1e-8)",
                )
                heel, toe = outcomes.support_edges(np, metrics.cell_x(data, ix.cell_geoms))
                within(
                    rows[0, j, [cpath.HEEL, cpath.TOE]],
                    [heel, toe],
                    atol=1e-9,
                    why="the same float64 kinematics of states equal to ~1e-9",
                )
            within(
                rows[0, j, cpath.QVEL],
                data.qvel,
                atol=1e-8,
                msg=(k, j),
                why="the same physics; rates through the contact solve's tolerance (1e-8)",
            )
            assert rows[0, j, cpath.OK] == 1
        np.testing.assert_allclose(last_q[0], data.qpos, atol=1e-9)
        warm = c.next_warm(state, states)
        state = states[:, -1].copy()
        state[:, 0] = cpath.TIME0
    # the same physics from the same states: only the warm start differs (by round-off), and
    # the contact solver converges to its tolerance from either
    within(
        worst,
        0.0,
        atol=1e-9,
        why="the same float64 physics; the contact solver's tolerance (1e-8 on forces) "
        "moves positions by far less in 60 periods",
    )


def test_a_reset_simulation_is_divergence():
    """MuJoCo resets a simulation that meets a huge value; every sample from there is marked
    not OK (the kernel then reports divergence, as the reference does on MuJoCo's warning)."""
    c = cpath.CPhysics(CONFIG, threads=1)
    states, sens = c.advance(
        c.rest[None], c.rest_warm[None], np.zeros((1, 2)), np.full((1, c.substeps), 1e30)
    )
    rows, _ = c.samples(states, sens)
    assert not rows[0, :, cpath.OK].any()
    ok_states, ok_sens = c.advance(
        c.rest[None], c.rest_warm[None], np.zeros((1, 2)), np.full((1, c.substeps), 100.0)
    )
    assert c.samples(ok_states, ok_sens)[0][0, :, cpath.OK].all()


def test_c_path_matches_the_reference(c_runner, c_frame):
    """With the batched ADMM as the reference's controller, the C path is the reference's closed
    loop: the same outcome, fall rule and fall sample, and summaries equal to round-off grown
    over 2 s of closed loop.

    The round-off that differs: the float32 ADMM compiled for 4 slots here and for 1 in the
    reference sums its products in other orders (and other CPUs in others again), so each
    period's inputs differ by up to margins.admm_rounding (1.9e-3 relative, no credit for the
    ADMM's contraction); the stable loop turns that into at most margins.input_gains times as
    much in a summary column (0.9-3.3 for these pushes, linear model), and a fall grows it by
    exp(lambda_max x (fall - first infeasible QP)) (margins.closed_loop_rounding). The float32
    torque map (2 eps) and the contact solver's recovered warm start (1e-9, above) are far
    below that; the period's last sample takes its positions (the CoM) from float32 kinematics
    (margins.kinematics_rounding). Measured on a 2-core AMD EPYC: up to 1.1e-5 relative on the
    energies of runs that do not fall (docs/reliability.md, margin audit)."""
    mpc = AdmmMPC(c_runner)
    assert {"recovered", "fell", "not_settled"} <= set(c_frame["outcome"])
    for b, (force, duration) in enumerate(CELLS):
        ref, series = reference.simulate_scenario(CONFIG, force, duration, mpc=mpc)
        mine = c_frame.iloc[b]
        assert mine.outcome == ref["outcome"], (force, duration)
        assert mine.fall_cause == ref["fall_cause"]
        # the capture columns (measures/capture.py): the decision instant is the first sample
        # past a threshold, so round-off moves it by a sample at most where the capture point
        # crosses it; the margin is then the reference's at one of those samples
        assert mine.steps_needed == ref["steps_needed"] or (
            np.isnan(mine.steps_needed) and np.isnan(ref["steps_needed"])
        )
        if ref["outcome"] == "fell":
            within(
                mine.decision_time,
                ref["decision_time"],
                atol=CONFIG.scenario.physics_dt + 1e-12,
                msg=force,
                why="one sample (comment)",
            )
            low, high = margins.capture_window(
                CONFIG, series, force, duration, ref["decision_time"], 1
            )
            within(
                np.clip(mine.capture_margin, low, high),
                mine.capture_margin,
                atol=tol_capture(CONFIG, ref, force, duration),
                msg=force,
                why="the margin at one of those samples, up to the loop's rounding of the "
                "CoM (margins.closed_loop_rounding) and float32 kinematics",
            )
        for key in ("fall_time", "settle_time"):
            within(
                mine[key],
                ref[key],
                atol=1e-12,
                msg=(key, force),
                why="the same sample (both compute its time as k dt)",
            )
        tol = margins.closed_loop_rounding(CONFIG, ref, force, duration)
        why = (
            "float32 ADMM rounding x the loop's gain, grown after an infeasible QP when it "
            "falls (margins.closed_loop_rounding)"
        )
        for key in (
            "peak_ankle",
            "peak_hip",
            "energy_ankle",
            "energy_hip",
            "energy_u1",
            "energy_u2",
        ):
            within(mine[key], ref[key], rtol=tol[key], atol=1e-9, msg=(key, force), why=why)
        excursion = {
            place: max(abs(ref[f"{place}_min"]), abs(ref[f"{place}_max"]))
            for place in ("cop", "com")
        }
        for key in ("cop_min", "cop_max"):
            within(
                mine[key],
                ref[key],
                atol=tol["cop"] * excursion["cop"] + 1e-9,
                msg=(key, force),
                why=why + ", of the CoP's largest excursion",
            )
        for key in ("com_min", "com_max"):
            within(
                mine[key],
                ref[key],
                atol=tol["com"] * excursion["com"] + margins.kinematics_rounding(CONFIG),
                msg=(key, force),
                why=why + ", of the CoM's largest excursion, plus float32 "
                "kinematics (margins.kinematics_rounding)",
            )
        # CoM velocity and margin of stability (docs/model.md): points of the same trajectory,
        # so their error is the loop's relative rounding of their largest excursion from rest
        # (the margin's rest value is the cells' half span, foot_length / 2); the C path's
        # float32 rows and the last sample's float32 kinematics and Jacobian add at most
        # 18 eps_float32 (2e-6) relative and margins.kinematics_rounding per position (CoM,
        # toe edge), far below tol["com"] (>= admm_rounding 1.9e-3 x gain)
        vel = max(abs(ref["com_vel_min"]), abs(ref["com_vel_max"]))
        for key in ("com_vel_min", "com_vel_max"):
            within(
                mine[key],
                ref[key],
                atol=tol["com"] * vel + 1e-9,
                msg=(key, force),
                why=why + ", of the CoM velocity's largest excursion",
            )
        dip = abs(CONFIG.body.foot_length / 2 - ref["mos_min"])
        within(
            mine.mos_min,
            ref["mos_min"],
            atol=tol["com"] * dip + 2 * margins.kinematics_rounding(CONFIG) + 1e-9,
            msg=("mos_min", force),
            why=why + ", of the margin's dip from rest, plus float32 kinematics of the "
            "CoM and the toe edge (margins.kinematics_rounding)",
        )
        if dip > 1e-3:  # a margin that dips (not F = 0, where its minimum is rest's jitter)
            within(
                mine.mos_min_time,
                ref["mos_min_time"],
                atol=0.01,
                msg=force,
                why="the first sample at the minimum: an error d <= 1e-5 m in the margin "
                "(above) moves it by d / slope where the margin still falls at the "
                "fall sample or t_end (slope >= 1.2e-3 m/s on these pushes: <= 8 ms), "
                "by sqrt(2 d / |MoS''|) at a turning point (51 m/s^2 after 20 N: 0.6 ms)",
            )
        print(
            f"{force:6.1f} N {duration} s: mos_min {mine.mos_min:.6f} vs {ref['mos_min']:.6f}"
            f" at {mine.mos_min_time:.3f} vs {ref['mos_min_time']:.3f} s; com_vel "
            f"[{mine.com_vel_min:.5f}, {mine.com_vel_max:.5f}] vs "
            f"[{ref['com_vel_min']:.5f}, {ref['com_vel_max']:.5f}]"
        )
        # the foot is not in the linear model: while it rests on its sole its pitch follows the
        # CoP (certificate.py: |pitch| <= PITCH_PER_COP |CoP - rest| + PITCH_FLOOR), and so does
        # its error; when it tips at a fall it moves with the body, whose error is relative
        pitch_error = max(
            PITCH_PER_COP * tol["cop"] * excursion["cop"],
            max(tol["cop"], tol["peak_ankle"], tol["peak_hip"]) * abs(ref["peak_foot_pitch"]),
        )
        within(
            mine.peak_foot_pitch,
            ref["peak_foot_pitch"],
            atol=pitch_error + 1e-9,
            msg=("peak_foot_pitch", force),
            why=why + ", through the pitch-CoP relation or the body's relative error",
        )
        # signed sums (and their magnitudes, the study's energy) cancel: their round-off is
        # relative to the absolute work of the same pair, not to their own size
        scale = {
            "work_u1": ("energy_u1",),
            "work_u2": ("energy_u2",),
            "study_energy_u1": ("energy_u1",),
            "study_energy_u2": ("energy_u2",),
            "study_energy_total": ("energy_u1", "energy_u2"),
        }
        for key, pairs in scale.items():
            allowed = sum(tol[pair] * ref[pair] for pair in pairs) + 1e-9
            within(
                mine[key],
                ref[key],
                atol=allowed,
                msg=(key, force),
                why=why + ", of the pair's absolute work",
            )
        assert mine.nonconverged_solves == ref["nonconverged_solves"]


def tol_capture(config, ref, force, duration) -> float:
    """The capture point's rounding [m]: the loop's relative rounding of the CoM
    (margins.closed_loop_rounding) of its largest excursion, plus float32 kinematics of the CoM
    and of the CoM velocity's excursion over omega0."""
    tol = margins.closed_loop_rounding(config, ref, force, duration)["com"]
    com = max(abs(ref["com_min"]), abs(ref["com_max"]))
    vel = max(abs(ref["com_vel_min"]), abs(ref["com_vel_max"]))
    from mjx_balance.measures import capture

    omega0 = capture.step_model(config).omega0
    return tol * (com + vel / omega0) + 2 * margins.kinematics_rounding(config) + 1e-9


def test_c_path_agrees_with_the_mjx_path(batch_runner, c_frame):
    """The MJX path (float32 physics, capped contact solver) on the same cells: the same
    outcome wherever a 1 % change of the force does not flip it."""
    forces, durations = np.array(CELLS).T
    mjx_frame = batch_runner.run_frame(forces, durations)
    for b, (force, duration) in enumerate(CELLS):
        if c_frame.outcome[b] == mjx_frame.outcome[b]:
            continue
        near = batch_runner.run_frame(np.array([0.99, 1.01]) * force, [duration] * 2)
        assert set(near.outcome) != {mjx_frame.outcome[b]}, (force, duration)


@pytest.mark.slow  # a second C-path run; the C path's agreement tests stay in the default run
def test_near_zero_pushes_are_certified_on_the_c_path(c_runner):
    """Rule 5 of certificate.py on the C path, as on the MJX path (test_engine.py): pushes of
    0 N stop at the first check whatever their duration, a 3-N push of 0.05 s before t_end, and
    their summaries (with a 20-N push's) match the C path's full-length runs by the documented
    rule (support.assert_certified_like_full_length)."""
    from mjx_balance.control.certificate import CHECK_EVERY

    config = Config().replace(scenario={"t_end": 3.0})
    forces, durations = np.array([(0.0, 0.1), (0.0, 1.5), (3.0, 0.05), (20.0, 0.1)]).T
    out = {}
    for name, early in (("early", True), ("full", False)):
        runner = BatchRunner(
            config,
            physics="c",
            slots=4,
            threads=2,
            early_stop=early,
            devices=jax.local_devices()[:1],
        )
        out[name] = runner.run(forces, durations)
        out[name + "_periods"], out[name + "_certified"] = (
            runner.last_periods,
            runner.last_certified,
        )
    assert out["early_certified"][:3].all()
    assert (out["early_periods"][:2] == CHECK_EVERY).all()
    assert out["early_periods"][2] < config.scenario.n_control
    jitter = {c: abs(float(out["full"][c][0])) for c in CERTIFIED_INTEGRALS}
    assert_certified_like_full_length(
        out["early"], out["full"], out["early_certified"], config, jitter
    )


def test_threads_slots_and_order_change_nothing(c_runner, c_frame):
    """A cell's row does not depend on MuJoCo's thread count, its slot or the other cells."""
    forces, durations = np.array(CELLS).T
    order = np.array([6, 1, 7, 3])
    one_thread = BatchRunner(
        CONFIG, physics="c", slots=4, threads=1, early_stop=False, devices=jax.local_devices()[:1]
    )
    again = one_thread.run_frame(forces[order], durations[order])
    expected = c_frame.iloc[order].reset_index(drop=True)
    for column in expected.columns:
        np.testing.assert_array_equal(
            again[column].to_numpy(), expected[column].to_numpy(), err_msg=column
        )


def test_the_c_engine_refuses_what_it_cannot_honour():
    """Engine's block, tile and bodies have no meaning on the C path: a TypeError naming them,
    raised before anything is built (the runner is never touched)."""
    for option in ({"block": 10}, {"tile": 2}, {"bodies": [None, None]}):
        with pytest.raises(TypeError, match=next(iter(option))):
            cpath.CEngine(None, slots=4, **option)


def test_the_path_is_resolved_and_recorded():
    hip = CONFIG.replace(scenario={"push_body": "hip"})
    assert cpath.resolve("auto", hip, platform="cpu") == "mjx"
    assert cpath.resolve("auto", CONFIG, platform="gpu") == "mjx"
    assert cpath.resolve("auto", CONFIG, platform="cpu") == cpath.AUTO_ON_CPU
    with pytest.raises(ValueError, match="push"):
        cpath.resolve("c", hip)
    with pytest.raises(ValueError, match="physics must be"):
        LazyBatch(CONFIG, physics="C")
    said = []
    recorded = {"slots": 8, "early_stop": True, "physics": "mjx"}
    with pytest.raises(ParameterError, match="started with mjx physics"):
        resume_engine(LazyBatch(CONFIG, physics="c"), recorded, "DIR", said.append)
    auto = LazyBatch(CONFIG)
    resume_engine(auto, {**recorded, "physics": "c"}, "DIR", said.append)
    assert auto.physics == "c" and auto.slots == 8
    old = LazyBatch(CONFIG)  # a folder from before the path was recorded ran MJX
    resume_engine(old, {"slots": 8, "early_stop": True}, "DIR", said.append)
    assert old.physics == "mjx"


def test_a_sweep_definition_names_its_physics(tmp_path):
    from mjx_balance.runs.definitions import load_sweep

    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nforces = "0,10"\ndurations = "0.1"\nphysics = "c"\n')
    assert load_sweep(path, CONFIG).physics == "c"
    path.write_text('[sweep]\nphysics = "C"\n')
    with pytest.raises(ParameterError, match="physics must be"):
        load_sweep(path, CONFIG)
