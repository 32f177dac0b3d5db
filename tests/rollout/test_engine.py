"""Continuous batching (rollout/engine.py) and certified recovery (certificate.py).

- Early stopping against ``--full-length`` on a grid with every outcome the window allows
  (recovered, not settled, fell), long pushes, backward pushes, pushes of 0 and 3 N and the
  edge of the region: identical outcomes, fall and settle times and ADMM statistics; peaks
  identical above their noise floors and below them within the floor; energies and work
  within ENERGY_RTOL and the rest jitter's energy (support.assert_certified_like_full_length,
  the rule of docs/engine.md). The default run
  uses a 3-s window (pushes up to 2.5 s); the slow run the study's 12-s window (pushes up to
  10 s, around the sustained-push limit of about 10.8 N).
- Schedule independence: the same cells run in another order, split over calls, with
  another chunk size, interrupted and resumed, and on two host devices give the same bytes.
- The certificate: exact for the linear model at its boundary; near-zero pushes certified under
  the noise floors, and not past them; in the MuJoCo runs every certified scenario stays in the
  band, and a check just before it fails.
- A push beyond MuJoCo's bound is diverged, as in the reference.
"""

import json
import os
import subprocess
import sys
import textwrap

import jax
import margins
import numpy as np
import pandas as pd
import pytest
from margins import within
from support import (
    CERTIFIED_EXACT,
    CERTIFIED_INTEGRALS,
    ENGINE_SLOTS,
    assert_certified_like_full_length,
    peak_floors,
)

from mjx_balance.control import certificate as cert_mod
from mjx_balance.control.qp import build_qp
from mjx_balance.measures.outcomes import OUTCOMES, SUMMARY_COLUMNS
from mjx_balance.model.linear import zoh
from mjx_balance.model.params import Config
from mjx_balance.rollout import queue as queue_mod
from mjx_balance.runs.grid import Grid

pytestmark = pytest.mark.usefixtures("float32")

# CoP/CoM extremes on the side the push did not drive: the full run's value is set in the
# seconds the early stop skips, near rest (module docstring of certificate.py). Both runs start
# at rest, so the early run's extreme already reaches rest; after the certified instant the
# joints stay inside the settle band (test_certified_runs_stay_in_the_band), so the full run's
# extreme lies at most the band's reach beyond rest: margins.band_excursion, 6.8 cm for the
# CoP and 1.1 cm for the CoM through the linear model's maps (the float32 contacts' jitter at
# rest, ~1e-4 m of CoP, is far below). Measured on this grid: 1.1e-4 m (CoP), 6e-7 m (CoM), both
# the rest jitter of the 0-N cells (a pushed cell's other side: 9.9e-5 m, 0); the bound is loose
# because the certificate does not record how far inside the band a run is.
EXTREME_ATOL = margins.band_excursion(Config())  # m, {"cop": ..., "com": ...}
# What a scenario that falls or runs to t_end keeps bit for bit in both modes
EXACT = (*CERTIFIED_EXACT, *peak_floors(), "max_residual")
INTEGRALS = CERTIFIED_INTEGRALS


def grid(window: str):
    """Forward and backward pushes from tiny to falling, long pushes and the 0.1-s edge of the
    region. "12s": pushes up to 10 s around the sustained-push limit (about 10.8 N), 95 cells;
    "3s": pushes up to 2.5 s (the longest end 0.5 s before t_end), 65 cells."""
    if window == "3s":
        forces = np.array(
            [0.0, 3.0, 8.0, 20.0, 40.0, 60.0, 90.0, 120.0, 150.0, -10.0, -40.0, -80.0]
        )
        durations = np.array([0.05, 0.1, 0.25, 1.0, 2.5])
        edge_f = np.linspace(84.0, 100.0, 5)  # around the 0.1-s boundary
        f, d = np.repeat(forces, durations.size), np.tile(durations, forces.size)
        return np.concatenate([f, edge_f]), np.concatenate([d, np.full(edge_f.size, 0.1)])
    forces = np.array(
        [0.0, 3.0, 8.0, 10.5, 11.0, 20.0, 40.0, 60.0, 90.0, 120.0, 150.0, -10.0, -40.0, -80.0]
    )
    durations = np.array([0.05, 0.1, 0.25, 1.0, 3.0, 10.0])
    f, d = np.repeat(forces, durations.size), np.tile(durations, forces.size)
    edge_f = np.linspace(84.0, 100.0, 9)  # around the 0.1-s boundary
    return np.concatenate([f, edge_f, [10.7, 10.6]]), np.concatenate(
        [d, np.full(edge_f.size, 0.1), [10.0, 11.0]]
    )


