"""Tolerances of the test suite, and the margin audit that records how much of each is used.

``within(actual, desired, rtol=, atol=, why=)`` is the suite's tolerance check: it asserts
|actual - desired| <= atol + rtol |desired| elementwise (NaN equal to NaN, as
``numpy.testing.assert_allclose``), ``why`` says where the tolerance comes from. With the
environment variable ``MJX_BALANCE_MARGIN_AUDIT`` naming a file, every call appends one JSON
line: the calling test file and line, the test's node id, rtol, atol, the measured ratio
max |a - d| / (atol + rtol |d|) and ``why``. conftest.py records ``numpy.testing.assert_allclose``
and ``pytest.approx`` the same way while the variable is set.

A tolerance is derived from a stated bound (float32 accumulation, a solver's tolerance, a step
count), never from what one machine measured: the functions below are those bounds, and
docs/reliability.md ("Margin audit") lists every site with its measured ratio. A site whose
ratio exceeds 1/3 on the audit machine needs a derived bound, because another CPU (another
vector width, another summation order) may use more of it.

    MJX_BALANCE_MARGIN_AUDIT=/tmp/margins.jsonl pytest -q -p no:cacheprovider
    python tests/margins.py /tmp/margins.jsonl      # the largest ratio of every call site
"""

from __future__ import annotations

import inspect
import json
import math
import os
from pathlib import Path

import numpy as np

AUDIT_VARIABLE = "MJX_BALANCE_MARGIN_AUDIT"
EPS_FLOAT32 = 2.0**-23  # float32's machine epsilon (the spacing of numbers in [1, 2))
_TESTS = Path(__file__).resolve().parent
_HELPERS = {Path(__file__).resolve(), (_TESTS / "conftest.py").resolve()}


# --------------------------------------------------------------------------------------------
# The check and the recorder


def ratio(actual, desired, rtol: float = 0.0, atol: float = 0.0) -> float:
    """max |a - d| / (atol + rtol |d|) over the elements (0 where a == d or both are NaN;
    inf where they differ and the allowance is 0, or only one is NaN)."""
    a = np.asarray(actual, dtype=float)
    d = np.asarray(desired, dtype=float)
    a, d = np.broadcast_arrays(a, d)
    if a.size == 0:
        return 0.0
    both_nan = np.isnan(a) & np.isnan(d)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        diff = np.where((a == d) | both_nan, 0.0, np.abs(a - d))
        diff = np.where(np.isnan(diff), np.inf, diff)  # one NaN, or inf against -inf
        allowed = atol + rtol * np.abs(d)
        used = np.where(diff == 0, 0.0, diff / np.where(allowed > 0, allowed, 0.0))
    return float(np.nanmax(np.where(np.isnan(used), np.inf, used)))


def within(
    actual, desired, *, rtol: float = 0.0, atol: float = 0.0, why: str, msg: object = None
) -> None:
    """Assert |actual - desired| <= atol + rtol |desired| elementwise (NaN equal to NaN);
    ``why``: the bound the tolerance comes from; ``msg``: context for the failure message."""
    used = ratio(actual, desired, rtol, atol)
    record(kind="within", rtol=rtol, atol=atol, used=used, why=why)
    if not used <= 1.0:
        a, d = np.broadcast_arrays(
            np.asarray(actual, dtype=float), np.asarray(desired, dtype=float)
        )
        lone_nan = int(np.sum(np.isnan(a) != np.isnan(d)))
        with np.errstate(invalid="ignore"):
            diff = np.abs(a - d)[~(np.isnan(a) | np.isnan(d))]
        worst = diff.max() if diff.size else 0.0
        raise AssertionError(
            f"not within rtol={rtol:g}, atol={atol:g} ({why}): max |actual - desired| = "
            f"{worst:.3g}, {used:.3g} times the tolerance"
            + (f", {lone_nan} NaN against a number" if lone_nan else "")
            + ("" if msg is None else f"; {msg}")
            + (f"\nactual:  {actual}\ndesired: {desired}" if np.size(a) <= 8 else "")
        )


