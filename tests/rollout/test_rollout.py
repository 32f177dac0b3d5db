"""The batched MJX closed loop (the rollout package) against MuJoCo C and the scalar reference.

The whole module runs with ``jax_enable_x64`` off (conftest turns it on for the session), as a
sweep does: with x64 on, MJX does some internal arithmetic in float64 even on a float32 model,
which would make the agreement look better than what users get.

Compiles are the expensive part (~13 s each on 2 cores), so the batched closed loop is the
session's shared one (conftest ``batch_runner``: defaults with t_end = 2 s, trajectories on,
batch padded to 8), whose model the physics tests reuse with one compiled 500-step open-loop
scan. The slow tests compare outcomes at the study's t_end = 12 s and compile their own.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from margins import within
from support import AdmmMPC

from mjx_balance import rollout
from mjx_balance.measures import metrics
from mjx_balance.measures.outcomes import OUTCOMES, SUMMARY_COLUMNS
from mjx_balance.model.mjcf import build_model, indices
from mjx_balance.model.params import Config
from mjx_balance.model.subject import Subject
from mjx_balance.reference import loop as reference

CONFIG = Config()  # the physics tests' body and time step; t_end comes from the runner
DT = CONFIG.scenario.physics_dt

# Positions MJX (float32, MJX_OPTIONS) vs mj_step (float64, MuJoCo's default 100-iteration
# Newton) after 1 s of open-loop torques with the foot rocking on its load cells. float32
# rounds each step at ~1e-7 relative; the open-loop body is unstable (time constant ~0.3 s), so
# rounding grows by about e^(1/0.3) ~ 30 over the second, and more where the foot's contacts
# switch. Measured: 3.1e-5 (the largest in the hip) with XLA's default vector width, 2.2e-4 with
# the 128-bit width the package sets for schedule-independent results (mjx_balance.runtime.xla): the
# same float32 arithmetic rounded in another order moves this unstable loop by that much, so
# the tolerance is the larger figure with a factor 2. The solver cap (4 Newton iterations; the
# C solver needs at most 3 here) adds nothing measurable: 100 iterations give the same error;
# 2 iterations give 0.2 rad. With the ISA capped at AVX (no FMA): 0.8e-4 to 1.6e-4 depending
# on XLA's other settings, up to a third of the tolerance (docs/reliability.md, margin audit).
# No useful bound can be derived: the open loop folds the body (the hip reaches 2.4 rad) and
# rounding grows in it as fast as exp(8.75/s x 1 s).
PHYSICS_TOL = 5e-4  # m or rad
# The agreement required of the batched closed loop (MJX float32 physics with its capped contact
# solver, the float32 ADMM) against the reference (MuJoCo C, OSQP). Most of what it allows is
# the difference of the two models and solvers, which is the same on every CPU; what a CPU
# changes is rounding: the float32 ADMM's (margins.admm_rounding, 1.9e-3 of the inputs) through
# the stable loop's gain (about 2, margins.input_gains) on joint angles of at most 0.36 rad (the
# 100-N fall's hip before its first infeasible QP, where the comparison stops): 1.4e-3 rad,
# 27 % of it. Measured on a 2-core AMD EPYC: 1.8e-3 rad, so another CPU (whose rounding may
# differ from this one's by twice that share) stays below 1.8e-3 + 2 x 1.4e-3 = 4.6e-3 rad.
ANGLE_TOL = 5e-3  # rad


def _open_loop_inputs(n: int = 500) -> tuple[np.ndarray, float, int]:
    """1 s of smooth motor torques and an 80 N, 0.1 s push: the foot rocks (pitch ~0.016)."""
    t = np.arange(n) * DT
    torques = np.stack(
        [-15 + 25 * np.sin(2 * np.pi * 1.3 * t), -5 + 8 * np.sin(2 * np.pi * 2.1 * t)], axis=1
    )
    return torques, 80.0, int(rollout.push_steps(np.array([0.1]), DT)[0])


def _c_open_loop(torques: np.ndarray, force: float, n_push: int) -> dict[str, np.ndarray]:
    """The same open loop with mj_step on the reference's model (MuJoCo defaults, float64)."""
    model = build_model(CONFIG.body, DT)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ix = indices(model)
    out = {"qpos": [], "cop": [], "com": [], "solver_iterations": []}
    for i, tau in enumerate(torques):
        data.ctrl[:] = tau
        data.xfrc_applied[:] = 0.0
        if i < n_push:
            data.xfrc_applied[ix.upper_body, 0] = force
        mujoco.mj_step(model, data)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        out["qpos"].append(data.qpos.copy())
        out["cop"].append(metrics.load_cell_cop(model, data, ix.cell_geoms)[0])
        out["com"].append(metrics.whole_body_com(data, ix.foot_body))
        out["solver_iterations"].append(int(data.solver_niter[0]))
    return {k: np.asarray(v) for k, v in out.items()}