# Per window: t_end, and how much the certificate must be seen to save. A certified scenario
# stops at its first check inside the certified set after the push (every CHECK_EVERY
# periods), so what it saves is the window's rest: most of a 12-s window (measured on the
# 12-s grid: 47 certified, 0.33 of the full run's periods), about a second of a 3-s one
# (measured on the 3-s grid: 26 certified, 0.76).
WINDOWS = {
    "3s": dict(t_end=3.0, min_certified=15, max_share=0.95),
    "12s": dict(t_end=12.0, min_certified=20, max_share=0.6),
}


@pytest.fixture(scope="module", params=["3s", pytest.param("12s", marks=pytest.mark.slow)])
def runs(request):
    """The grid of ``request.param`` run with early stopping and at full length (the engine's
    shared slots: conftest.ENGINE_SLOTS)."""
    from mjx_balance.rollout import BatchRunner

    window = WINDOWS[request.param]
    config = Config().replace(scenario={"t_end": window["t_end"]})
    forces, durations = grid(request.param)
    out = {"window": window, "config": config}
    told = out["running"] = []  # what the engine told its queue after each call
    heard = queue_mod.Queue.running

    def running(queue, cells, periods):
        told.append((cells.copy(), periods.copy()))
        return heard(queue, cells, periods)

    with jax.enable_x64(False):
        for name, early in (("early", True), ("full", False)):
            runner = BatchRunner(
                config, slots=ENGINE_SLOTS, early_stop=early, devices=jax.local_devices()[:1]
            )
            queue_mod.Queue.running = running if early else heard
            try:
                out[name] = runner.run(forces, durations)
            finally:
                queue_mod.Queue.running = heard
            out[name + "_periods"] = runner.last_periods
            out[name + "_certified"] = runner.last_certified
            out[name + "_runner"] = runner
    out["forces"], out["durations"] = forces, durations
    return out


def test_grid_reaches_every_outcome_the_window_allows(runs):
    seen = {OUTCOMES[i] for i in runs["full"]["outcome"]}
    assert {"recovered", "not_settled", "fell"} <= seen


def test_the_queue_hears_how_long_each_cell_in_a_slot_has_run(runs):
    """After each call the engine tells its queue the cells still in a slot and the periods
    each has run (Queue.running: the lower bounds of their lengths): fewer than the cell's
    length, at least one."""
    told, length = runs["running"], np.asarray(runs["early_periods"])
    assert len(told) >= 2 and any((cells >= 0).any() for cells, _ in told)
    for cells, periods in told:
        busy = cells >= 0
        assert (periods[busy] >= 1).all() and (periods[busy] < length[cells[busy]]).all()


def test_early_stopping_changes_no_decided_column(runs):
    early, full, window = runs["early"], runs["full"], runs["window"]
    assert runs["early_certified"].sum() >= window["min_certified"]  # the certificate is used
    assert runs["early_periods"].sum() < window["max_share"] * runs["full_periods"].sum()
    assert_certified_like_full_length(
        early, full, runs["early_certified"], runs["config"], _jitter(runs["forces"], full)
    )
    # CoP and CoM extremes: on the side the push drove them they are final; on the other the
    # full run's value is rest plus the contact solver's jitter (EXTREME_ATOL)
    for column in ("cop_min", "cop_max", "com_min", "com_max"):
        diff = np.nanmax(np.abs(early[column] - full[column]))
        print(f"{column}: largest difference {diff:.3g} m")
        within(
            early[column],
            full[column],
            atol=EXTREME_ATOL[column[:3]],
            msg=column,
            why="the settle band's reach through the CoP/CoM map (margins.band_excursion)",
        )
    # CoM velocity and margin of stability (docs/model.md): in the band the CoM moves at most
    # at (ankle lever + hip lever) x settle_rate_tol, the levers the CoM's velocity per unit
    # joint rate at rest; the XcoM reaches the CoM's band plus that velocity / omega0
    vel_band, omega0 = _band_velocity(runs["config"])
    for column, atol in (
        ("com_vel_min", vel_band),
        ("com_vel_max", vel_band),
        ("mos_min", EXTREME_ATOL["com"] + vel_band / omega0),
    ):
        diff = np.nanmax(np.abs(early[column] - full[column]))
        print(f"{column}: largest difference {diff:.3g}")
        within(
            early[column],
            full[column],
            atol=atol,
            msg=column,
            why="the settle band's reach in CoM velocity and XcoM (comment)",
        )