def record(*, kind: str, rtol: float, atol: float, used: float, why: str | None) -> None:
    """Append one audit line (when MJX_BALANCE_MARGIN_AUDIT names a file)."""
    target = os.environ.get(AUDIT_VARIABLE)
    if not target:
        return
    file, line, code = _caller()
    test = os.environ.get("PYTEST_CURRENT_TEST", "")
    if file == "?":  # not called from a test (pytest's own use of approx, say)
        return
    entry = {
        "file": file,
        "line": line,
        "test": test.rsplit(" (", 1)[0],
        "kind": kind,
        "rtol": float(np.max(rtol)),
        "atol": float(np.max(atol)),
        "ratio": used if math.isfinite(used) else str(used),
        "why": why,
        "code": code,
    }
    with open(target, "a", encoding="utf-8") as out:
        out.write(json.dumps(entry) + "\n")


def _caller() -> tuple[str, int, str]:
    """The innermost frame in a test file (not this module, not conftest.py)."""
    frame = inspect.currentframe()
    try:
        while frame is not None:
            path = Path(frame.f_code.co_filename).resolve()
            if path.parent == _TESTS and path not in _HELPERS:
                info = inspect.getframeinfo(frame, context=1)
                code = info.code_context[0].strip() if info.code_context else ""
                return f"tests/{path.name}", frame.f_lineno, code
            frame = frame.f_back
        return "?", 0, ""
    finally:
        del frame


# --------------------------------------------------------------------------------------------
# Bounds the tolerances are derived from


def admm_rounding(controller) -> float:
    """Relative difference of one control period's input between two runs of the same float32
    ADMM compiled for different batch sizes (the batched path's slots against the reference's
    one): every iteration's products are dot products of length at most k = n + m (n = 2 x
    horizon inputs, m = 6 x horizon constraint rows), each rounded in whatever order the
    program's vector code sums, within gamma_k ~ k eps_float32 of the exact one (Higham,
    "Accuracy and Stability of Numerical Algorithms", 2nd ed., eq. 3.5); over at most
    admm_max_iter iterations, with no credit for the ADMM's contraction: k eps admm_max_iter
    (1.9e-3 for the defaults: 160 x 1.19e-7 x 100)."""
    n, m = 2 * controller.horizon, 6 * controller.horizon
    return (n + m) * EPS_FLOAT32 * controller.admm_max_iter


def unstable_rate(config) -> float:
    """lambda_max (1/s): the largest real part among the eigenvalues of the linear model's
    continuous A (8.75 /s for the default body): the fastest a difference between two runs
    grows where the controller does not hold the body."""
    from mjx_balance.model.linear import linear_model

    lm = linear_model(config.body, config.controller.convention, config.scenario.control_dt)
    return float(np.linalg.eigvals(lm.Ac).real.max())


SENSITIVE_COLUMNS = (
    "energy_ankle",
    "energy_hip",
    "energy_u1",
    "energy_u2",
    "peak_ankle",
    "peak_hip",
    "cop_min",
    "cop_max",
    "com_min",
    "com_max",
)