pytestmark = pytest.mark.usefixtures("float32_module")  # x64 off (conftest)


@pytest.fixture(scope="module")
def runner(batch_runner):
    """The session's compiled runner (conftest): CONFIG with t_end = 2 s, trajectories on."""
    assert batch_runner.config == CONFIG.replace(scenario={"t_end": 2.0})
    assert batch_runner.trajectories
    return batch_runner


@pytest.fixture(scope="module")
def physics(runner):
    """(mujoco model with MJX options, mjx model float32, rest data, sensors, open loop jitted
    for 500 steps). The model comes from the runner, so it is built once."""
    mx, d0, sn = runner.arrays.mx, runner.arrays.d0, runner.sensors
    run = jax.jit(lambda mx, d0, tau, f, n: rollout.open_loop(mx, sn, d0, tau, f, n))
    return runner.model, mx, d0, sn, run


# --------------------------------------------------------------------------------------------
# Physics


def test_mjx_physics_matches_mj_step(physics):
    model, mx, d0, sn, run = physics
    torques, force, n_push = _open_loop_inputs()
    c = _c_open_loop(torques, force, n_push)
    assert np.abs(c["qpos"][:, indices(model).foot_pitch]).max() > 0.01  # the foot does rock

    out = run(mx, d0, jnp.asarray(torques, jnp.float32), jnp.float32(force), jnp.int32(n_push))
    qpos = np.asarray(out["qpos"])
    assert qpos.dtype == np.float32
    err = np.abs(qpos - c["qpos"]).max(axis=0)
    print(
        f"\nMJX vs mj_step, 1 s open loop: max |qpos error| per coordinate {err}; "
        f"C solver iterations max {max(c['solver_iterations'])}"
    )
    within(qpos, c["qpos"], atol=PHYSICS_TOL, why="PHYSICS_TOL: measured, x2 (comment)")
    assert max(c["solver_iterations"]) <= rollout.MJX_OPTIONS["iterations"]


def test_cop_and_com_match_c_side(physics):
    """One physics step from the same C state: CoP (load-cell normal forces) and CoM agree.

    The MJX step is the first step of the module's compiled open loop started from the C state
    (so nothing new is compiled); only its first sample is used.
    """
    model, mx, d0, sn, run = physics
    ref_model = build_model(CONFIG.body, DT)
    ix = indices(ref_model)
    torques, force, n_push = _open_loop_inputs()
    data = mujoco.MjData(ref_model)
    mujoco.mj_forward(ref_model, data)
    checked = 0
    for i, tau in enumerate(torques):
        push = force if i < n_push else 0.0
        if i in (10, 60, 150, 260, 400):
            # on d0's device, committed like d0's arrays: an uncommitted array would make
            # jit compile the open loop a second time
            put = functools.partial(jax.device_put, device=d0.qpos.sharding)
            d = d0.replace(
                qpos=put(np.asarray(data.qpos, np.float32)),
                qvel=put(np.asarray(data.qvel, np.float32)),
                qacc_warmstart=put(np.asarray(data.qacc_warmstart, np.float32)),
            )
            seq = np.roll(torques, -i, axis=0)
            out = run(mx, d, jnp.asarray(seq, jnp.float32), jnp.float32(push), jnp.int32(1))
        data.ctrl[:] = tau
        data.xfrc_applied[:] = 0.0
        data.xfrc_applied[ix.upper_body, 0] = push
        mujoco.mj_step(ref_model, data)
        mujoco.mj_kinematics(ref_model, data)
        mujoco.mj_comPos(ref_model, data)
        if i in (10, 60, 150, 260, 400):
            cop_c, load_c = metrics.load_cell_cop(ref_model, data, ix.cell_geoms)
            com_c = metrics.whole_body_com(data, ix.foot_body)
            low_c = metrics.cell_heights(ref_model, data, ix.cell_geoms)
            cop_j, com_j = float(out["cop"][0]), float(out["com"][0])
            low_j = np.asarray(out["cell_low"][0])
            print(
                f"step {i}: cop C {cop_c:+.6f} MJX {cop_j:+.6f}, "
                f"com C {com_c:+.7f} MJX {com_j:+.7f}, load {load_c:.1f} N"
            )
            within(cop_j, cop_c, atol=1e-4, msg=i, why="float32 contact solve (m)")
            within(com_j, com_c, atol=1e-6, msg=i, why="float32 kinematics (m)")
            np.testing.assert_allclose(low_j, low_c, atol=1e-6)
            checked += 1
    assert checked == 5


