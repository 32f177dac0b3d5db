"""Whole-pipeline benchmark (``mjx-balance bench``): closed-loop scenarios per second.

One run puts the same 12-s push scenarios (forces 0-150 N, durations 0.05-10 s, a fixed
low-discrepancy set, so outcomes are mixed) through

1. the batched pipeline: MJX physics + batched ADMM (``rollout.BatchRunner``), in chunks;
   build time (model, QP, rest state) and compile time are reported apart from the run;
2. the scalar reference: MuJoCo C + OSQP (``reference.simulate_scenario``), one scenario per
   task on a pool of worker processes (one per core by default);
3. the study's toolchain: the same MuJoCo C closed loop with the MPC solved by CasADi/IPOPT
   (``bench.ipopt_mpc``: multiple shooting, RK4 on the continuous linear model), on a subset.

The reference runs a prefix of the scenario list; the toolchain runs a subset of that prefix
with the reference's outcome mix (``stratified_subset``: the scalar loops stop at a fall, so a
subset of falls alone would flatter them). So (3) is inside (2) is inside (1), and the outcome
agreement is counted on the scenarios each pair shares. Worker pools are started and warmed up
(imports, model, QP) before timing, as the batched pipeline's compile is timed apart.

Peak memory is ``resource.getrusage`` maxrss: of this process (which runs the batched pipeline),
and the largest of its finished worker processes.

``--memory-scaling 10000,100000,...`` runs, for each size, a sweep (``sweep.run_sweep``, the
user's path: chunks from the memory budget, chunk files on disk) with a tiny ``t_end`` in a
fresh subprocess and prints that process's peak resident memory.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any

import numpy as np

from .params import Config

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
FORCE_RANGE = (0.0, 150.0)
DURATION_RANGE = (0.05, 10.0)


def scenario_set(n: int, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """n (force, duration) pairs: forces uniform in 0-150 N and durations log-uniform in
    0.05-10 s (capped at t_end), from a 2-D golden-ratio (Kronecker) sequence, so every prefix
    covers the square evenly. Rounded to 0.1 N and 1 ms."""
    i = np.arange(n, dtype=np.float64) + 0.5
    a = (i * GOLDEN) % 1.0
    b = (i * 0.5 * (math.sqrt(3.0) - 1.0) + 0.25) % 1.0
    forces = np.round(FORCE_RANGE[0] + a * (FORCE_RANGE[1] - FORCE_RANGE[0]), 1)
    lo, hi = math.log(DURATION_RANGE[0]), math.log(DURATION_RANGE[1])
    durations = np.round(np.exp(lo + b * (hi - lo)), 3)
    return forces, np.minimum(durations, t_end)


def _peak_rss_mib(who: int) -> float:
    """maxrss of this process (RUSAGE_SELF) or the largest finished child, in MiB."""
    return resource.getrusage(who).ru_maxrss / 1024.0


# --------------------------------------------------------------------------------------------
# Worker-side functions (run in spawned processes; module level so they pickle)


def _warm_reference(config: Config) -> int:
    from . import reference

    reference.simulate_scenario(config, 0.0, 0.05, record=False)  # model, QP, OSQP set up
    return os.getpid()


def _run_reference(config: Config, force: float, duration: float) -> tuple[int, float]:
    from . import metrics, reference

    t0 = time.perf_counter()
    row, _ = reference.simulate_scenario(config, force, duration, record=False)
    return metrics.OUTCOMES.index(row["outcome"]), time.perf_counter() - t0


class IpoptMPC:
    """The study's MPC (CasADi/IPOPT, ``bench.ipopt_mpc``) behind ``reference.ReferenceMPC``'s
    interface, so the reference's MuJoCo C closed loop and metrics run unchanged around it."""

    def __init__(self, qp, controller):
        from .bench import ipopt_mpc

        self.qp = qp
        self._solve, self._shift = ipopt_mpc(qp, controller)
        self._w = None

    def reset(self) -> None:
        self._w = None

    def solve(self, x0: np.ndarray):
        u, w = self._solve(np.asarray(x0, float), self._w)
        ok = bool(np.isfinite(w).all())
        self._w = self._shift(w) if ok else None
        # IPOPT's own status is not exposed by ipopt_mpc: count a solve as converged when its
        # result is finite; no primal residual (NaN).
        return u, w, ok, math.nan


