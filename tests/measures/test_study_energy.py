"""The two energy definitions on a trajectory small enough to compute by hand.

Paper convention: x = [q1, q2, ...] (absolute tilts), u = [tau1, tau2] (generalised forces),
motor torques tau_ankle = tau1 + tau2, tau_hip = tau2, joint angles q_a = q1, q_h = q2 - q1.
Four samples of a constant input u = (10, -40) N m, so tau_ankle = -30, tau_hip = -40 N m, with
the increments

    step          1      2      3       4
    Δq1        +0.02  +0.01  -0.01  -0.005      q1: 0.02, 0.03, 0.02, 0.015
    Δq2        +0.03  -0.01  -0.01   0          q2: 0.03, 0.02, 0.01, 0.01
    Δq_a = Δq1 +0.02  +0.01  -0.01  -0.005
    Δq_h       +0.01  -0.02   0     +0.005      q_h: 0.01, -0.01, -0.01, -0.005

The study's energy (eq. 20, docs/model.md) is |Σ u_i Δx_i| per pair; the package's absolute
work Σ |τ Δq| is given for the convention's pairs (energy_u1/u2) and for the motors
(energy_ankle/hip). Every expected number below is worked out by hand from this table.
"""

from __future__ import annotations

import types

import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from margins import within

from mjx_balance.control import certificate
from mjx_balance.measures import metrics
from mjx_balance.measures.outcomes import SUMMARY_COLUMNS, Limits
from mjx_balance.model.params import Config
from mjx_balance.reference import loop as reference
from mjx_balance.rollout import kernel, runner, sensing

U = (10.0, -40.0)
TAU = (-30.0, -40.0)  # tau1 + tau2, tau2
Q1 = [0.02, 0.03, 0.02, 0.015]
Q2 = [0.03, 0.02, 0.01, 0.01]
QA = Q1
QH = [0.01, -0.01, -0.01, -0.005]

# by hand, from the table in the module docstring
EXPECTED = {
    # signed work of the pairs (u_i, x_i): 10 (0.02 + 0.01 - 0.01 - 0.005) = 0.15,
    # -40 (0.03 - 0.01 - 0.01 + 0) = -0.4
    "work_u1": 0.15,
    "work_u2": -0.4,
    # the study's energy: their magnitudes, and the sum of the two
    "study_energy_u1": 0.15,
    "study_energy_u2": 0.4,
    "study_energy_total": 0.55,
    # absolute work of the same pairs: 10 (0.02 + 0.01 + 0.01 + 0.005) = 0.45,
    # 40 (0.03 + 0.01 + 0.01 + 0) = 2.0
    "energy_u1": 0.45,
    "energy_u2": 2.0,
    # the motors: 30 (0.045) = 1.35 and 40 (0.01 + 0.02 + 0 + 0.005) = 1.4 absolute,
    # -30 (0.015) = -0.45 and -40 (0.01 - 0.02 + 0 + 0.005) = 0.2 signed
    "energy_ankle": 1.35,
    "energy_hip": 1.4,
    "energy_total": 2.75,
    "work_ankle": -0.45,
    "work_hip": 0.2,
}
# the cumulative study energy after each sample: |10 (0.02, 0.03, 0.02, 0.015)|,
# |-40 (0.03, 0.02, 0.01, 0.01)|
CUMULATIVE_1 = [0.2, 0.3, 0.2, 0.15]
CUMULATIVE_2 = [1.2, 0.8, 0.4, 0.4]
CONFIG = Config()  # the paper convention


def _series():
    n = len(Q1)
    x = np.zeros((n, 4))
    x[:, 0], x[:, 1] = Q1, Q2
    q = np.stack([QA, QH], axis=1)
    return {
        "q": q,
        "x": x,
        "tau": np.tile(TAU, (n, 1)),
        "u": np.tile(U, (n, 1)),
        "time": (np.arange(n) + 1) * CONFIG.scenario.physics_dt,
    }


