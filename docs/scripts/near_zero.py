"""Near-zero pushes and the certified early stop (docs/engine.md, "Certified recovery").

    python docs/scripts/near_zero.py diagnose                   # which test of the check fails
    python docs/scripts/near_zero.py noise                      # V(x) of the rest jitter
    python docs/scripts/near_zero.py run default OUT.parquet     # the default sweep's cells
    python docs/scripts/near_zero.py run dense OUT.parquet       # region_dense_paper's cells
    python docs/scripts/near_zero.py run cohort OUT.parquet      # --population 5 --seed 1
    python docs/scripts/near_zero.py run GRID OUT.parquet --full-length
    python docs/scripts/near_zero.py compare EARLY.parquet FULL.parquet [BEFORE.parquet]

``diagnose`` re-runs pushes of 0-5 N to t_end with trajectories and evaluates every test of
``certificate.check`` at every check instant (every CHECK_EVERY periods after the push) from the
recorded samples: the running peaks, the state at the control instant, the prediction. It
prints, per push, the engine's periods and how many checks each test failed, and the figures
of the tests at a few instants.

``run`` runs the cells of a sweep on the engine as ``mjx-balance sweep`` / ``cohort`` do (the
same configuration, 32 slots on each of 2 host devices) and keeps every cell's summary with the
engine's ``periods`` (control periods simulated) and ``certified``, which the sweep's own
outputs leave out. ``compare`` prints the control periods of two runs of the same cells (total,
the longest cell, cells run to t_end) and, per summary column, how many cells differ and the
largest absolute and relative difference; given the early run of the code before a change,
apart for the cells it certified too and the cells certified only now.
"""
import os
import sys

if "jax" not in sys.modules:  # one host device per core, as the command line sets them
    flags = os.environ.get("XLA_FLAGS", "")
    if "device_count" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count=2".strip()

import jax
import numpy as np
import pandas as pd

# (JAX's backend starts at the first computation, after mjx_balance has set its XLA options)
from mjx_balance.control import certificate as C
from mjx_balance.model.params import Config
from mjx_balance.rollout import BatchRunner

GRIDS = {"default": ("0:150:10", "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5"),
         "dense": ("0:150:2", "0.05:10:0.05"),
         "cohort": ("0:150:10", "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5")}
COHORT = {"n": 5, "seed": 1}


def diagnose(forces=(0.0, 0.5, 1.0, 2.0, 3.0, 5.0), durations=(0.05, 0.5, 1.5)) -> None:
    config = Config()
    sc = config.scenario
    f, d = np.repeat(forces, len(durations)), np.tile(durations, len(forces))
    with jax.enable_x64(False):
        early = BatchRunner(config)
        early.run(f, d)
        traj = BatchRunner(config, trajectories=True)
        traj.run(f, d)
    cert = C.Certificate(*(np.asarray(v, np.float64) for v in early.engine.cert))
    lm, sn, series = traj.qp.linear, traj.sensors, traj.last_trajectories
    S = sc.substeps
    for row in range(f.size):
        q = series["qpos"][row][:, sn.joints_q].astype(float)
        dq = series["qvel"][row][:, sn.joints_v].astype(float)
        pitch = np.abs(series["qpos"][row][:, sn.foot_pitch].astype(float))
        tau = np.abs(series["tau"][row].astype(float))
        in_band = ((np.abs(q) <= sc.settle_angle_tol).all(1)
                   & (np.abs(dq) <= sc.settle_rate_tol).all(1))
        n_push = round(d[row] / sc.physics_dt)
        failed: dict[str, int] = {}
        shown = []
        checks = 0
        for k in range(C.CHECK_EVERY, sc.n_control, C.CHECK_EVERY):
            if k * S < n_push:
                continue
            checks += 1
            i = k * S - 1
            x = lm.state_from_joints(q[i], dq[i])
            pred = np.einsum("nqi,i->nq", cert.rows, x)
            tail = np.sqrt(C.GROWTH * (x @ cert.tail @ x)) * cert.tail_reach
            size = np.maximum(np.maximum(pred.max(0), tail), -np.minimum(pred.min(0), -tail))
            size = size / C.MARGIN
            need_pitch = float(cert.pitch_per_cop) * size[6] + float(cert.pitch_floor)
            peaks = {"peak_ankle": np.abs(q[:i + 1, 0]).max(),
                     "peak_hip": np.abs(q[:i + 1, 1]).max(),
                     "peak_tau_ankle": tau[:i + 1, 0].max(), "peak_tau_hip": tau[:i + 1, 1].max(),
                     "peak_foot_pitch": pitch[:i + 1].max()}
            tests = {"in_band": in_band[i], "band": (size[:4] <= cert.band).all(),
                     "peak_ankle": size[0] <= peaks["peak_ankle"],
                     "peak_hip": size[1] <= peaks["peak_hip"],
                     "peak_tau_ankle": size[4] <= peaks["peak_tau_ankle"],
                     "peak_tau_hip": size[5] <= peaks["peak_tau_hip"],
                     "foot_pitch": peaks["peak_foot_pitch"] >= need_pitch,
                     "qp_free": C.GROWTH * (x @ cert.P @ x) <= float(cert.qp_level)}
            for name, ok in tests.items():
                failed[name] = failed.get(name, 0) + (not ok)
            if k in (100, 300, 1195):
                shown.append(
                    f"    k={k}: failing {[n for n, ok in tests.items() if not ok]}; "
                    f"predicted/recorded ankle {size[0]:.2g}/{peaks['peak_ankle']:.2g} rad, "
                    f"hip {size[1]:.2g}/{peaks['peak_hip']:.2g} rad, "
                    f"tau {size[4]:.2g}/{peaks['peak_tau_ankle']:.2g}, "
                    f"{size[5]:.2g}/{peaks['peak_tau_hip']:.2g} N m; "
                    f"foot pitch needed {need_pitch:.2g}, recorded {peaks['peak_foot_pitch']:.2g}"
                    f" rad; band use {(size[:4] / cert.band).max():.2g}")
        print(f"F={f[row]:g} N T={d[row]:g} s: {early.last_periods[row]} periods, certified "
              f"{bool(early.last_certified[row])}; of {checks} checks failed: "
              + ", ".join(f"{n} {c}" for n, c in failed.items() if c)
              + f"; whole run: max|q| {np.abs(q).max():.2g} rad, max|dq| {np.abs(dq).max():.2g}"
              f" rad/s, max foot pitch {pitch.max():.2g} rad")
        print("\n".join(shown))