def _use_ipopt() -> None:
    """In an IPOPT worker: make the reference closed loop build IpoptMPC instead of OSQP's."""
    import functools

    from . import reference
    from .qp import build_qp

    @functools.lru_cache(maxsize=8)
    def _mpc(controller, body, control_dt):
        return IpoptMPC(build_qp(controller, body, control_dt), controller)

    reference._mpc = _mpc  # this worker process only runs the study's toolchain


def _warm_ipopt(config: Config) -> int:
    _use_ipopt()
    return _warm_reference(config)


def _run_ipopt(config: Config, force: float, duration: float) -> tuple[int, float]:
    _use_ipopt()
    return _run_reference(config, force, duration)


def _pool_run(warm, run, config: Config, forces, durations, workers: int, label: str):
    """Run scenarios on a fresh pool of ``workers`` spawned processes; time after warm-up."""
    ctx = get_context("spawn")  # never fork a process that has started JAX's threads
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        list(pool.map(warm, [config] * workers))
        warm_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        futures = [pool.submit(run, config, float(f), float(d)) for f, d in zip(forces, durations)]
        results = [fut.result() for fut in futures]
        seconds = time.perf_counter() - t1
    outcomes = np.array([r[0] for r in results], np.int32)
    per = np.array([r[1] for r in results])
    print(f"  {label}: {len(forces)} scenarios in {seconds:.1f} s on {workers} processes "
          f"(warm-up {warm_s:.1f} s; per scenario median {np.median(per):.2f} s, "
          f"max {per.max():.2f} s)", flush=True)
    return outcomes, seconds, per


# --------------------------------------------------------------------------------------------
# The batched pipeline (this process)


def _run_batched(config: Config, forces: np.ndarray, durations: np.ndarray, chunk: int,
                 repeats: int) -> dict[str, Any]:
    import jax

    from .rollout import BatchRunner

    t0 = time.perf_counter()
    runner = BatchRunner(config)
    build_s = time.perf_counter() - t0
    batch = runner.padded_batch(min(chunk, len(forces)))
    t0 = time.perf_counter()
    runner.compiled(batch)
    compile_s = time.perf_counter() - t0
    print(f"  MJX + ADMM: build {build_s:.1f} s, compile {compile_s:.1f} s (batch {batch}, "
          f"{len(jax.devices())} {jax.devices()[0].platform} device(s))", flush=True)
    times, outcomes, iters = [], None, None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        parts = [runner.run(forces[i:i + batch], durations[i:i + batch])
                 for i in range(0, len(forces), batch)]  # run() returns host numpy: synchronous
        times.append(time.perf_counter() - t0)
        outcomes = np.concatenate([p["outcome"] for p in parts])
        iters = np.concatenate([p["admm_iterations"] for p in parts])
    seconds = float(np.median(times))
    sc = config.scenario
    print(f"  MJX + ADMM: {len(forces)} scenarios in {seconds:.1f} s (median of {len(times)}; "
          f"{len(forces) * sc.n_control * sc.substeps / seconds:,.0f} physics steps/s, "
          f"mean ADMM iterations per period {iters.sum() / max(1, len(forces) * sc.n_control):.1f})",
          flush=True)
    return dict(outcomes=outcomes, seconds=seconds, build_s=build_s, compile_s=compile_s,
                batch=batch, devices=len(jax.devices()))