# --------------------------------------------------------------------------------------------
# Closed loop vs the reference


class RecordingMPC:
    """The reference's OSQP controller (reference.reference_mpc), recording whether each solve
    converged."""

    def __init__(self, config: Config):
        sc = config.scenario
        self.inner = reference.reference_mpc(config.controller, config.body, sc.control_dt)
        self.qp = self.inner.qp
        self.converged: list[bool] = []

    def reset(self) -> None:
        self.inner.reset()
        self.converged.clear()

    def solve(self, x0):
        result = self.inner.solve(x0)
        self.converged.append(result[2])
        return result


def _reference_with_solver_flags(force: float, duration: float, config: Config):
    """Reference run, also recording whether each OSQP solve converged."""
    mpc = RecordingMPC(config)
    summary, series = reference.simulate_scenario(config, force, duration, record=True, mpc=mpc)
    return summary, series, np.asarray(mpc.converged)


@pytest.fixture(scope="module")
def closed_loop(runner):
    """0 N (rest), 50 N (recovers, settles by ~1.2 s), 100 N (falls at ~1.4 s) for 0.1 s."""
    forces = np.array([0.0, 50.0, 100.0])
    durations = np.full(3, 0.1)
    summary = runner.run(forces, durations)
    series = runner.last_trajectories
    refs = [_reference_with_solver_flags(f, t, runner.config) for f, t in zip(forces, durations)]
    return forces, summary, series, refs


def test_closed_loop_matches_reference(closed_loop, runner):
    forces, summary, series, refs = closed_loop
    S = CONFIG.scenario.substeps
    ix = indices(runner.model)
    assert [ref["outcome"] for ref, _, _ in refs] == ["recovered", "recovered", "fell"]
    for b, (force, (ref, ref_series, converged)) in enumerate(zip(forces, refs)):
        outcome = OUTCOMES[summary["outcome"][b]]
        assert outcome == ref["outcome"], (force, outcome, ref["outcome"])
        n = len(ref_series)
        q = series["qpos"][b, :n][:, [ix.ankle_qpos, ix.hip_qpos]]
        q_ref = ref_series[["q_a", "q_h"]].to_numpy()
        diff = np.abs(q - q_ref).max(axis=1)
        # After the first non-converged reference solve (an infeasible QP) the controller's
        # input is a solver's last iterate, which depends on the solver and its iteration
        # count: compare up to that control instant.
        bad = np.flatnonzero(~converged)
        n_cmp = n if not bad.size else min(n, int(bad[0]) * S)
        print(
            f"\nF = {force:5.1f} N: {outcome} (reference {ref['outcome']}), "
            f"max |angle diff| {np.nanmax(diff[:n_cmp]):.2e} rad over {n_cmp * DT:.2f} s"
            + (
                f" (first non-converged reference solve at {bad[0] * S * DT:.2f} s; "
                f"max over the whole run {np.nanmax(diff):.2e})"
                if bad.size
                else ""
            )
            + f"; settle {summary['settle_time'][b]:.3f} vs {ref['settle_time']:.3f}, "
            f"fall {summary['fall_time'][b]:.3f} vs {ref['fall_time']:.3f}"
        )
        assert n_cmp > 0.5 / DT
        within(
            np.nanmax(diff[:n_cmp]),
            0.0,
            atol=ANGLE_TOL,
            msg=force,
            why="the closed loop's agreement with the reference (ANGLE_TOL)",
        )
        # the fall sample is the last one (both stop / mask there)
        if ref["outcome"] == "fell":
            assert np.isnan(series["qpos"][b, int(round(summary["fall_time"][b] / DT))]).all()