def noise() -> None:
    """The closed loop standing unpushed (0 N) for the whole window, with trajectories: the
    largest V(x) = x^T P x at a control instant (the level of the rest jitter), per body (the
    default and the cohort's subjects), and the peaks the jitter reaches."""
    from mjx_balance.studies import members as cohort_members

    bodies = [("default", Config())] + [(m.id, m.subject.config(Config()))
                                        for m in cohort_members.population(COHORT["n"], COHORT["seed"])]
    for label, config in bodies:
        sc = config.scenario
        with jax.enable_x64(False):
            traj = BatchRunner(config, trajectories=True)
            traj.run(np.zeros(1), np.full(1, 0.05))
        lm, sn, series = traj.qp.linear, traj.sensors, traj.last_trajectories
        q = series["qpos"][0][:, sn.joints_q].astype(float)
        dq = series["qvel"][0][:, sn.joints_v].astype(float)
        at = np.arange(C.CHECK_EVERY, sc.n_control) * sc.substeps - 1
        x = lm.state_from_joints(q[at], dq[at])
        V = np.einsum("ti,ij,tj->t", x, traj.qp.Qf, x)
        cert = C.Certificate(*(np.asarray(v, np.float64)
                               for v in C.build(traj.qp, config.controller, sc, rest=(0.0, 0.0))))
        sizes = []
        for xk in x:
            pred = np.einsum("nqi,i->nq", cert.rows, xk)
            tail = np.sqrt(C.GROWTH * (xk @ cert.tail @ xk)) * cert.tail_reach
            sizes.append(np.maximum(np.maximum(pred.max(0), tail),
                                    -np.minimum(pred.min(0), -tail)) / C.MARGIN)
        sizes = np.max(sizes, axis=0)
        # the largest level set inside the band: V <= c keeps |g x| <= band for g = the rows
        band_level = float(np.min((cert.band / cert.tail_reach[:4]) ** 2))
        reach = np.sqrt(C.GROWTH * V.max()) * cert.tail_reach / C.MARGIN
        print(f"{label}: V at rest <= {V.max():.3g} (median {np.median(V):.3g}), "
              f"{V.max() / band_level:.3g} of the band's level {band_level:.3g}; "
              f"the check's bounds at rest: ankle {sizes[0]:.3g}, hip {sizes[1]:.3g} rad, "
              f"tau {sizes[4]:.3g}, {sizes[5]:.3g} N m, CoP {sizes[6]:.3g} m; through V: "
              f"{reach[0]:.3g}, {reach[1]:.3g}, {reach[4]:.3g}, {reach[5]:.3g}, {reach[6]:.3g}; "
              f"peaks |q| {np.abs(q).max(0)} rad, |tau| {np.abs(series['tau'][0]).max(0)} N m, "
              f"foot pitch {np.abs(series['qpos'][0][:, sn.foot_pitch]).max():.3g} rad")