def _jitter(forces, full) -> dict[str, float]:
    """Per energy or work column, the largest a 0-N cell spends over the whole window in the
    full-length run (the rest jitter's)."""
    zero = np.asarray(forces) == 0
    assert zero.any(), "the grid needs a 0-N cell"
    return {column: float(np.abs(np.asarray(full[column])[zero]).max()) for column in INTEGRALS}


def test_near_zero_pushes_are_certified(runs):
    """Rule 5 of certificate.py on MuJoCo runs: a push of 0 N is certified at the first check
    whatever its duration (before the rule it ran to t_end), and so are 3-N pushes of up to
    0.25 s before t_end (before the rule: to t_end, the foot pitch's bound above their peak);
    their summaries against the full-length runs are checked with every other certified one
    (test_early_stopping_changes_no_decided_column)."""
    forces, durations = runs["forces"], runs["durations"]
    zero = forces == 0
    assert runs["early_certified"][zero].all()
    assert (runs["early_periods"][zero] == cert_mod.CHECK_EVERY).all()
    small = (forces == 3.0) & (durations <= 0.25)
    assert small.sum() == 3 and runs["early_certified"][small].all()
    n_control = runs["config"].scenario.n_control
    assert (runs["early_periods"][small] < n_control).all()
    # the full-length runs of these never left the settle band
    assert (runs["full"]["settle_time"][zero | small] == 0).all()