def stratified_subset(outcomes: np.ndarray, n: int) -> np.ndarray:
    """Indices of n scenarios whose outcome mix follows ``outcomes`` (the reference's): a
    scenario that falls ends at its fall in the scalar loops, so a subset of only falls (or
    only recoveries) would misstate the toolchain's throughput on the benchmark's mix. Each
    outcome gets its proportional share (at least one if present, while n allows), earliest
    scenarios first."""
    outcomes = np.asarray(outcomes)
    n = min(n, outcomes.size)
    classes, counts = np.unique(outcomes, return_counts=True)
    share = np.maximum(1, np.round(n * counts / counts.sum()).astype(int))
    while share.sum() > n:
        share[np.argmax(share)] -= 1
    while share.sum() < n:
        share[np.argmax(counts - share)] += 1
    picks = [np.nonzero(outcomes == c)[0][:k] for c, k in zip(classes, share)]
    return np.sort(np.concatenate(picks))


def _agreement(a: np.ndarray, b: np.ndarray) -> tuple[int, int]:
    n = min(len(a), len(b))
    return int((a[:n] == b[:n]).sum()), n


# --------------------------------------------------------------------------------------------
# Memory scaling


def _memory_child(cells: int, t_end: float, chunk: int | None, out: str) -> None:
    """(In a fresh process) one sweep of about ``cells`` cells with t_end; prints a JSON line."""
    from . import sweep

    config = Config().replace(scenario={"t_end": t_end, "duration": min(0.1, t_end)})
    n_f = int(round(math.sqrt(cells)))
    n_d = int(math.ceil(cells / n_f))
    forces = np.linspace(0.0, 150.0, n_f)
    durations = np.linspace(0.0, t_end, n_d)
    t0 = time.perf_counter()
    result = sweep.run_sweep(out, config, forces, durations, chunk_size=chunk, progress=False,
                             log=None)
    seconds = time.perf_counter() - t0
    import pandas as pd

    # Only the outcome column: reading the whole region back would add the table to the peak.
    outcomes = pd.read_parquet(result.region_path, columns=["outcome"])["outcome"]
    counts = outcomes.value_counts().to_dict()
    print(json.dumps(dict(cells=n_f * n_d, seconds=seconds,
                          peak_rss_mib=_peak_rss_mib(resource.RUSAGE_SELF),
                          chunks=result.computed_chunks, outcomes=counts)), flush=True)


def memory_scaling(sizes: list[int], t_end: float, chunk: int | None,
                   timeout: float) -> list[dict[str, Any]]:
    rows = []
    print(f"memory scaling: sweeps with t_end = {t_end} s, each in a fresh process", flush=True)
    for cells in sizes:
        with tempfile.TemporaryDirectory() as out:
            cmd = [sys.executable, "-m", "mjx_balance.bench_pipeline", "--memory-child",
                   str(cells), str(t_end), str(chunk or 0), out]
            t0 = time.perf_counter()
            try:
                proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
            except subprocess.TimeoutExpired:
                print(f"  {cells:>9,} cells: not finished within {timeout:.0f} s", flush=True)
                rows.append(dict(cells=cells, timed_out=True, seconds=time.perf_counter() - t0))
                continue
            lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
            if proc.returncode or not lines:
                print(f"  {cells:>9,} cells: failed ({proc.stderr.strip()[-400:]})", flush=True)
                rows.append(dict(cells=cells, failed=True))
                continue
            row = json.loads(lines[-1])
            print(f"  {row['cells']:>9,} cells: peak RSS {row['peak_rss_mib']:7.0f} MiB, "
                  f"{row['seconds']:7.1f} s ({row['chunks']} chunks, "
                  f"{row['cells'] / row['seconds']:,.0f} cells/s incl. compile)", flush=True)
            rows.append(row)
    return rows


# --------------------------------------------------------------------------------------------
# The command