def cells(grid: str):
    """[(label, config, forces, durations)] of a grid's runs."""
    from mjx_balance.runs.folders import grid_values

    forces, durations = (grid_values(v, n) for v, n in zip(GRIDS[grid], ("forces", "durations")))
    f, d = np.repeat(forces, durations.size), np.tile(durations, forces.size)
    if grid != "cohort":
        return [("", Config(), f, d)]
    from mjx_balance.studies import members as cohort_members

    return [(m.id, m.subject.config(Config()), f, d)
            for m in cohort_members.population(COHORT["n"], COHORT["seed"])]


def run(grid: str, out: str, full_length: bool) -> None:
    frames = []
    for label, config, f, d in cells(grid):
        runner = BatchRunner(config, early_stop=not full_length)
        parts = []
        for index, columns in runner.stream(f, d):
            part = pd.DataFrame({k: np.asarray(v) for k, v in columns.items()})
            part["cell"] = index
            parts.append(part)
        frame = pd.concat(parts).sort_values("cell").reset_index(drop=True)
        frame.insert(0, "subject", label)
        frames.append(frame)
    frame = pd.concat(frames, ignore_index=True)
    frame.to_parquet(out)
    periods = frame["periods"]
    print(f"{grid}: {len(frame)} cells, {periods.sum():,} control periods, longest "
          f"{periods.max()}, {int(frame['certified'].sum())} certified -> {out}")


def compare(a_path: str, b_path: str, before_path: str | None = None) -> None:
    """Periods of A and B; per column, the cells that differ and the largest differences. With
    ``before_path`` (A's cells with the code before), the differences are given apart for the
    cells it certified too and for the cells certified only now."""
    frames = [pd.read_parquet(p) for p in (a_path, b_path, before_path) if p is not None]
    key = ["subject", "cell"]
    frames = [f.sort_values(key).reset_index(drop=True) for f in frames]
    a, b = frames[0], frames[1]
    for frame in frames[1:]:
        assert (a[key].to_numpy() == frame[key].to_numpy()).all(), "not the same cells"
    n_control = Config().scenario.n_control
    for name, frame in zip((a_path, b_path, before_path), frames):
        p = frame["periods"]
        print(f"{name}: {len(p)} cells, {p.sum():,} control periods, longest {p.max()}, "
              f"{int((p >= n_control).sum())} run to t_end, {int(frame['certified'].sum())} "
              f"certified")
    groups = {"all cells": np.ones(len(a), bool)}
    if before_path is not None:
        old = frames[2]["certified"].to_numpy()
        groups = {"certified before too": old, "certified only now": a["certified"].to_numpy()
                  & ~old}
        print("cells per group: " + ", ".join(f"{k} {int(v.sum())}" for k, v in groups.items()))
    print(f"{'column':28s}" + "".join(f" | {g:>30s}" for g in groups))
    print(f"{'':28s}" + " | cells differ, max abs, max rel" * len(groups))
    for column in a.columns:
        if column in [*key, "periods", "certified"]:
            continue
        x, y = a[column].to_numpy(), b[column].to_numpy()
        row = f"{column:28s}"
        for rows in groups.values():
            xs, ys = x[rows], y[rows]
            if not np.issubdtype(xs.dtype, np.number):
                row += f" | {int((xs != ys).sum()):12d}" + " " * 18
                continue
            xs, ys = xs.astype(float), ys.astype(float)
            same = (xs == ys) | (np.isnan(xs) & np.isnan(ys))
            diff = np.where(same, 0.0, np.abs(xs - ys))
            diff = np.where(np.isnan(diff), np.inf, diff)
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(same, 0.0, diff / np.abs(ys))
            row += (f" | {int((~same).sum()):12d} {diff.max(initial=0):8.3g} "
                    f"{rel.max(initial=0):8.3g}")
        print(row)


if __name__ == "__main__":
    command = sys.argv[1]
    if command == "diagnose":
        diagnose()
    elif command == "noise":
        noise()
    elif command == "run":
        run(sys.argv[2], sys.argv[3], "--full-length" in sys.argv[4:])
    elif command == "compare":
        compare(sys.argv[2], sys.argv[3], sys.argv[4] if len(sys.argv) > 4 else None)
    else:
        raise SystemExit(__doc__)
