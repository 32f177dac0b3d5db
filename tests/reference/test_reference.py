"""Scalar reference closed loop (MuJoCo C + OSQP) and the metrics it reports."""

import math

import mujoco
import numpy as np
import pytest
from margins import within

from mjx_balance.control.osqp_mpc import ReferenceMPC, osqp_solve, osqp_solver
from mjx_balance.control.qp import build_qp
from mjx_balance.measures import metrics
from mjx_balance.measures.outcomes import SUMMARY_COLUMNS, Limits
from mjx_balance.model.mjcf import build_model, indices
from mjx_balance.model.params import Config, ControllerParams, ScenarioParams
from mjx_balance.reference.loop import TIMESERIES_COLUMNS, simulate_scenario

CONVENTIONS = ("paper", "joint")


def short(convention: str, t_end: float, **controller) -> Config:
    return Config().replace(
        controller={"convention": convention, **controller}, scenario={"t_end": t_end}
    )


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_zero_push_stays_upright(convention):
    summary, frame = simulate_scenario(short(convention, 1.0), 0.0, 0.1)
    assert list(summary) == SUMMARY_COLUMNS
    assert summary["outcome"] == "recovered"
    assert summary["settle_time"] == 0.0
    assert math.isnan(summary["fall_time"])
    for key in ("energy_ankle", "energy_hip", "energy_total", "energy_u1", "energy_u2"):
        within(
            summary[key],
            0.0,
            atol=1e-12,
            msg=key,
            why="upright rest: zero torques but for the contact solver's float64 round-off",
        )
    within(
        [summary["peak_ankle"], summary["peak_hip"]],
        0.0,
        atol=1e-12,
        why="upright rest: zero angles but for float64 round-off",
    )
    assert summary["nonconverged_solves"] == 0
    assert list(frame.columns) == TIMESERIES_COLUMNS
    assert len(frame) == 500  # one row per physics step
    np.testing.assert_allclose(frame.time.to_numpy(), 0.002 * np.arange(1, 501))
    within(
        [frame.cop.abs().max(), frame.com.abs().max()],
        0.0,
        atol=1e-9,
        why="upright rest, symmetric contacts: float64 round-off of the contact forces",
    )


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_very_large_push_falls(convention):
    summary, frame = simulate_scenario(short(convention, 2.0), 1000.0, 0.3)
    assert summary["outcome"] == "fell"
    assert 0.0 < summary["fall_time"] <= 0.3 + 1e-9  # it goes over while still pushed
    assert math.isnan(summary["settle_time"])
    # the run stops at the fall sample
    assert frame.time.iloc[-1] == pytest.approx(summary["fall_time"])
    assert np.isfinite(frame.drop(columns=["convention", "cop"]).to_numpy(float)).all()


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_moderate_push_recovers_and_energy_adds_up(convention):
    summary, frame = simulate_scenario(short(convention, 3.0), 20.0, 0.1)
    assert summary["outcome"] == "recovered"
    assert 0.0 <= summary["settle_time"] < 3.0
    last = frame.iloc[-1]
    why = "the same float64 running sum, read at the last sample (a few ulps at most)"
    within(last.energy_ankle, summary["energy_ankle"], rtol=1e-12, why=why)
    within(last.energy_hip, summary["energy_hip"], rtol=1e-12, why=why)
    assert summary["energy_total"] == pytest.approx(summary["energy_ankle"] + summary["energy_hip"])
    assert summary["peak_tau_ankle"] == pytest.approx(frame.tau_ankle.abs().max())
    assert summary["cop_max"] > 0.0  # the forward push moves the CoP forward
    assert summary["max_bound_violation"] == 0.0
    if convention == "joint":  # generalised pairs are the motors themselves
        assert summary["energy_u1"] == pytest.approx(summary["energy_ankle"])
        assert summary["energy_u2"] == pytest.approx(summary["energy_hip"])


def test_scenarios_are_independent():
    config = short("paper", 1.0)
    first, _ = simulate_scenario(config, 50.0, 0.1, record=False)
    simulate_scenario(config, -40.0, 0.2, record=False)
    again, frame = simulate_scenario(config, 50.0, 0.1, record=False)
    assert frame is None
    assert first == again


