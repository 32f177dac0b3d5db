"""The differences from the study, and their measured causes (issue 27.5; docs/study.md).

    python docs/scripts/differences.py relax        # one relaxation at a time, scalar reference
    python docs/scripts/differences.py margins      # the ankle bound from which each push recovers
    python docs/scripts/differences.py sensitivity  # threshold force at 0.1 s and sustained limit
    python docs/scripts/differences.py confirm      # those thresholds on the scalar reference

Each part prints its table (and writes it as CSV under OUT, default out/differences). The
scalar reference (`mb.simulate`: MuJoCo C + OSQP) decides every outcome quoted as "recovers"
or "falls"; the sensitivity table scans forces with the batched path on MuJoCo C physics
(`mb.sweep(..., physics="c")`) and confirms the baseline and the largest movers on the
reference. Run it with `nice -n 10` on a shared machine.
"""
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

import mjx_balance as mb

OUT = Path(sys.argv[2] if len(sys.argv) > 2 else "out/differences")
BASE = mb.Config()
SHOW = ["outcome", "fall_cause", "fall_time", "first_infeasible_time",
        "ankle_saturation_fraction", "hip_saturation_fraction", "peak_ankle", "peak_hip",
        "com_max", "cop_max"]

# One change at a time: (label, the sections to replace).
RELAX = [
    ("baseline", {}),
    ("input1_bounds +-25", {"controller": {"input1_bounds": (-25.0, 25.0)}}),
    ("input1_bounds +-30", {"controller": {"input1_bounds": (-30.0, 30.0)}}),
    ("input2_bounds +-200", {"controller": {"input2_bounds": (-200.0, 200.0)}}),
    ("state1_bounds +-1.5", {"controller": {"state1_bounds": (-1.5, 1.5)}}),
    ("state2_bounds +-2", {"controller": {"state2_bounds": (-2.0, 2.0)}}),
    ("cop_bounds +-1 (MPC only)", {"controller": {"cop_bounds": (-1.0, 1.0)}}),
    ("com_bounds +-1", {"controller": {"com_bounds": (-1.0, 1.0)}}),
    ("horizon 40", {"controller": {"horizon": 40}}),
    ("horizon 10", {"controller": {"horizon": 10}}),
    ("convention joint", {"controller": {"convention": "joint"}}),
    ("foot_pitch_limit 0.5", {"scenario": {"foot_pitch_limit": 0.5}}),
    ("foot_lift_limit 0.1 m", {"scenario": {"foot_lift_limit": 0.1}}),
    ("bound_violation_limit 1", {"scenario": {"bound_violation_limit": 1.0}}),
    ("lower_tilt_limit 1.5", {"scenario": {"lower_tilt_limit": 1.5}}),
    ("all four fall rules off", {"scenario": {"foot_pitch_limit": 3.0, "foot_lift_limit": 2.0,
                                              "bound_violation_limit": 10.0,
                                              "lower_tilt_limit": 1.5}}),
    ("settle band x10 looser", {"scenario": {"settle_angle_tol": 0.1, "settle_rate_tol": 0.5}}),
    ("push_body hip", {"scenario": {"push_body": "hip"}}),
    ("friction 2", {"body": {"friction": 2.0}}),
]
PUSHES = [([100.0, 120.0], [0.1]), ([15.0], [6.0, 12.0])]  # 12 s = t_end: a sustained push


def relax() -> pd.DataFrame:
    rows = []
    for label, change in RELAX:
        config = BASE.replace(**change)
        start = time.perf_counter()
        for forces, durations in PUSHES:
            summary, _ = mb.simulate(forces, durations, config)
            for _, r in summary.iterrows():
                rows.append({"change": label, "force": r.force, "duration": r.duration,
                             **{k: r[k] for k in SHOW}})
        print(f"{label}: {time.perf_counter() - start:.0f} s", flush=True)
    return pd.DataFrame(rows)


def recovers(force: float, duration: float, config: mb.Config) -> bool:
    """Recovered; for a push still on at t_end (sustained), held: recovered or not_settled."""
    outcome = mb.simulate([force], [duration], config)[0]["outcome"].iloc[0]
    return outcome == "recovered" or (duration >= config.scenario.t_end
                                      and outcome == "not_settled")