def test_summary_matches_reference_for_recovered_runs(closed_loop):
    forces, summary, _, refs = closed_loop
    for b, (ref, _, _) in enumerate(refs):
        if ref["outcome"] != "recovered":
            continue
        # 5 % or an absolute floor: the ADMM stops at eps 1e-4 (scaled), which leaves inputs
        # ~0.01 N m away from OSQP's 1e-8 solution even at rest (F = 0); at rest the float32
        # contact solve splits the weight between heel and toe cells to ~1e-4 m of CoP.
        floors = {
            "peak_ankle": 1e-4,
            "peak_hip": 1e-4,
            "com_max": 1e-4,
            "cop_max": 5e-4,
            "peak_tau_ankle": 0.05,
            "energy_total": 1e-3,
            "energy_u1": 1e-3,
            "energy_u2": 1e-3,
            "work_u1": 1e-3,
            "work_u2": 1e-3,
            "study_energy_u1": 1e-3,
            "study_energy_u2": 1e-3,
            "study_energy_total": 1e-3,
        }
        for name, floor in floors.items():
            within(
                summary[name][b],
                ref[name],
                rtol=0.05,
                atol=floor,
                msg=(forces[b], name),
                why="ADMM (eps 1e-4 scaled) vs OSQP (1e-8) and float32 contacts (comment)",
            )
        # CoM velocity and the margin of stability's dip below its rest value (the cells' half
        # span): the same rule, on the velocity and on the dip (docs/model.md)
        rest = CONFIG.body.foot_length / 2
        within(
            summary["com_vel_max"][b],
            ref["com_vel_max"],
            rtol=0.05,
            atol=1e-4,
            msg=(forces[b], "com_vel_max"),
            why="ADMM (eps 1e-4 scaled) vs OSQP (1e-8) and float32 contacts (comment)",
        )
        within(
            rest - summary["mos_min"][b],
            rest - ref["mos_min"],
            rtol=0.05,
            atol=1e-4,
            msg=(forces[b], "mos_min"),
            why="ADMM (eps 1e-4 scaled) vs OSQP (1e-8) and float32 contacts (comment)",
        )
        assert summary["nonconverged_solves"][b] == ref["nonconverged_solves"] == 0
        within(
            summary["settle_time"][b],
            ref["settle_time"],
            atol=0.1,
            msg=forces[b],
            why="the settle band is crossed at a shallow slope: 0.1 s",
        )


def test_run_frame_columns_and_padding(runner):
    frame = runner.run_frame([20.0, -20.0], [0.1, 0.1])
    assert list(frame.columns) == SUMMARY_COLUMNS
    assert list(frame["outcome"]) == ["recovered", "recovered"]
    assert (frame["convention"] == CONFIG.controller.convention).all()
    # a backward push mirrors a forward one only approximately (the model is symmetric, the
    # float32 solver path is not exactly); the peak angles agree closely
    within(
        frame["peak_ankle"][0],
        frame["peak_ankle"][1],
        rtol=1e-2,
        why="a mirrored push, computed in another float32 order (comment)",
    )
    sc = runner.config.scenario
    assert runner.last_trajectories["qpos"].shape[:2] == (2, sc.n_control * sc.substeps)


def test_bad_inputs_raise(runner):
    with pytest.raises(ValueError):
        runner.run([1.0, 2.0], [0.1])
    with pytest.raises(ValueError):
        runner.run([math.nan], [0.1])
    with pytest.raises(ValueError):
        runner.run([10.0], [-0.1])


# Cells near the recovery boundary (found with the batched runner: at T = 0.1 s pushes start
# failing between 85 and 90 N, at T = 0.2 s between 45 and 50 N). Eight cells, so the runner's
# compiled batch of 8 is reused.
BOUNDARY_GRID = [
    (80.0, 0.1),
    (85.0, 0.1),
    (90.0, 0.1),
    (95.0, 0.1),
    (40.0, 0.2),
    (45.0, 0.2),
    (50.0, 0.2),
    (55.0, 0.2),
]
# A cell whose reference outcome changes when its force moves by 2 % or its duration by
# 0.01 s lies within this tolerance of the reference's own threshold; a disagreement there is
# reported, not failed.
FORCE_MARGIN, DURATION_MARGIN = 0.02, 0.01