def input_gains(config, force: float, duration: float, t_end: float) -> dict[str, float]:
    """How much a closed loop amplifies a relative error in its inputs into its summary: for
    each of SENSITIVE_COLUMNS, sum_k,i |d column / d u_k,i| |u_k,i| / |column|, the relative
    change of the column when every input of every period is off by a relative error of 1 with
    the worst sign (to first order; 0 where the column is 0).

    Computed on the linear model, where the MPC near rest is the LQR of its terminal weight
    (certificate.lqr_gain), with the push held over whole control periods and the summary taken
    at the periods' ends, to ``t_end``: the gain of the stable loop, without the QP's active
    constraints. The loop is linear, so the finite differences are exact to round-off."""
    from mjx_balance.bench.states import push_input
    from mjx_balance.control.certificate import lqr_gain
    from mjx_balance.control.qp import build_qp

    sc = config.scenario
    qp = build_qp(config.controller, config.body, sc.control_dt)
    lm, K, push = qp.linear, lqr_gain(qp, config.controller.r_diag), push_input(qp, config.body)
    periods = max(1, int(round(t_end / sc.control_dt)))
    h = 1e-7
    # trajectory 0 is the nominal one; 1 + 2k + i has input i of period k scaled by (1 + h)
    x = np.zeros((1 + 2 * periods, 4))
    energy = np.zeros((1 + 2 * periods, 4))
    peak = np.zeros((1 + 2 * periods, 2))
    low = np.zeros((1 + 2 * periods, 2))  # CoP and CoM extremes from rest (0)
    high = np.zeros((1 + 2 * periods, 2))
    rows = np.arange(2)
    for k in range(periods):
        u = -x @ K.T
        u[1 + 2 * k + rows, rows] += h * np.abs(u[0])
        f = force if k * sc.control_dt < duration else 0.0
        x_next = x @ lm.A.T + u @ lm.B.T + f * push
        q, q_next = lm.joints_from_state(x)[0], lm.joints_from_state(x_next)[0]
        tau = lm.motor_torques(u)
        energy += np.abs(np.concatenate([tau * (q_next - q), u * (x_next - x)[:, :2]], axis=1))
        peak = np.maximum(peak, np.abs(q_next))
        places = np.stack([x_next @ lm.cop_x + u @ lm.cop_u, x_next @ lm.com_x], axis=1)
        low, high = np.minimum(low, places), np.maximum(high, places)
        x = x_next
    columns = np.concatenate(
        [energy, peak, low[:, :1], high[:, :1], low[:, 1:], high[:, 1:]], axis=1
    )
    nominal = np.abs(columns[0])
    effect = np.abs(columns[1:] - columns[0]).sum(axis=0) / h
    gains = np.divide(effect, nominal, out=np.zeros_like(effect), where=nominal > 0)
    return dict(zip(SENSITIVE_COLUMNS, gains.tolist()))


def closed_loop_rounding(config, row, force: float, duration: float) -> dict[str, float]:
    """Relative tolerances of the energies and peaks of SENSITIVE_COLUMNS, and of the CoP's and
    CoM's extremes ("cop", "com": relative to the larger of |min| and |max|), for a closed loop
    run by the batched path and by the reference with the same float32 ADMM, ``row`` the
    reference's summary.

    Every period's inputs differ by at most :func:`admm_rounding` (relative); while the MPC's
    QP is feasible the loop is stable and turns that into at most :func:`input_gains` times as
    much relative error in a column; a run that falls leaves upright along the unstable mode
    once its QP has no solution, and from its first infeasible QP to its fall sample a
    difference grows by at most exp(lambda_max (fall_time - first_infeasible_time))
    (:func:`unstable_rate`); a fall without an infeasible QP is charged the whole time. Without
    a push, 1 (below)."""
    base = admm_rounding(config.controller)
    t_end, growth = config.scenario.t_end, 1.0
    if row["outcome"] == "fell":
        start = row["first_infeasible_time"]
        start = 0.0 if start is None or math.isnan(start) else float(start)
        t_end = max(start, config.scenario.control_dt)
        growth = math.exp(unstable_rate(config) * (float(row["fall_time"]) - start))
    gains = input_gains(config, force, duration, t_end)
    if not any(gains.values()):
        # no push: the body stays at rest, where the inputs are the ADMM's noise at its
        # absolute tolerance (eps_abs 1e-7; ~2e-7 N m seen) and two roundings give unrelated
        # noise: the runs' extremes (~1e-9 m of CoP) agree in size only
        return {
            column: 1.0
            for column in (
                "energy_ankle",
                "energy_hip",
                "energy_u1",
                "energy_u2",
                "peak_ankle",
                "peak_hip",
                "cop",
                "com",
            )
        }
    out = {column: base * gain * growth for column, gain in gains.items()}
    # an extreme on the side the push did not drive may stay at rest in the linear model
    # (gain 0): both extremes are points of one trajectory, whose error is relative to its
    # largest excursion (the caller scales "cop" and "com" by max |extreme|)
    for place in ("cop", "com"):
        out[place] = max(out.pop(f"{place}_min"), out.pop(f"{place}_max"))
    return out


def kinematics_rounding(config) -> float:
    """Absolute error (m) of a position computed by float32 kinematics (MJX) where float64 would
    be exact: each of the 3 bodies of the chain (foot, lower, upper) adds a rotation and a
    position, two 3-term products (gamma_3 = 3 eps_float32 each) on lengths up to the body's
    whole reach (foot + lower + upper): 3 x 2 x 3 eps x reach (4.1e-6 m for the default body)."""
    body = config.body
    reach = body.foot_length + body.lower_length + body.upper_length
    return 3 * 2 * 3 * EPS_FLOAT32 * reach