def smallest(force: float, duration: float, make, lo: int, hi: int) -> int:
    """The smallest integer v in (lo, hi] with which the push recovers, by bisection: the push
    falls with make(lo) and recovers with make(hi) (both measured in `relax`)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if recovers(force, duration, make(mid)) else (mid, hi)
    return hi


def margins() -> pd.DataFrame:
    """Per push, the smallest whole ankle bound (input1_bounds = +-b N m) and the smallest
    horizon with which it recovers (scalar reference; brackets from `relax`)."""
    ankle = lambda b: BASE.replace(controller={"input1_bounds": (-float(b), float(b))})
    horizon = lambda n: BASE.replace(controller={"horizon": n})
    rows = []
    for force, duration in [(100.0, 0.1), (120.0, 0.1), (15.0, 6.0), (15.0, 12.0)]:
        lo, hi = (20, 25) if force == 100 else (25, 30)
        row = {"force": force, "duration": duration,
               "recovers_from_input1": smallest(force, duration, ankle, lo, hi)}
        if duration == 0.1:
            row["recovers_from_horizon"] = smallest(force, duration, horizon, 20, 40)
        rows.append(row)
        print(row, flush=True)
    return pd.DataFrame(rows)


def threshold(config: mb.Config, grid: str = "60:200:1") -> tuple[float, str]:
    """The largest force recovering at T = 0.1 s such that every force of the grid below it
    recovers too (batched path, MuJoCo C physics where it supports the change)."""
    physics = "auto" if config.scenario.push_body == "hip" else "c"
    frame = mb.sweep(grid, [0.1], config, physics=physics).sort_values("force")
    ok = (frame["outcome"] == "recovered").to_numpy()
    forces = frame["force"].to_numpy()
    first_fall = int(np.argmin(ok)) if not ok.all() else len(ok)
    note = "" if not ok[first_fall:].any() else f"recovers again up to {forces[ok].max():g} N"
    return (float(forces[first_fall - 1]) if first_fall else float("nan")), note


def scaled(section: str, name: str, factor: float) -> mb.Config:
    value = getattr(getattr(BASE, section), name)
    value = tuple(v * factor for v in value) if isinstance(value, tuple) else value * factor
    return BASE.replace(**{section: {name: value}})


PARAMETERS = [("body", n) for n in ("foot_mass", "lower_mass", "upper_mass", "lower_length",
                                    "upper_length", "lower_com", "upper_com", "foot_length")]
PARAMETERS += [("controller", "input1_bounds")]  # input2 (hip): never saturates in `relax`


def sensitivity() -> pd.DataFrame:
    """One row per case, appended to OUT/sensitivity.csv as it is measured (a rerun skips the
    cases already there)."""
    cases = [("baseline", "-", BASE)]
    for section, name in PARAMETERS:
        cases += [(name, f"{f:+.0%}", scaled(section, name, 1 + f)) for f in (-0.1, 0.1)]
    cases.append(("push_body", "hip", BASE.replace(scenario={"push_body": "hip"})))
    path = OUT / "sensitivity.csv"
    done = pd.read_csv(path) if path.exists() else pd.DataFrame(columns=["parameter", "change"])
    for name, change, config in cases:
        if ((done["parameter"] == name) & (done["change"] == change)).any():
            continue
        start = time.perf_counter()
        force, note = threshold(config)
        physics = "auto" if config.scenario.push_body == "hip" else "c"
        table = mb.table([15.0], config, physics=physics)
        row = {"parameter": name, "change": change, "threshold_0.1s": force,
               "sustained_limit": float(table["sustained_push_limit"].iloc[0]),
               "max_acting_time_15N": float(table["max_acting_time"].iloc[0]),
               "note": note, "seconds": round(time.perf_counter() - start, 1)}
        done = pd.concat([done, pd.DataFrame([row])], ignore_index=True)
        done.to_csv(path, index=False)
        print(row, flush=True)
    return done


def confirm() -> pd.DataFrame:
    """The batched thresholds of the baseline and of the largest movers on the scalar
    reference: the threshold F must recover and F + 1 N fall."""
    table = pd.read_csv(OUT / "sensitivity.csv").set_index(["parameter", "change"])
    rows = []
    cases = [("baseline", "-", BASE),
             ("input1_bounds", "-10%", scaled("controller", "input1_bounds", 0.9)),
             ("input1_bounds", "+10%", scaled("controller", "input1_bounds", 1.1)),
             ("upper_com", "+10%", scaled("body", "upper_com", 1.1)),
             ("lower_length", "-10%", scaled("body", "lower_length", 0.9))]
    for name, change, config in cases:
        force = float(table.loc[(name, change), "threshold_0.1s"])
        summary, _ = mb.simulate([force, force + 1], [0.1], config)
        rows.append({"parameter": name, "change": change, "threshold_0.1s": force,
                     "reference": " / ".join(f"{f:g} N {o} {c}".strip() for f, o, c in
                                             zip(summary.force, summary.outcome,
                                                 summary.fall_cause.fillna("")))})
        print(rows[-1], flush=True)
    return pd.DataFrame(rows)


if __name__ == "__main__":
    part = sys.argv[1] if len(sys.argv) > 1 else "relax"
    OUT.mkdir(parents=True, exist_ok=True)
    result = {"relax": relax, "margins": margins, "sensitivity": sensitivity,
              "confirm": confirm}[part]()
    result.to_csv(OUT / f"{part}.csv", index=False)
    with pd.option_context("display.width", 250, "display.max_rows", 500):
        print(result.to_string(index=False))