def test_the_hand_trajectory_is_one_of_the_paper_convention():
    s = _series()
    # np.allclose's tolerances on hand-written values
    within(
        s["tau"][:, 0],
        s["u"][:, 0] + s["u"][:, 1],
        rtol=1e-5,
        atol=1e-8,  # tau1 + tau2
        why="tau_ankle = tau1 + tau2 exactly in the hand values, float64 round-off",
    )
    within(
        s["q"][:, 1],
        s["x"][:, 1] - s["x"][:, 0],
        rtol=1e-5,
        atol=1e-8,  # q_h = q2 - q1
        why="q_h = q2 - q1 exactly in the hand values, float64 round-off",
    )
    # virtual work: the two pairs of signed work add up to the same total
    assert EXPECTED["work_u1"] + EXPECTED["work_u2"] == pytest.approx(
        EXPECTED["work_ankle"] + EXPECTED["work_hip"]
    )


def test_reference_summary_gives_each_definition():
    s = _series()
    n = len(Q1)
    row = metrics.summarize(
        force=0.0,
        duration=0.1,
        convention="paper",
        scenario=CONFIG.scenario,
        controller=CONFIG.controller,
        time=s["time"],
        q=s["q"],
        dq=np.zeros((n, 2)),
        x=s["x"],
        foot_pitch=np.zeros(n),
        cell_low_z=np.zeros((n, 4)),
        cop=np.zeros(n),
        com=np.zeros(n),
        tau=s["tau"],
        u=s["u"],
        q0=np.zeros(2),
        x0=np.zeros(4),
        u_control=np.array([U]),
        converged=np.array([True]),
        residual=np.array([0.0]),
        completed=False,
    )
    assert set(row) == set(SUMMARY_COLUMNS)
    for key, value in EXPECTED.items():
        within(
            row[key],
            value,
            atol=1e-12,
            msg=key,
            why="hand values of a few terms, summed in float64 (a few ulps)",
        )


def test_batched_accumulators_give_each_definition():
    """The kernel's sample_update, step by step, then the host summary (runner.summarize)."""
    s = _series()
    limits = Limits.from_params(CONFIG.scenario, CONFIG.controller)
    acc = kernel.Accumulators.initial(jnp.float32)
    q_prev, x_prev = jnp.zeros(2, jnp.float32), jnp.zeros(4, jnp.float32)
    for i in range(len(Q1)):
        q, x = jnp.asarray(s["q"][i], jnp.float32), jnp.asarray(s["x"][i], jnp.float32)
        sample = sensing.Sample(
            q=q,
            dq=jnp.zeros(2, jnp.float32),
            x=x,
            pitch=jnp.float32(0),
            cell_low=jnp.zeros(4, jnp.float32),
            cop=jnp.float32(0),
            com=jnp.float32(0),
            magnitude=jnp.float32(0),
        )
        acc = kernel.sample_update(
            acc,
            sample,
            jnp.int32(i),
            jnp.asarray(TAU, jnp.float32),
            jnp.asarray(U, jnp.float32),
            q_prev,
            x_prev,
            limits,
        )
        q_prev, x_prev = q, x
    assert bool(acc.alive)
    summary = runner.summarize(_batch_of_one(acc), CONFIG)
    for key, value in EXPECTED.items():
        within(
            float(summary[key][0]),
            value,
            rtol=1e-5,
            atol=1e-6,
            msg=key,
            why="the same sums of four samples in float32 (a few eps_float32 = 1.2e-7)",
        )


def _batch_of_one(acc):
    """Accumulators of one scenario as a batch of one (runner.summarize takes [B] arrays)."""
    return kernel.Accumulators(*(np.asarray(v)[None] for v in acc))


def test_certificate_tail_integrals_give_each_definition():
    """A certified scenario's predicted future is integrated in the same definitions: the
    same four samples as a prediction from x = 0 (joint angles to_q @ x[:2] = 0)."""
    s = _series()
    n = len(Q1)
    pred = np.zeros((n, 12))
    pred[:, 0:2], pred[:, 4:6] = s["q"], s["tau"]
    pred[:, 8:10], pred[:, 10:12] = s["x"][:, :2], s["u"]
    cert = types.SimpleNamespace(to_q=np.array([[1.0, 0.0], [-1.0, 1.0]]))
    tail = certificate.tail_integrals(np, cert, np.zeros(4), pred, n)
    assert set(tail) == set(certificate.TAIL_FIELDS)
    for key in certificate.TAIL_FIELDS:
        within(
            tail[key],
            EXPECTED[key],
            atol=1e-12,
            msg=key,
            why="hand values of a few terms, summed in float64 (a few ulps)",
        )
    # only the samples before t_end count: two samples left
    short = certificate.tail_integrals(np, cert, np.zeros(4), pred, 2)
    assert short["work_u1"] == pytest.approx(10 * (0.02 + 0.01))
    assert short["work_u2"] == pytest.approx(-40 * (0.03 - 0.01))