def test_runs_in_threads_side_by_side_are_the_runs_alone():
    """Explore computes cells' runs side by side in threads: each thread has its own OSQP
    solver (one solver shared by two threads at once gave "Problem data validation" and a
    segfault), so every run is bit for bit the run computed alone."""
    import threading

    config = short("paper", 1.0)
    pushes = [(50.0, 0.1), (-40.0, 0.2), (80.0, 0.05), (20.0, 0.3)]
    alone = [simulate_scenario(config, f, t, record=False)[0] for f, t in pushes]
    side_by_side: dict[int, dict] = {}

    def run(i: int) -> None:
        for _ in range(3):  # long enough to overlap
            side_by_side[i] = simulate_scenario(config, *pushes[i], record=False)[0]

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(pushes))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert [side_by_side[i] for i in range(len(pushes))] == alone


@pytest.mark.parametrize("convention", CONVENTIONS)
def test_qp_with_violated_state_bounds_returns_clipped_control(convention):
    controller = ControllerParams(convention=convention, osqp_max_iter=2000)
    qp = build_qp(controller, Config().body, 0.01)
    mpc = ReferenceMPC(qp, controller)
    # 0.2 rad beyond the upper bound of x[0] and moving away: no input sequence is feasible
    x0 = np.array([0.7, 0.3, 1.0, 0.5])
    u, z, ok, prim_res = mpc.solve(x0)
    assert not ok
    assert np.isfinite(u).all() and np.isfinite(z).all()
    assert (u >= qp.input_lower).all() and (u <= qp.input_upper).all()
    assert np.isfinite(prim_res) and prim_res > 1e-3
    # next solve still works and a feasible state converges
    mpc.reset()
    u, _, ok, _ = mpc.solve(np.array([0.01, 0.0, 0.0, 0.0]))
    assert ok and np.isfinite(u).all()


def test_infeasible_solves_are_counted_in_the_closed_loop():
    # A 100 N push in the paper convention drives the QP infeasible before the fall; a small
    # iteration cap keeps the test fast (each non-converged solve runs to the cap).
    summary, frame = simulate_scenario(short("paper", 2.5, osqp_max_iter=300), 100.0, 0.1)
    assert summary["nonconverged_solves"] > 0
    assert np.isfinite(summary["max_residual"]) and summary["max_residual"] > 1e-3
    assert np.isfinite(frame[["tau_ankle", "tau_hip", "u1", "u2"]].to_numpy()).all()
    assert frame.u1.abs().max() <= 20.0 and frame.u2.abs().max() <= 100.0


@pytest.mark.parametrize(
    "x0, ankle_at_lower_bound",
    [
        ([0.02, 0.03, 0.1, 0.1], True),  # the ankle input rides its lower bound over the horizon
        ([0.002, 0.001, 0.0, 0.0], False),  # every constraint inactive
    ],
    ids=["active_bounds", "interior"],
)
def test_feasible_solve_satisfies_kkt(x0, ankle_at_lower_bound):
    """KKT conditions of the reference's solve, with OSQP's multipliers y (OSQP's sign
    convention: y < 0 on an active lower bound, y > 0 on an active upper one, 0 otherwise):
    H z + q + C^T y = 0, l <= C z <= u, and y vanishes off the active set.

    The multipliers come from the same OSQP set-up (``osqp_mpc.osqp_solver`` with the
    controller's eps 1e-8 and cap), which gives the same iterate as ReferenceMPC. Tolerance 1e-6
    on stationarity: the dual residual of an eps 1e-8 solve (measured 1e-7 at a cost gradient
    of ~10 where the bounds are active)."""
    controller = ControllerParams()
    qp = build_qp(controller, Config().body, 0.01)
    x0 = np.array(x0)
    u, z, ok, prim_res = ReferenceMPC(qp, controller).solve(x0)
    assert ok
    within(
        prim_res,
        0.0,
        atol=1e-6,
        why="OSQP's eps 1e-8 (absolute and relative) on bounds of ~100 N m",
    )
    result = osqp_solve(osqp_solver(qp, controller.osqp_eps, controller.osqp_max_iter), qp, x0)
    np.testing.assert_array_equal(result.x, z)
    y = result.y
    lower, upper = qp.bounds(x0)
    Cz = qp.C @ z
    assert (Cz >= lower - 1e-6).all() and (Cz <= upper + 1e-6).all()
    at_lower, at_upper = Cz - lower < 1e-6, upper - Cz < 1e-6
    ankle_rows = np.arange(qp.rows["inputs"].start, qp.rows["inputs"].stop, 2)
    if ankle_at_lower_bound:
        assert at_lower[ankle_rows].all()
        within(
            u[0],
            qp.input_lower[0],
            atol=1e-6,
            why="an active bound, met to OSQP's primal residual (eps 1e-8 x ~100 N m)",
        )
    else:
        assert not (at_lower | at_upper).any()
    gradient = qp.H @ z + qp.linear_term(x0)
    within(
        gradient + qp.C.T @ y,
        0.0,
        atol=1e-6,  # stationarity
        why="the dual residual of an eps 1e-8 solve at a cost gradient of ~10 (docstring)",
    )
    assert (y[at_lower] < 0).all() and (y[at_upper] > 0).all()  # the multipliers push inwards
    within(
        y[~(at_lower | at_upper)],
        0.0,
        atol=1e-9,  # and vanish off the active set
        why="the multipliers of an eps 1e-8 solve off its active set",
    )
    if ankle_at_lower_bound:  # the active bounds carry the cost gradient
        assert np.abs(gradient).max() > 1.0