def band_excursion(config) -> dict[str, float]:
    """How far the CoP and the CoM can be from rest while the joints stay inside the settle band
    (|q| <= settle_angle_tol, |dq| <= settle_rate_tol), the MPC being the LQR there (the
    certified set, docs/engine.md): max over the band of |cop_x x + cop_u u|, u = -K x, and of
    |com_x x| in the linear model (m)."""
    from mjx_balance.control.certificate import lqr_gain
    from mjx_balance.control.qp import build_qp

    sc = config.scenario
    qp = build_qp(config.controller, config.body, sc.control_dt)
    lm, K = qp.linear, lqr_gain(qp, config.controller.r_diag)
    eye, zero = np.eye(2), np.zeros((2, 2))
    per_angle, per_rate = lm.state_from_joints(eye, zero), lm.state_from_joints(zero, eye)
    out = {}
    for name, row in (("cop", lm.cop_x - lm.cop_u @ K), ("com", lm.com_x)):
        out[name] = float(
            np.abs(per_angle @ row).sum() * sc.settle_angle_tol
            + np.abs(per_rate @ row).sum() * sc.settle_rate_tol
        )
    return out


# --------------------------------------------------------------------------------------------
# The audit's summary


def summarise(path: str | os.PathLike) -> list[dict]:
    """One row per call site (file:line): the largest ratio over its calls, its tests, its
    tolerances and why; sorted by the ratio, largest first."""
    sites: dict[tuple[str, int], dict] = {}
    for text in Path(path).read_text(encoding="utf-8").splitlines():
        entry = json.loads(text)
        used = float(entry["ratio"])
        key = (entry["file"], entry["line"])
        site = sites.setdefault(
            key,
            {
                "file": entry["file"],
                "line": entry["line"],
                "kind": entry["kind"],
                "code": entry["code"],
                "ratio": 0.0,
                "calls": 0,
                "tests": set(),
                "rtol": set(),
                "atol": set(),
                "why": entry["why"],
            },
        )
        site["calls"] += 1
        site["tests"].add(entry["test"].split("::", 1)[-1])
        site["rtol"].add(entry["rtol"])
        site["atol"].add(entry["atol"])
        if not used <= site["ratio"]:
            site["ratio"], site["worst_test"] = used, entry["test"]
    return sorted(sites.values(), key=lambda s: -s["ratio"])


def main(argv: list[str] | None = None) -> None:
    import sys

    args = sys.argv[1:] if argv is None else argv
    rows = summarise(args[0] if args else os.environ[AUDIT_VARIABLE])
    for s in rows:
        tol = "/".join(f"{r:g}" for r in sorted(s["rtol"]))
        atol = "/".join(f"{a:.3g}" for a in sorted(s["atol"]))
        print(
            f"{s['ratio']:9.3g}  {s['file']}:{s['line']}  [{s['kind']}, {s['calls']} calls, "
            f"rtol {tol}, atol {atol}]  {s['code'][:90]}"
        )
    over = sum(s["ratio"] > 1 / 3 for s in rows)
    print(f"{len(rows)} call sites, {over} above 1/3 of their tolerance")


if __name__ == "__main__":
    main()


def capture_window(config, frame, force: float, duration: float, at: float, samples: int):
    """The one-step capture margins (measures/capture.py) of a reference run's recorded
    capture point (``frame``: its time series, with ``xcom``) at every sample within
    ``samples`` of the decision instant ``at`` [s]: another path whose decision instant lies
    within those samples must report one of them, up to its own rounding of the capture point.
    Returns (smallest, largest)."""
    import numpy as np

    from mjx_balance.measures import capture
    from mjx_balance.model.params import push_steps

    model = capture.step_model(config)
    time = frame["time"].to_numpy()
    i = int(np.argmin(np.abs(time - at)))
    near = slice(max(0, i - samples), min(time.size, i + samples + 1))
    remaining = push_steps(duration, model.physics_dt) * model.physics_dt - time[near]
    margin, _ = capture.margins(model, frame["xcom"].to_numpy()[near], force, remaining, 1)
    return float(margin.min()), float(margin.max())