@pytest.fixture(scope="module")
def runner_12():
    """A runner at the study's t_end = 12 s (recovery within 12 s), for the slow tests."""
    return rollout.BatchRunner(CONFIG, trajectories=True)


@pytest.mark.slow
def test_outcomes_agree_on_grid_across_recovery_boundary(runner_12):
    forces = np.array([f for f, _ in BOUNDARY_GRID])
    durations = np.array([t for _, t in BOUNDARY_GRID])
    batched = runner_12.run(forces, durations)
    outcomes = [OUTCOMES[c] for c in batched["outcome"]]
    ref = [
        reference.simulate_scenario(CONFIG, f, t, record=False)[0]["outcome"]
        for f, t in BOUNDARY_GRID
    ]
    assert {"recovered", "fell"} <= set(ref)  # the grid does span the boundary
    borderline, failures = [], []
    for (f, t), mine, theirs in zip(BOUNDARY_GRID, outcomes, ref):
        if mine == theirs:
            continue
        neighbours = [
            (f * (1 - FORCE_MARGIN), t),
            (f * (1 + FORCE_MARGIN), t),
            (f, max(t - DURATION_MARGIN, 0.0)),
            (f, t + DURATION_MARGIN),
        ]
        flips = {
            reference.simulate_scenario(CONFIG, nf, nt, record=False)[0]["outcome"]
            for nf, nt in neighbours
        } - {theirs}
        (borderline if flips else failures).append((f, t, mine, theirs))
    print(
        f"\n{len(BOUNDARY_GRID)} cells: reference {ref}\nbatched {outcomes}\n"
        f"{len(borderline)} disagreeing cell(s) within the margin of the reference's "
        f"threshold: {borderline}"
    )
    assert not failures, failures


@pytest.mark.slow
def test_joint_convention_closed_loop_matches_reference():
    config = CONFIG.replace(controller={"convention": "joint"})
    # the shapes of runner_12's: one compiled function for both slow tests
    runner = rollout.BatchRunner(config, trajectories=True)
    forces, durations = np.array([50.0, 80.0]), np.array([0.1, 0.1])
    summary = runner.run(forces, durations)
    assert_angles_match_reference(runner, config, forces, durations, summary, "joint convention")


@pytest.mark.slow
def test_a_subjects_closed_loop_matches_its_reference():
    """A scaled subject (female, 1.60 m, 55 kg: de Leva's segments, given inertias, CoP/CoM
    bounds at its 0.21-m foot's edges, torque bounds x 55 / 66.3): the batched lanes agree with
    the scalar reference built for that subject, to the same ANGLE_TOL as the study's body (the
    tolerance's rounding argument does not depend on the body). Slow: its own compile (its
    bounds differ from the shared runner's), 78 s on 2 cores. Measured: all three recover,
    max |angle diff| 5.6e-7 (0 N), 1.4e-5 (30 N), 9.5e-6 rad (-30 N)."""
    config = Subject(1.60, 55, "female").config(Config().replace(scenario={"t_end": 2.0}))
    with jax.enable_x64(False):
        runner = rollout.BatchRunner(config, trajectories=True, devices=jax.local_devices()[:1])
        forces, durations = np.array([0.0, 30.0, -30.0]), np.full(3, 0.1)
        summary = runner.run(forces, durations)
    assert_angles_match_reference(runner, config, forces, durations, summary, "subject")


def assert_angles_match_reference(runner, config, forces, durations, summary, label: str):
    """Each lane's outcome is the reference's, and its joint angles agree to ANGLE_TOL over
    at least 0.5 s, up to the reference's first non-converged solve (after it the two loops
    may part within their tolerances)."""
    ix = indices(runner.model)
    S = config.scenario.substeps
    for b, (force, duration) in enumerate(zip(forces, durations)):
        ref, series, converged = _reference_with_solver_flags(force, duration, config)
        assert OUTCOMES[summary["outcome"][b]] == ref["outcome"], force
        n = len(series)
        q = runner.last_trajectories["qpos"][b, :n][:, [ix.ankle_qpos, ix.hip_qpos]]
        diff = np.abs(q - series[["q_a", "q_h"]].to_numpy()).max(axis=1)
        bad = np.flatnonzero(~converged)
        n_cmp = n if not bad.size else min(n, int(bad[0]) * S)
        print(
            f"\n{label}, F = {force} N: {ref['outcome']}, max |angle diff| "
            f"{np.nanmax(diff[:n_cmp]):.2e} rad over {n_cmp * DT:.2f} s"
        )
        assert n_cmp > 0.5 / DT
        within(
            np.nanmax(diff[:n_cmp]),
            0.0,
            atol=ANGLE_TOL,
            msg=force,
            why="the closed loop's agreement with the reference (ANGLE_TOL)",
        )