def _band_velocity(config) -> tuple[float, float]:
    """(largest |CoM velocity| (m/s) with the joint rates in the settle band at upright rest,
    omega0 of the margin of stability)."""
    import mujoco

    from mjx_balance.measures import metrics
    from mjx_balance.model.mjcf import build_model, indices

    model = build_model(config.body, config.scenario.physics_dt)
    ix = indices(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    levers = []
    for dof in (ix.ankle_dof, ix.hip_dof):
        data.qvel[:] = 0.0
        data.qvel[dof] = 1.0
        levers.append(abs(metrics.com_velocity(model, data, ix.foot_body)))
    return (
        sum(levers) * config.scenario.settle_rate_tol,
        metrics.pendulum_frequency(model, ix.foot_body, ix.ankle_dof),
    )


def test_uncertified_scenarios_are_bit_identical_to_full_length(runs):
    """Falls and scenarios run to t_end go through the same steps in both modes."""
    plain = ~runs["early_certified"]
    for column in (
        *EXACT,
        *INTEGRALS,
        "admm_iterations",
        "cop_min",
        "com_min",
        "com_vel_min",
        "com_vel_max",
        "mos_min",
        "mos_min_time",
    ):
        assert np.array_equal(
            runs["early"][column][plain], runs["full"][column][plain], equal_nan=True
        ), column


def test_same_bits_in_any_order_and_split(runs):
    runner = runs["early_runner"]
    forces, durations = runs["forces"], runs["durations"]
    perm = np.random.default_rng(3).permutation(forces.size)[:40]
    with jax.enable_x64(False):
        a = runner.run(forces[perm[:13]], durations[perm[:13]])
        b = runner.run(forces[perm[13:]], durations[perm[13:]])
    for column, values in runs["early"].items():
        got = np.concatenate([a[column], b[column]])
        assert np.array_equal(got, np.asarray(values)[perm], equal_nan=True), column


def test_certified_runs_stay_in_the_band(runs):
    """From the certified instant on, the full-length run of a certified scenario never
    leaves the settle band: its last sample outside the band (its settle time) comes before
    the instant the early run stopped, and its joint-angle peaks are those recorded until
    then. The full run's summary says it for every sample; the slow
    test_certified_trajectories_stay_in_the_band reads the samples themselves."""
    certified = runs["early_certified"]
    sc = runs["config"].scenario
    periods = runs["early_periods"][certified]
    assert (periods >= cert_mod.CHECK_EVERY).all() and (periods % cert_mod.CHECK_EVERY == 0).all()
    stopped = periods * sc.control_dt
    # a sample outside at the stop (index k S - 1, time k dt_control) or later would put the
    # settle time at k dt_control + dt or beyond
    assert (runs["full"]["settle_time"][certified] < stopped + sc.physics_dt / 2).all()
    assert all(OUTCOMES[c] == "recovered" for c in runs["full"]["outcome"][certified])
    for column in ("peak_ankle", "peak_hip"):  # below the noise floor: rule 5
        above = certified & (runs["early"][column] >= peak_floors()[column])
        assert np.array_equal(runs["full"][column][above], runs["early"][column][above])


@pytest.mark.slow
@pytest.mark.parametrize("runs", ["12s"], indirect=True)
def test_certified_trajectories_stay_in_the_band(runs):
    """Full-length trajectories of certified scenarios: from the certified instant on, every
    sample stays in the settle band and below the joint-angle peaks recorded until then, or
    below the angle's noise floor where the peak recorded was below it (rule 5)."""
    from mjx_balance.rollout import BatchRunner

    pick = np.nonzero(runs["early_certified"])[0][::4][:8]
    config = runs["config"]
    with jax.enable_x64(False):
        runner = BatchRunner(config, trajectories=True, devices=jax.local_devices()[:1])
        runner.run(runs["forces"][pick], runs["durations"][pick])
    series = runner.last_trajectories
    sn, sc = runner.sensors, config.scenario
    for row, i in enumerate(pick):
        k = int(runs["early_periods"][i])  # periods run: certified after period k
        step = k * sc.substeps  # first sample not run
        q = series["qpos"][row][:, sn.joints_q]
        dq = series["qvel"][row][:, sn.joints_v]
        assert (np.abs(q[step - 1 :]) <= sc.settle_angle_tol).all()
        assert (np.abs(dq[step - 1 :]) <= sc.settle_rate_tol).all()
        assert (
            np.abs(q[step:]).max(axis=0)
            <= np.maximum(np.abs(q[:step]).max(axis=0), cert_mod.ANGLE_FLOOR)
        ).all()
        assert k >= cert_mod.CHECK_EVERY and k % cert_mod.CHECK_EVERY == 0


def linear_setup():
    config = Config()
    sc, ctrl = config.scenario, config.controller
    qp = build_qp(ctrl, config.body, sc.control_dt)
    cert = cert_mod.build(qp, ctrl, sc, rest=(0.0, 0.0))
    return config, qp, cert


class _Acc:
    """Running peaks large enough not to matter (the band and QP tests alone)."""

    alive = in_band = True
    peak_ankle = peak_hip = peak_tau_ankle = peak_tau_hip = peak_foot_pitch = np.inf


def test_certificate_is_exact_for_the_linear_model():
    """Along the linear closed loop u = -Kx with u held over each period, from states on the
    boundary of the certified set in several directions, the simulated trajectory stays
    within MARGIN of the band and inside the input bounds for the whole 12-s window; scaled
    1 % beyond the boundary the check fails."""
    config, qp, cert = linear_setup()
    sc, lm = config.scenario, qp.linear
    K = cert_mod.lqr_gain(qp, config.controller.r_diag)
    to_q = cert.to_q
    substeps = [zoh(lm.Ac, lm.Bc, j * sc.physics_dt) for j in range(1, sc.substeps + 1)]
    rng = np.random.default_rng(0)
    for direction in rng.normal(size=(6, 4)):
        lo, hi = 0.0, 1.0
        while cert_mod.check(np, cert, hi * direction, _Acc, True, 0)[0]:
            hi *= 2
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            inside = cert_mod.check(np, cert, mid * direction, _Acc, True, 0)[0]
            lo, hi = (mid, hi) if inside else (lo, mid)
        assert not cert_mod.check(np, cert, 1.01 * hi * direction, _Acc, True, 0)[0]
        x = lo * direction
        worst = 0.0
        for _ in range(sc.n_control):
            u = -K @ x
            for Aj, Bj in substeps:
                xj = Aj @ x + Bj @ u
                use = np.concatenate(
                    [
                        np.abs(to_q @ xj[:2]) / sc.settle_angle_tol,
                        np.abs(to_q @ xj[2:]) / sc.settle_rate_tol,
                    ]
                )
                worst = max(worst, use.max())
            assert (u >= qp.input_lower).all() and (u <= qp.input_upper).all()
            x = lm.A @ x + lm.B @ u
        assert worst <= cert_mod.MARGIN * (1 + 1e-6)


def test_certificate_needs_the_push_over_and_a_live_scenario():
    _, _, cert = linear_setup()
    x = np.zeros(4)
    assert cert_mod.check(np, cert, x, _Acc, True, 0)[0]
    assert not cert_mod.check(np, cert, x, _Acc, False, 0)[0]

    class Dead(_Acc):
        alive = False

    assert not cert_mod.check(np, cert, x, Dead, True, 0)[0]


class _Still(_Acc):
    """Running peaks of a push that moved nothing beyond the rest jitter."""

    peak_ankle = peak_hip = 1e-6  # rad
    peak_tau_ankle = peak_tau_hip = 0.01  # N m
    peak_foot_pitch = 3e-7  # rad


def _scaled_to(cert, direction, column, value):
    """``direction`` scaled so that the check's bound on quantity ``column`` is ``value`` (the
    bound is linear in the state: the prediction and the level-set tail scale alike)."""
    pred = np.einsum("nqi,i->nq", cert.rows, direction)
    tail = np.sqrt(cert_mod.GROWTH * (direction @ cert.tail @ direction)) * cert.tail_reach
    size = np.maximum(np.abs(pred).max(axis=0), tail) / cert_mod.MARGIN
    return direction * value / size[column]


def test_near_zero_pushes_are_certified_under_the_noise_floors():
    """Rule 5 of certificate.py: with running peaks below their noise floors (a push that moved
    nothing beyond the rest jitter), a state whose predicted future stays below the floors is
    certified (before the rule, the foot pitch's bound, never below PITCH_FLOOR, kept such a
    push running to t_end); scaled until one bound passes its floor it is not, though the same
    state is certified where the peaks recorded are larger; a state that leaves the settle band
    is not certified whatever the peaks."""
    _, _, cert = linear_setup()
    assert cert_mod.check(np, cert, np.zeros(4), _Still, True, 0)[0]
    floors = {
        0: cert_mod.ANGLE_FLOOR,
        1: cert_mod.ANGLE_FLOOR,
        4: cert_mod.TORQUE_FLOOR,
        5: cert_mod.TORQUE_FLOOR,
        6: cert_mod.COP_FLOOR,
    }
    for direction in np.random.default_rng(1).normal(size=(6, 4)):
        # the state at which the first bound reaches its floor
        first = min(floors, key=lambda c: np.linalg.norm(_scaled_to(cert, direction, c, floors[c])))
        x = _scaled_to(cert, direction, first, floors[first])
        assert cert_mod.check(np, cert, 0.99 * x, _Still, True, 0)[0]
        assert not cert_mod.check(np, cert, 1.01 * x, _Still, True, 0)[0], first
        assert cert_mod.check(np, cert, 1.01 * x, _Acc, True, 0)[0]
        out = _scaled_to(cert, direction, 0, 1.01 * cert.band[0])
        assert not cert_mod.check(np, cert, out, _Still, True, 0)[0]
        assert not cert_mod.check(np, cert, out, _Acc, True, 0)[0]


def test_a_push_of_zero_newtons_is_over_from_its_start():
    assert cert_mod.push_over(0, 500, 0.0) and cert_mod.push_over(0, 500, -0.0)
    assert not cert_mod.push_over(0, 500, 1e-6)
    assert not cert_mod.push_over(499, 500, 3.0) and cert_mod.push_over(500, 500, 3.0)


def test_no_certificate_with_a_delay_or_a_hip_servo():
    assert cert_mod.applies(Config())
    assert not cert_mod.applies(Config().replace(scenario={"controller_delay": 0.01}))
    assert not cert_mod.applies(
        Config().replace(body={"hip_servo_stiffness": 100.0, "hip_servo_damping": 10.0})
    )


TWO_DEVICES = textwrap.dedent("""
    import json, sys
    import numpy as np
    import mjx_balance
    import jax
    from mjx_balance.model.params import Config
    from mjx_balance.rollout import BatchRunner
    forces, durations = (np.array(v) for v in json.loads(sys.argv[1]))
    runner = BatchRunner(Config().replace(scenario={"t_end": 3.0}), slots=8)
    out = runner.run(forces, durations)
    print(json.dumps({"devices": len(jax.devices()),
                      **{k: np.asarray(v, float).tolist() for k, v in out.items()}}))
""")


def _run_child(env_flags, forces, durations):
    env = dict(os.environ, XLA_FLAGS=env_flags, MJX_BALANCE_HOST_DEVICES="1")
    arg = json.dumps([forces.tolist(), durations.tolist()])
    proc = subprocess.run(
        [sys.executable, "-c", TWO_DEVICES, arg],
        env=env,
        text=True,
        capture_output=True,
        timeout=600,
        check=True,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # tens of seconds on 2 cores: .ci/run runs it after the default suite
def test_one_and_two_host_devices_give_the_same_bits():
    forces = np.array([0.0, 20.0, 60.0, 90.0, 120.0, -40.0, 10.0, 150.0, 30.0, 80.0])
    durations = np.array([0.1, 0.2, 0.2, 0.1, 0.3, 0.2, 2.0, 0.05, 0.5, 0.15])
    one = _run_child("", forces, durations)
    two = _run_child("--xla_force_host_platform_device_count=2", forces, durations)
    assert (one.pop("devices"), two.pop("devices")) == (1, 2)
    for column in one:
        assert np.array_equal(np.array(one[column]), np.array(two[column]), equal_nan=True), column


def test_interrupted_sweep_resumes_to_the_same_bytes(tmp_path):
    """A sweep killed after its first chunk file, resumed, equals an uninterrupted one with
    another chunk size, byte for byte (region.parquet)."""
    from support import held_sweep

    from mjx_balance.runs import LazyBatch

    config = Config().replace(scenario={"t_end": 2.0})
    forces, durations = np.array([0.0, 30.0, 70.0, 100.0, -50.0]), np.array([0.1, 0.2, 1.0])

    class Interrupted(LazyBatch):
        def stream(self, f, d):
            for i, item in enumerate(super().stream(f, d)):
                yield item
                if i == 1:
                    raise KeyboardInterrupt

    with jax.enable_x64(False):
        with pytest.raises(KeyboardInterrupt):
            held_sweep(
                tmp_path / "a",
                config,
                Grid.of(forces, durations, config),
                chunk=4,
                run_batch=Interrupted(config, slots=ENGINE_SLOTS),
                progress=False,
                say=None,
            )
        assert any((tmp_path / "a" / "chunks").glob("chunk-*.parquet"))
        resumed = held_sweep(
            tmp_path / "a",
            config,
            Grid.of(forces, durations, config),
            run_batch=LazyBatch(config, slots=ENGINE_SLOTS),
            progress=False,
            say=None,
        )
        assert resumed.reused_chunks >= 1
        whole = held_sweep(
            tmp_path / "b",
            config,
            Grid.of(forces, durations, config),
            chunk=16,
            run_batch=LazyBatch(config, slots=ENGINE_SLOTS),
            progress=False,
            say=None,
        )
    assert resumed.region_path.read_bytes() == whole.region_path.read_bytes()
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["region"]["engine"] == {
        "slots": ENGINE_SLOTS,
        "early_stop": True,
        "physics": "mjx",
    }
    assert len(pd.read_parquet(whole.region_path)) == forces.size * durations.size


@pytest.mark.slow
def test_early_stopping_on_a_larger_grid():
    """As test_early_stopping_changes_no_decided_column on 600 cells: forces -100..150 N,
    durations 0.01-10 s (log-spaced), and a 0-N cell (the rest jitter's energy)."""
    from mjx_balance.rollout import BatchRunner

    forces = np.linspace(-100.0, 150.0, 30)
    durations = np.round(np.geomspace(0.01, 10.0, 20) / 0.002) * 0.002
    f, d = np.repeat(forces, durations.size), np.tile(durations, forces.size)
    f, d = np.append(f, 0.0), np.append(d, 0.1)
    out = {}
    with jax.enable_x64(False):
        for name, early in (("early", True), ("full", False)):
            runner = BatchRunner(Config(), early_stop=early)
            out[name] = runner.run(f, d)
            out[name + "_certified"] = runner.last_certified
    plain = ~out["early_certified"]
    for column in (*EXACT, *INTEGRALS):
        assert np.array_equal(
            out["early"][column][plain], out["full"][column][plain], equal_nan=True
        ), column
    assert_certified_like_full_length(
        out["early"], out["full"], out["early_certified"], Config(), _jitter(f, out["full"])
    )
    for column in ("cop_min", "cop_max", "com_min", "com_max"):
        within(
            out["early"][column],
            out["full"][column],
            atol=EXTREME_ATOL[column[:3]],
            msg=column,
            why="the settle band's reach through the CoP/CoM map (margins.band_excursion)",
        )


def test_a_damaged_engine_record_is_a_bad_manifest():
    from mjx_balance.store.folder import manifest_problem

    region = {"forces": [0.0], "durations": [0.1], "chunk_size": 8, "cells": 1}
    good = {
        "region": {**region, "engine": {"slots": 8, "early_stop": True, "physics": "c"}},
        "table_engine": {"slots": 32, "early_stop": False},
    }
    assert manifest_problem(good) == ""
    for bad in (
        {"slots": "8", "early_stop": True},
        {"slots": 0, "early_stop": True},
        {"slots": 8, "early_stop": 1},
        [8, True],
        {"slots": 8, "early_stop": True, "physics": "gpu"},
    ):
        assert "engine" in manifest_problem({"region": {**region, "engine": bad}})
        assert "table_engine" in manifest_problem({"table_engine": bad})


def test_no_cells_is_an_empty_table_without_a_compile():
    from mjx_balance.rollout import BatchRunner

    with jax.enable_x64(False):
        runner = BatchRunner(Config().replace(scenario={"t_end": 0.1}), slots=8)
        frame = runner.run_frame(np.zeros(0), np.zeros(0))
    assert frame.empty and list(frame.columns) == SUMMARY_COLUMNS
    assert not runner.is_prepared()


def test_huge_values_diverge_the_batched_path():
    """A push that sends MuJoCo beyond its bound (mjMAXVAL, which the scalar reference sees as
    a "huge value" warning) is ``diverged`` on the batched path, as in the reference."""
    from mjx_balance.measures.outcomes import OUTCOMES
    from mjx_balance.reference.loop import simulate_scenario
    from mjx_balance.rollout import BatchRunner

    # a 1-s window: the engine's calls run 100 periods, as for every test of conftest's
    # ENGINE_SLOTS (one compiled engine); 50 N x 0.1 s has not settled by then (~1.2 s)
    config = Config().replace(scenario={"t_end": 1.0})
    with jax.enable_x64(False):
        result = BatchRunner(config, slots=ENGINE_SLOTS, devices=jax.local_devices()[:1]).run(
            np.array([1e12, 50.0]), np.array([0.1, 0.1])
        )
    outcomes = [OUTCOMES[int(code)] for code in result["outcome"]]
    reference, _ = simulate_scenario(config, 1e12, 0.1, record=False)
    assert reference["outcome"] == "diverged"
    assert outcomes == ["diverged", "not_settled"], result
    assert np.isnan(result["fall_time"][0])