def pipeline_command(args: argparse.Namespace) -> int:
    """``mjx-balance bench``: batched pipeline vs scalar reference vs the study's toolchain."""
    from .cli import load_run_config

    config = load_run_config(args)
    if getattr(args, "t_end", None):
        t_end = float(args.t_end)
        config = config.replace(scenario={
            "t_end": t_end, "duration": min(config.scenario.duration, t_end)})
    ref_config = config
    if getattr(args, "osqp_max_iter", None):
        ref_config = config.replace(controller={"osqp_max_iter": int(args.osqp_max_iter)})
    sc = config.scenario
    n_mjx, n_ref, n_ipopt = args.scenarios, min(args.reference, args.scenarios), args.ipopt
    n_ipopt = min(n_ipopt, n_ref) if n_ref else n_ipopt
    forces, durations = scenario_set(n_mjx, sc.t_end)
    load = os.getloadavg()
    print(f"pipeline benchmark: {n_mjx} scenarios of {sc.t_end:g} s (forces 0-150 N, durations "
          f"{durations.min():g}-{durations.max():g} s), convention {config.controller.convention}; "
          f"reference on {n_ref}, CasADi/IPOPT on {n_ipopt}; {args.workers} worker processes; "
          f"{os.cpu_count()} CPUs, load average {load[0]:.2f} at start", flush=True)

    # Worker pools first: they are spawned (not forked) anyway, and this keeps JAX idle meanwhile.
    ref = ipopt = None
    if n_ref:
        cap = ref_config.controller.osqp_max_iter
        out, seconds, per = _pool_run(_warm_reference, _run_reference, ref_config,
                                      forces[:n_ref], durations[:n_ref], args.workers,
                                      f"reference (MuJoCo C + OSQP, max_iter {cap})")
        ref = dict(outcomes=out, seconds=seconds, per=per)
    ipopt_idx = np.arange(n_ipopt)
    if n_ipopt and ref is not None:
        ipopt_idx = stratified_subset(ref["outcomes"], n_ipopt)
    if n_ipopt:
        try:
            import casadi  # noqa: F401
        except ImportError:
            print("  CasADi/IPOPT: casadi not installed, skipped")
        else:
            out, seconds, per = _pool_run(_warm_ipopt, _run_ipopt, config, forces[ipopt_idx],
                                          durations[ipopt_idx], args.workers,
                                          "study toolchain (MuJoCo C + CasADi/IPOPT)")
            ipopt = dict(outcomes=out, seconds=seconds, per=per)
    batched = _run_batched(config, forces, durations, args.chunk, args.repeats)

    def rate(r, n):
        return n / r["seconds"] if r else math.nan

    r_mjx = rate(batched, n_mjx)
    r_ref = rate(ref, n_ref)
    r_ipopt = rate(ipopt, n_ipopt)
    names = ("recovered", "not_settled", "fell", "diverged")
    mix = {name: int((batched["outcomes"] == i).sum()) for i, name in enumerate(names)}
    print()
    print(f"{'system':44s} {'scenarios':>9s} {'seconds':>9s} {'scen/s':>9s} {'MJX ratio':>10s}")
    print(f"{'MJX + ADMM (batched, this process)':44s} {n_mjx:9d} {batched['seconds']:9.1f} "
          f"{r_mjx:9.2f} {1.0:10.1f}")
    if ref:
        print(f"{'MuJoCo C + OSQP (reference, processes)':44s} {n_ref:9d} {ref['seconds']:9.1f} "
              f"{r_ref:9.3f} {r_mjx / r_ref:10.1f}")
    if ipopt:
        print(f"{'MuJoCo C + CasADi/IPOPT (study, processes)':44s} {n_ipopt:9d} "
              f"{ipopt['seconds']:9.1f} {r_ipopt:9.3f} {r_mjx / r_ipopt:10.1f}")
    print(f"outcomes (MJX, all {n_mjx}): {mix}")
    agree = {}
    if ref:
        a, n = _agreement(batched["outcomes"], ref["outcomes"])
        agree["mjx_vs_reference"] = [a, n]
        print(f"outcome agreement MJX vs reference: {a}/{n}")
    if ipopt:
        a, n = _agreement(batched["outcomes"][ipopt_idx], ipopt["outcomes"])
        agree["mjx_vs_ipopt"] = [a, n]
        print(f"outcome agreement MJX vs CasADi/IPOPT: {a}/{n}")
        if ref:
            a, n = _agreement(ref["outcomes"][ipopt_idx], ipopt["outcomes"])
            agree["reference_vs_ipopt"] = [a, n]
            print(f"outcome agreement reference vs CasADi/IPOPT: {a}/{n}")
    rss_self = _peak_rss_mib(resource.RUSAGE_SELF)
    rss_children = _peak_rss_mib(resource.RUSAGE_CHILDREN)
    print(f"compile {batched['compile_s']:.1f} s, build {batched['build_s']:.1f} s; peak RSS "
          f"{rss_self:.0f} MiB (this process), {rss_children:.0f} MiB (largest worker)")
    print(f"targets: >= 60 scen/s: {r_mjx:.2f} ({'met' if r_mjx >= 60 else 'NOT met'}); "
          f">= 6x reference: {r_mjx / r_ref:.1f}x "
          f"({'met' if r_mjx / r_ref >= 6 else 'NOT met'}); >= 150x study toolchain: "
          f"{r_mjx / r_ipopt:.1f}x ({'met' if r_mjx / r_ipopt >= 150 else 'NOT met'})")
    memory = memory_scaling(args.memory_scaling, args.memory_t_end, args.memory_chunk,
                            args.memory_timeout) if args.memory_scaling else None
    if args.json:
        print(json.dumps(dict(
            scenarios=n_mjx, t_end=sc.t_end, workers=args.workers, cpus=os.cpu_count(),
            load_average_start=load[0],
            mjx=dict(scen_per_s=r_mjx, seconds=batched["seconds"], build_s=batched["build_s"],
                     compile_s=batched["compile_s"], batch=batched["batch"],
                     devices=batched["devices"], outcomes=mix),
            reference=dict(scenarios=n_ref, scen_per_s=r_ref,
                           seconds=ref["seconds"] if ref else math.nan,
                           osqp_max_iter=ref_config.controller.osqp_max_iter),
            ipopt=dict(scenarios=n_ipopt, scen_per_s=r_ipopt,
                       seconds=ipopt["seconds"] if ipopt else math.nan),
            ratio_vs_reference=r_mjx / r_ref, ratio_vs_ipopt=r_mjx / r_ipopt,
            agreement=agree, peak_rss_mib=dict(main=rss_self, workers=rss_children),
            memory_scaling=memory,
        )))
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Options of ``mjx-balance bench`` (the pipeline benchmark)."""
    p.add_argument("--scenarios", type=int, default=64, help="scenarios through MJX + ADMM")
    p.add_argument("--reference", type=int, default=16,
                   help="of those, how many through the scalar reference (0: skip)")
    p.add_argument("--ipopt", type=int, default=8,
                   help="of those, how many through CasADi/IPOPT + MuJoCo C, with the "
                        "reference's outcome mix (0: skip)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 2,
                   help="worker processes of the reference and the study toolchain")
    p.add_argument("--chunk", type=int, default=64, help="MJX batch size (padded to 2^k)")
    p.add_argument("--repeats", type=int, default=1, help="timed MJX runs (median)")
    p.add_argument("--t-end", type=float, default=None, help="scenario length [s] (default 12)")
    p.add_argument("--osqp-max-iter", type=int, default=None,
                   help="reference OSQP iteration cap (default: the configuration's, 20000)")
    p.add_argument("--memory-scaling", type=lambda s: [int(float(v)) for v in s.split(",")],
                   default=None, help="comma list of sweep sizes (cells), e.g. 10000,100000")
    p.add_argument("--memory-t-end", type=float, default=0.02, help="t_end of those sweeps [s]")
    p.add_argument("--memory-chunk", type=int, default=None, help="chunk size of those sweeps")
    p.add_argument("--memory-timeout", type=float, default=900.0, help="seconds per sweep")
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "--memory-child":
        _memory_child(int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]) or None, sys.argv[5])
    else:
        print("usage: mjx-balance bench [options]", file=sys.stderr)
        sys.exit(2)