# Cells of every outcome the 2-s window allows, and falls of each kind of rule.
LEAN_GRID = [
    (0.0, 0.1),
    (50.0, 0.1),
    (100.0, 0.1),
    (200.0, 0.1),
    (-150.0, 0.3),
    (30.0, 1.0),
    (60.0, 0.3),
    (15.0, 1.9),
]


@pytest.mark.slow  # tens of seconds on 2 cores: .ci/run runs it after the default suite
def test_lean_physics_is_the_step_plus_kinematics_loop(runner, float32):
    """The engine's closed loop reads a sample's positions from the next step's start instead
    of an extra mjx.kinematics per step (kernel.period); the summaries it gives are those of
    the loop with the extra kinematics (the runner with trajectories), which every agreement
    test in this module checks against the reference."""
    forces = np.array([f for f, _ in LEAN_GRID])
    durations = np.array([t for _, t in LEAN_GRID])
    lean = rollout.BatchRunner(
        runner.config, slots=8, early_stop=False, devices=jax.local_devices()[:1]
    ).run(forces, durations)
    full = runner.run(forces, durations)
    assert {"recovered", "fell"} <= {OUTCOMES[c] for c in full["outcome"]}
    for name, values in full.items():
        np.testing.assert_array_equal(lean[name], values, err_msg=name)


FALL_GRID = [(100.0, 0.1), (200.0, 0.1), (-150.0, 0.3), (30.0, 1.0)]


def test_fall_cause_and_first_infeasible_qp_match_the_reference(runner, float32):
    """Why a run ended, in both paths. Every fall on this grid comes after a QP that has no
    solution; what a solver returns for an infeasible QP depends on the solver (its scaling
    sets the "least violation"), so the reference with OSQP falls later than the batched
    path (by 0.1-0.5 s) and, after forward pushes, often the other way. With the batched
    path's ADMM as its controller the reference is the same closed loop in other physics, and
    the cause of each fall must be the same rule."""
    forces = np.array([f for f, _ in FALL_GRID])
    durations = np.array([t for _, t in FALL_GRID])
    batched = runner.run_frame(forces, durations)
    mpc = AdmmMPC(runner)
    for b, (force, duration) in enumerate(FALL_GRID):
        ref = reference.simulate_scenario(runner.config, force, duration, record=False, mpc=mpc)[0]
        mine = batched.iloc[b]
        print(
            f"F = {force:6.1f} N, T = {duration} s: batched {mine.outcome} by "
            f"{mine.fall_cause} at {mine.fall_time:.3f} s, first infeasible QP at "
            f"{mine.first_infeasible_time:.2f} s; reference (ADMM) {ref['outcome']} by "
            f"{ref['fall_cause']} at {ref['fall_time']:.3f} s, first infeasible QP at "
            f"{ref['first_infeasible_time']:.2f} s"
        )
        assert mine.outcome == ref["outcome"] == "fell"
        assert mine.fall_cause == ref["fall_cause"]
        within(
            mine.fall_time,
            ref["fall_time"],
            atol=0.05,
            msg=force,
            why="the same closed loop in float32 physics: the same rule within 0.05 s",
        )
        # The reference tests feasibility exactly (an LP), the batched path by the ADMM's
        # certificate after its iteration cap, which can lag by a few control periods.
        assert mine.first_infeasible_time <= mine.fall_time
        assert ref["first_infeasible_time"] <= ref["fall_time"]
        within(
            mine.first_infeasible_time,
            ref["first_infeasible_time"],
            atol=0.1,
            msg=force,
            why="the ADMM's certificate lags an exact LP by a few periods (comment)",
        )
