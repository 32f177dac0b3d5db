"""The recovery certificate's linear part (control/certificate.py), in NumPy: no JAX program.

The margin is a measured design value (docs/engine.md, "Certified recovery"): the linear prediction
of the joint angles must stay within MARGIN = 0.5 of the settle band, because the real plant
used up to 49.8 % of the band after certification when the prediction was held to 50 %. A
change of the margin must be re-measured, so these tests pin it from both sides.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mjx_balance.control import certificate
from mjx_balance.control.qp import build_qp
from mjx_balance.model.params import Config

DOCUMENTED_MARGIN = 0.5  # docs/engine.md: "every prediction must stay within half of its limit"


@pytest.fixture(scope="module")
def cert():
    config = Config()
    ctrl, sc = config.controller, config.scenario
    qp = build_qp(ctrl, config.body, sc.control_dt)
    return certificate.build(qp, ctrl, sc, rest=(0.0, 0.0))


def _settled_acc():
    """Running accumulators of a scenario whose recorded peaks are far above anything the
    prediction reaches: only the band (and the QP's level set) can refuse it."""
    big = 1e9
    return SimpleNamespace(
        peak_ankle=big,
        peak_hip=big,
        peak_tau_ankle=big,
        peak_tau_hip=big,
        peak_foot_pitch=big,
        alive=np.bool_(True),
        in_band=np.bool_(True),
    )


def _band_use(cert, x):
    """The largest share of the settle band the linear prediction from x uses (joint angles
    and rates, the prediction and its tail bound), before the margin."""
    pred = np.einsum("nqi,i->nq", cert.rows, x)
    tail = np.sqrt(certificate.GROWTH * (x @ cert.tail @ x)) * cert.tail_reach
    size = np.maximum(np.maximum(pred.max(axis=0), tail), -np.minimum(pred.min(axis=0), -tail))
    return float((size[:4] / cert.band).max())


@pytest.mark.parametrize(
    "direction", [[1.0, 0.0, 0.0, 0.0], [0.3, -1.0, 0.0, 0.0], [-1.0, -1.0, 0.0, 0.0]]
)
def test_the_margin_is_half_the_settle_band(cert, direction):
    """A state whose predicted joint angles and rates use 49 % of the settle band is certified
    and one that uses 51 % is not (the documented margin, 0.5, from both sides): loosening the
    margin to 0.9, or tightening it to 0.4, fails here."""
    unit = np.asarray(direction, float)
    unit = unit / _band_use(cert, unit)  # uses exactly the whole band
    acc = _settled_acc()
    for use, expected in ((0.98 * DOCUMENTED_MARGIN, True), (1.02 * DOCUMENTED_MARGIN, False)):
        x = use * unit
        # the QP's level set is not what decides here (else the band's margin is untested)
        assert certificate.GROWTH * (x @ cert.P @ x) <= cert.qp_level, use
        ok, _ = certificate.check(np, cert, x, acc, np.bool_(True), 10_000)
        assert bool(ok) is expected, (direction, use)


def test_the_peaks_must_be_final(cert):
    """The same state, certified with room in the band, is refused when a recorded peak lies
    below what the prediction still reaches (the summary would change after the stop)."""
    unit = np.array([1.0, 0.0, 0.0, 0.0])
    x = 0.2 * unit / _band_use(cert, unit)
    acc = _settled_acc()
    assert bool(certificate.check(np, cert, x, acc, np.bool_(True), 10_000)[0])
    acc.peak_ankle = 0.0
    assert not bool(certificate.check(np, cert, x, acc, np.bool_(True), 10_000)[0])
    # and a push still acting is never certified
    assert not bool(certificate.check(np, cert, x, _settled_acc(), np.bool_(False), 10_000)[0])
