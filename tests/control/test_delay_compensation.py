"""Delay-compensated MPC (``controller.delay_compensation``): the predictor is exact in the
linear plant, and the batched path and the reference compensate alike."""

import jax
import numpy as np
import pytest
import scipy.linalg
from support import AdmmMPC, assert_cells_like_the_reference

from mjx_balance.model.linear import delay_predictor, linear_model, predict, zoh
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import BatchRunner

DELAY = 0.05  # s: 25 physics steps, 5 control periods


pytestmark = pytest.mark.usefixtures("float32_module")  # x64 off (conftest)


@pytest.mark.parametrize("delay_steps", [1, 5, 12, 25, 75])
def test_in_the_linear_plant_the_compensated_loop_is_the_undelayed_loop(delay_steps):
    """Linear plant at the physics step, the controller's gain held over a control period: with
    the measurement d steps old and the compensator, every input and state equals the undelayed
    loop's to round-off. (Before t = 0 the plant ran free from its state at 0, so the delayed
    measurement is defined from the start.)"""
    config = Config()
    sc = config.scenario
    lm = linear_model(config.body, "paper", sc.control_dt)
    Ah, Bh = zoh(lm.Ac, lm.Bc, sc.physics_dt)
    P = scipy.linalg.solve_discrete_are(lm.A, lm.B, np.eye(4) * 1e3, np.diag([1e-1, 1e-4]))
    K = np.linalg.solve(lm.B.T @ P @ lm.B + np.diag([1e-1, 1e-4]), lm.B.T @ P @ lm.A)
    S, n_periods = sc.substeps, 80
    pred_A, pred_G = delay_predictor(lm.Ac, lm.Bc, sc.physics_dt, delay_steps, S)
    x0 = np.array([0.05, -0.03, 0.2, -0.1])
    back = np.linalg.inv(Ah)

    def run(delayed: bool):
        xs = [x0]  # x at physics steps 0, 1, ...
        applied = np.zeros((pred_G.shape[0], 2))
        inputs = []
        for k in range(n_periods):
            i = k * S - (delay_steps if delayed else 0)
            x_meas = xs[i] if i >= 0 else np.linalg.matrix_power(back, -i) @ x0
            if delayed:
                x_meas = predict(np, pred_A, pred_G, x_meas, applied)
            u = -K @ x_meas
            inputs.append(u)
            applied = np.concatenate([u[None], applied[:-1]])
            for _ in range(S):
                xs.append(Ah @ xs[-1] + Bh @ u)
        return np.array(xs), np.array(inputs)

    x_now, u_now = run(False)
    x_late, u_late = run(True)
    assert np.abs(u_now).max() > 1.0  # the loop does something
    np.testing.assert_allclose(u_late, u_now, rtol=0, atol=1e-9 * np.abs(u_now).max())
    np.testing.assert_allclose(x_late, x_now, rtol=0, atol=1e-9 * np.abs(x_now).max())


def test_the_delay_error_is_validated():
    with pytest.raises(ParameterError, match="delay_error"):
        Config().replace(scenario={"controller_delay": 0.01, "delay_error": -0.02})
    with pytest.raises(ParameterError, match="delay_error"):
        Config().replace(scenario={"delay_error": 0.0011})
    sc = Config().replace(scenario={"controller_delay": 0.1, "delay_error": 0.02}).scenario
    assert (sc.delay_steps, sc.assumed_delay_steps) == (60, 50)


CELLS = [(0.0, 0.1), (20.0, 0.1), (40.0, 0.3), (120.0, 0.1)]


# the compensated controller's own compile; the linear-plant check stays in the default run
@pytest.mark.slow
def test_batched_and_reference_compensate_alike():
    """The C path (the reference's physics) and the reference with the same ADMM controller,
    both compensating a 50-ms delay: the same outcomes and fall samples, summaries as close as
    without compensation (tests/rollout/test_cpath.py)."""
    config = Config().replace(
        scenario={"t_end": 2.0, "controller_delay": DELAY}, controller={"delay_compensation": True}
    )
    runner = BatchRunner(
        config, physics="c", slots=4, early_stop=False, devices=jax.local_devices()[:1]
    )
    forces, durations = np.array(CELLS).T
    frame = runner.run_frame(forces, durations)
    mpc = AdmmMPC(runner)
    assert runner.static.compensate
    # The energies' tolerance: the float32 controls' rounding (4 slots here, 1 in the reference:
    # XLA's vector code, which also differs between CPUs) through the stable loop, grown
    # exponentially along the unstable direction after an infeasible QP when it falls
    # (margins.closed_loop_rounding; measured on a 2-core AMD EPYC: 1.2e-3 relative on the
    # falls, 3.8e-6 on recoveries). In the linear plant the compensated loop is the undelayed
    # one (above), whose gain margins.input_gains computes; the predictor, float32 here and
    # float64 in the reference, rounds within gamma_14 (1.7e-6 relative), far below that.
    assert_cells_like_the_reference(config, frame, CELLS, mpc)
    # and compensation is what made the difference: without it the same pushes end otherwise
    # (the reference's plain loop, cheaper than a second compile: 20 N for 0.1 s falls)
    plain = config.replace(controller={"delay_compensation": False})
    outcomes = [
        reference.simulate_scenario(plain, force, duration, record=False, mpc=mpc)[0]["outcome"]
        for force, duration in CELLS
    ]
    assert outcomes != list(frame.outcome)