def _frame() -> pd.DataFrame:
    """The reference's time-series frame of :func:`_series` (paper convention, at rest)."""
    s = _series()
    n = len(Q1)
    return reference.timeseries_frame(
        0,
        0.0,
        0.1,
        "paper",
        q0=np.zeros(2),
        x0=np.zeros(4),
        time=s["time"],
        q=s["q"],
        dq=np.zeros((n, 2)),
        x=s["x"],
        foot=np.zeros((n, 3)),
        u=s["u"],
        tau=s["tau"],
        cop=np.zeros(n),
        com=np.zeros(n),
    )


def test_time_series_carries_the_cumulative_study_energy():
    frame = _frame()
    np.testing.assert_allclose(frame["study_energy_u1"], CUMULATIVE_1, atol=1e-12)
    np.testing.assert_allclose(frame["study_energy_u2"], CUMULATIVE_2, atol=1e-12)
    np.testing.assert_allclose(
        frame["study_energy_total"], np.add(CUMULATIVE_1, CUMULATIVE_2), atol=1e-12
    )
    # the motors' cumulative absolute work, for comparison: 30 (0.02, 0.03, 0.04, 0.045)
    np.testing.assert_allclose(frame["energy_ankle"], [0.6, 0.9, 1.2, 1.35], atol=1e-12)
    last = frame.iloc[-1]
    for key in (
        "study_energy_u1",
        "study_energy_u2",
        "study_energy_total",
        "energy_ankle",
        "energy_hip",
        "energy_total",
    ):
        within(
            last[key],
            EXPECTED[key],
            atol=1e-12,
            msg=key,
            why="hand values of a few terms, summed in float64 (a few ulps)",
        )


# --- which energy heads the outputs ----------------------------------------------------------


def test_paper_convention_outputs_headline_the_study_energy():
    """Paper convention: the study's energy first in the time-series figure, the weight
    figure, the report tables and table.csv, the motors' beside it; joint: the motors'."""
    from mjx_balance.figures import report as bars
    from mjx_balance.figures import timeseries as plots
    from mjx_balance.report import html
    from mjx_balance.runs import acting_time

    frame = _frame()
    assert plots.energy_rows(frame) == [plots.STUDY_ENERGY, plots.PAIRS["energy"]]
    assert plots.energy_rows(frame.assign(convention="joint")) == [plots.PAIRS["energy"]]
    assert "study's (eq. 20)" in plots.energy_title(plots.energy_rows(frame))

    weights = pd.DataFrame({c: [1.0] for c in SUMMARY_COLUMNS})
    assert bars.weight_rows(weights, "paper")[0][0] is bars.STUDY_BARS
    assert bars.weight_rows(weights, "paper")[1][0] is bars.MOTOR_BARS
    assert [r[0] for r in bars.weight_rows(weights, "joint")] == [bars.MOTOR_BARS]

    for kind, first in (
        ("summary", "study_energy_u1"),
        ("weights", "study_energy_u1"),
        ("table", "study_energy_u1_01"),
    ):
        paper = html.shown_columns(kind, "paper")
        energies = [c for c in paper if "energy" in c]
        assert energies[0] == first, kind
        assert any(c.startswith("energy_total") for c in energies), kind  # the motors' beside
        joint = [c for c in html.shown_columns(kind, "joint") if "energy" in c]
        assert joint[0].startswith("energy_ankle") and not any("study" in c for c in joint)

    paper = acting_time.table_columns("paper")
    joint = acting_time.table_columns("joint")
    assert paper[2] == "study_energy_u1_01" and joint[2] == "energy_ankle_01"
    assert sorted(paper) == sorted(joint) == sorted(acting_time.TABLE_COLUMNS)