# --- metrics -------------------------------------------------------------------------------


def test_load_cell_cop_at_rest():
    model = build_model()
    ix = indices(model)
    data = mujoco.MjData(model)
    for _ in range(200):
        mujoco.mj_step(model, data)
    cop, load = metrics.load_cell_cop(model, data, ix.cell_geoms)
    body = Config().body
    within(cop, 0.0, atol=1e-9, why="symmetric contacts at rest: float64 round-off")
    within(
        load,
        body.total_mass * body.gravity,
        rtol=1e-6,
        why="200 steps from rest settle the contact to MuJoCo's solver tolerance (1e-8)",
    )
    heights = metrics.cell_heights(model, data, ix.cell_geoms)
    assert np.all(heights < 0) and np.all(heights > -1e-3)  # resting, slightly sunk


def test_settle_time_and_saturation_fractions():
    """The series rules of metrics.py (the rules of one sample:
    tests/measures/test_outcomes.py)."""
    limits = Limits.from_params(ScenarioParams(), ControllerParams())
    time = np.array([0.1, 0.2, 0.3, 0.4])
    q = np.array([[0.02, 0.0], [0.0, 0.0], [0.0, 0.011], [0.0, 0.0]])
    dq = np.zeros((4, 2))
    assert metrics.settle_time(time, q, dq, limits) == pytest.approx(0.3)
    assert metrics.settle_time(time, np.zeros((4, 2)), dq, limits) == 0.0
    dq_late = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, -0.06]])  # a rate, last
    assert metrics.settle_time(time, np.zeros((4, 2)), dq_late, limits) == pytest.approx(0.4)
    u = np.array([[20.0, 0.0], [-20.0, 100.0], [19.0, -99.0], [0.0, -100.0]])
    assert metrics.saturation_fractions(u, limits) == (0.5, 0.5)
    assert metrics.saturation_fractions(u[:1], limits) == (1.0, 0.0)
    assert all(math.isnan(v) for v in metrics.saturation_fractions(np.zeros((0, 2)), limits))


# 40 N for 0.1 s, 1-s runs: the push at the hip recovers as the base case does; with a 20-ms
# delay the body still sways at 1 s (peak hip angle ~0.05 rad against ~0.008 undelayed).
EXPECTED_VARIANT_OUTCOME = {"push_body": "recovered", "controller_delay": "not_settled"}


@pytest.mark.parametrize(
    "scenario",
    [{"push_body": "hip"}, {"controller_delay": 0.02}],
    ids=["push_at_hip", "controller_delay"],
)
def test_scenario_variants_run(scenario):
    config = Config().replace(scenario={"t_end": 1.0, **scenario})
    base, _ = simulate_scenario(Config().replace(scenario={"t_end": 1.0}), 40.0, 0.1)
    summary, frame = simulate_scenario(config, 40.0, 0.1)
    assert base["outcome"] == "recovered"
    assert summary["outcome"] == EXPECTED_VARIANT_OUTCOME[next(iter(scenario))]
    assert len(frame) == 500
    assert summary["peak_ankle"] != base["peak_ankle"]  # the variant changes the run
    if "push_body" in scenario:  # same force lower down: less lean
        assert summary["peak_hip"] < base["peak_hip"]
