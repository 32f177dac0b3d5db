"""Whole-pipeline benchmark (``mjx-balance bench``): closed-loop scenarios per second.

One run puts the same push scenarios (forces 0-150 N, durations 0.05-10 s, a fixed
low-discrepancy set, so outcomes are mixed; :func:`scenario_set`) through

1. the batched pipeline: MJX physics + batched ADMM (``rollout.BatchRunner``), in chunks;
   build time (model, QP, rest state) and compile time are measured apart from the run
   (:func:`build_batched`, :func:`run_batched`);
2. the scalar reference: MuJoCo C + OSQP (``reference.simulate_scenario``), one scenario per
   task on a pool of worker processes (:func:`run_reference_pool`);
3. the study's toolchain: the same MuJoCo C closed loop with the MPC solved by CasADi/IPOPT
   (``bench.ipopt.IpoptMPC``), on a subset (:func:`run_ipopt_pool`).

The reference runs a prefix of the scenario list; the toolchain runs a subset of that prefix
with the reference's outcome mix (:func:`stratified_subset`: the scalar loops stop at a fall, so
a subset of falls alone would flatter them). So (3) is inside (2) is inside (1), and the outcome
agreement is counted on the scenarios each pair shares (:func:`compare`). Worker pools are
started and warmed up (imports, model, QP) before timing, as the batched pipeline's compile is
timed apart.

Peak memory is ``resource.getrusage`` maxrss: of this process (which runs the batched pipeline),
and the largest of its finished worker processes (:func:`peak_rss_mib`).

:func:`memory_sweep` runs one sweep (``runs.region.run_sweep``, the user's path: chunks from the
memory budget, chunk files on disk) of a given number of cells with a tiny ``t_end`` in a fresh
subprocess (``python -m mjx_balance.bench.pipeline --memory-child ...``) and returns that
process's peak resident memory.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from multiprocessing import get_context
from typing import Any, Callable

import numpy as np

from ..measures.outcomes import OUTCOMES
from ..model.params import Config
from ..model.config_files import dumps_config
from .ipopt import study_mpc
from ..reference import loop as reference
from ..rollout import BatchRunner
from ..rollout.cpath import PATHS, resolve, unsupported
from .. import runs as sweep
from ..runs.grid import Grid
from ..store.folder import folder_lock
from ..store.files import write_text

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
FORCE_RANGE = (0.0, 150.0)
DURATION_RANGE = (0.05, 10.0)

# The targets the figures are held against.
TARGET_SCENARIOS_PER_S = 60  # MJX + ADMM
TARGET_VS_REFERENCE = 6  # x MuJoCo C + OSQP
TARGET_VS_STUDY = 150  # x MuJoCo C + CasADi/IPOPT


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


def benchmark_configs(
    config: Config, t_end: float | None = None, osqp_max_iter: int | None = None
) -> tuple[Config, Config]:
    """(config, ref_config): ``config`` with scenario length ``t_end`` (the push duration capped
    at it), and that with the reference's OSQP iteration cap ``osqp_max_iter`` (None or 0: keep
    the configuration's)."""
    if t_end:
        t_end = float(t_end)
        config = config.replace(
            scenario={"t_end": t_end, "duration": min(config.scenario.duration, t_end)}
        )
    ref_config = config
    if osqp_max_iter:
        ref_config = config.replace(controller={"osqp_max_iter": int(osqp_max_iter)})
    return config, ref_config


def scenario_counts(scenarios: int, reference: int, ipopt: int) -> tuple[int, int, int]:
    """(MJX, reference, IPOPT) scenario counts: the reference runs a prefix of the MJX set and
    the toolchain a subset of the reference's (of the MJX set when the reference is skipped)."""
    n_ref = min(reference, scenarios)
    n_ipopt = min(ipopt, n_ref) if n_ref else ipopt
    return scenarios, n_ref, n_ipopt


def peak_rss_mib(who: int) -> float:
    """maxrss of this process (RUSAGE_SELF) or the largest finished child, in MiB."""
    return resource.getrusage(who).ru_maxrss / 1024.0


# --------------------------------------------------------------------------------------------
# Worker-side functions (run in spawned processes; module level so they pickle)


def _study_mpc(config: Config):
    """This worker's CasADi/IPOPT controller for ``config`` (built once per process)."""
    sc = config.scenario
    return study_mpc(config.controller, config.body, sc.control_dt)


def _warm_reference(config: Config, mpc=None) -> int:
    reference.simulate_scenario(config, 0.0, 0.05, record=False, mpc=mpc)  # model, QP, MPC
    return os.getpid()


def _run_reference(config: Config, force: float, duration: float, mpc=None) -> tuple[int, float]:
    t0 = time.perf_counter()
    row, _ = reference.simulate_scenario(config, force, duration, record=False, mpc=mpc)
    return OUTCOMES.index(row["outcome"]), time.perf_counter() - t0


def _warm_ipopt(config: Config) -> int:
    return _warm_reference(config, _study_mpc(config))


def _run_ipopt(config: Config, force: float, duration: float) -> tuple[int, float]:
    return _run_reference(config, force, duration, _study_mpc(config))


def _pool_run(
    warm: Callable, run: Callable, config: Config, forces, durations, workers: int
) -> dict[str, Any]:
    """Run scenarios on a fresh pool of ``workers`` spawned processes; time after warm-up.

    Returns outcomes (codes), seconds (all scenarios, after warm-up), per (seconds of each
    scenario in its worker), warm_s (pool start and warm-up).
    """
    ctx = get_context("spawn")  # never fork a process that has started JAX's threads
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        list(pool.map(warm, [config] * workers))
        warm_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        futures = [pool.submit(run, config, float(f), float(d)) for f, d in zip(forces, durations)]
        results = [fut.result() for fut in futures]
        seconds = time.perf_counter() - t1
    return dict(
        outcomes=np.array([r[0] for r in results], np.int32),
        seconds=seconds,
        per=np.array([r[1] for r in results]),
        warm_s=warm_s,
    )


def run_reference_pool(config: Config, forces, durations, workers: int) -> dict[str, Any]:
    """The scalar reference (MuJoCo C + OSQP) on a pool of processes (see :func:`_pool_run`)."""
    return _pool_run(_warm_reference, _run_reference, config, forces, durations, workers)


def run_ipopt_pool(config: Config, forces, durations, workers: int) -> dict[str, Any]:
    """The study's toolchain (MuJoCo C + CasADi/IPOPT) on a pool of processes (see
    :func:`_pool_run`)."""
    return _pool_run(_warm_ipopt, _run_ipopt, config, forces, durations, workers)


def casadi_available() -> bool:
    """Whether the study's toolchain can run here (casadi importable)."""
    try:
        import casadi  # noqa: F401 - imported only to learn whether it is installed
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------------------------
# The batched pipeline (this process)


def build_batched(
    config: Config, *, slots: int | None = None, early_stop: bool = True, physics: str = "mjx"
) -> dict[str, Any]:
    """Build the batched runner and compile its continuous-batching engine (``physics``: the
    MJX or the MuJoCo C path). Returns runner, slots (per device), build_s, compile_s, devices,
    platform."""
    import jax

    t0 = time.perf_counter()
    runner = BatchRunner(config, slots=slots, early_stop=early_stop, physics=physics)
    build_s = time.perf_counter() - t0
    compile_s = runner.prepare()
    return dict(
        runner=runner,
        slots=runner.engine.slots,
        build_s=build_s,
        compile_s=compile_s,
        devices=len(jax.devices()),
        platform=jax.devices()[0].platform,
    )


def run_batched(
    built: dict[str, Any], config: Config, forces: np.ndarray, durations: np.ndarray, repeats: int
) -> dict[str, Any]:
    """Run every scenario through :func:`build_batched`'s engine, ``repeats`` times.

    Returns outcomes (codes), summary (the columns of ``BatchRunner.run``), seconds (median),
    repeats, physics_steps_per_s (simulated steps), admm_iterations_per_period (mean over the
    periods run), simulated_s (mean simulated seconds per scenario) and certified (count).
    """
    runner = built["runner"]
    times, summary = [], None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        summary = runner.run(forces, durations)  # host numpy: synchronous
        times.append(time.perf_counter() - t0)
    assert summary is not None  # (max(1, repeats) runs)
    seconds = float(np.median(times))
    sc = config.scenario
    periods = runner.last_periods
    return dict(
        outcomes=summary["outcome"],
        summary=summary,
        seconds=seconds,
        repeats=len(times),
        physics_steps_per_s=float(periods.sum()) * sc.substeps / seconds,
        admm_iterations_per_period=summary["admm_iterations"].sum() / max(1, periods.sum()),
        simulated_s=float(periods.mean()) * sc.control_dt,
        certified=int(runner.last_certified.sum()),
    )


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


def agreement(a: np.ndarray, b: np.ndarray) -> tuple[int, int]:
    """(equal outcomes, compared) over the scenarios both lists have."""
    n = min(len(a), len(b))
    return int((a[:n] == b[:n]).sum()), n


def early_vs_full(early: dict[str, Any], full: dict[str, Any]) -> dict[str, Any]:
    """Continuous batching with early stopping against ``--full-length`` on the same scenarios:
    rates, their ratio, mean simulated seconds, and whether the summaries agree (outcomes,
    fall and settle times, peaks exactly; energies: the largest relative difference)."""
    a, b = early["summary"], full["summary"]
    exact = (
        "outcome",
        "fall_time",
        "settle_time",
        "peak_ankle",
        "peak_hip",
        "peak_foot_pitch",
        "peak_tau_ankle",
        "peak_tau_hip",
        "nonconverged_solves",
        "ankle_saturation_fraction",
        "hip_saturation_fraction",
    )
    differ = [c for c in exact if not np.array_equal(a[c], b[c], equal_nan=True)]
    energy = max(
        float(np.nanmax(np.abs(a[c] - b[c]) / np.maximum(np.abs(b[c]), 1e-9)))
        for c in (
            "energy_ankle",
            "energy_hip",
            "energy_total",
            "work_ankle",
            "work_hip",
            "energy_u1",
            "energy_u2",
        )
    )
    n = len(a["outcome"])
    return dict(
        scen_per_s=n / full["seconds"],
        seconds=full["seconds"],
        simulated_s=full["simulated_s"],
        early_scen_per_s=n / early["seconds"],
        speedup=full["seconds"] / early["seconds"],
        exact_columns_differ=differ,
        energy_max_rel_diff=energy,
    )


def compare(
    counts: tuple[int, int, int],
    batched: dict[str, Any],
    ref: dict[str, Any] | None,
    ipopt: dict[str, Any] | None,
    ipopt_idx: np.ndarray,
) -> dict[str, Any]:
    """Rates (scenarios/s, NaN for a system not run), MJX ratios, the MJX outcome mix and the
    outcome agreements [equal, compared] of each pair of systems that ran."""
    n_mjx, n_ref, n_ipopt = counts

    def rate(r, n):
        return n / r["seconds"] if r else math.nan

    r_mjx, r_ref, r_ipopt = rate(batched, n_mjx), rate(ref, n_ref), rate(ipopt, n_ipopt)
    mix = {name: int((batched["outcomes"] == i).sum()) for i, name in enumerate(OUTCOMES)}
    agree = {}
    if ref:
        agree["mjx_vs_reference"] = list(agreement(batched["outcomes"], ref["outcomes"]))
    if ipopt:
        agree["mjx_vs_ipopt"] = list(agreement(batched["outcomes"][ipopt_idx], ipopt["outcomes"]))
        if ref:
            agree["reference_vs_ipopt"] = list(
                agreement(ref["outcomes"][ipopt_idx], ipopt["outcomes"])
            )
    return dict(
        mjx=r_mjx,
        reference=r_ref,
        ipopt=r_ipopt,
        ratio_vs_reference=r_mjx / r_ref,
        ratio_vs_ipopt=r_mjx / r_ipopt,
        mix=mix,
        agreement=agree,
    )


def pipeline_figures(
    *,
    counts: tuple[int, int, int],
    t_end: float,
    workers: int,
    load_average: float,
    built: dict[str, Any],
    batched: dict[str, Any],
    ref: dict[str, Any] | None,
    ipopt: dict[str, Any] | None,
    ref_config: Config,
    comparison: dict[str, Any],
    peak_rss_mib: dict[str, float],
    memory_scaling: list[dict[str, Any]] | None,
    full_length: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The benchmark's figures (what ``--json`` prints), from the steps' results."""
    n_mjx, n_ref, n_ipopt = counts
    return dict(
        scenarios=n_mjx,
        t_end=t_end,
        workers=workers,
        cpus=os.cpu_count(),
        load_average_start=load_average,
        mjx=dict(
            scen_per_s=comparison["mjx"],
            seconds=batched["seconds"],
            build_s=built["build_s"],
            compile_s=built["compile_s"],
            batch=built["slots"],
            slots=built["slots"],
            devices=built["devices"],
            outcomes=comparison["mix"],
            simulated_s=batched["simulated_s"],
            certified=batched["certified"],
        ),
        reference=dict(
            scenarios=n_ref,
            scen_per_s=comparison["reference"],
            seconds=ref["seconds"] if ref else math.nan,
            osqp_max_iter=ref_config.controller.osqp_max_iter,
        ),
        ipopt=dict(
            scenarios=n_ipopt,
            scen_per_s=comparison["ipopt"],
            seconds=ipopt["seconds"] if ipopt else math.nan,
        ),
        ratio_vs_reference=comparison["ratio_vs_reference"],
        ratio_vs_ipopt=comparison["ratio_vs_ipopt"],
        agreement=comparison["agreement"],
        peak_rss_mib=peak_rss_mib,
        memory_scaling=memory_scaling,
        full_length=full_length,
    )


# --------------------------------------------------------------------------------------------
# Memory scaling


def memory_child(cells: int, t_end: float, chunk: int | None, out: str) -> None:
    """(In a fresh process) one sweep of about ``cells`` cells with t_end; prints a JSON line."""
    config = Config().replace(scenario={"t_end": t_end, "duration": min(0.1, t_end)})
    # durations: every whole number of physics steps up to t_end (at most 100 of them), forces
    # as many as the cell count needs
    dt = config.scenario.physics_dt
    steps = int(round(t_end / dt))
    durations = np.unique(np.round(np.linspace(0, steps, min(steps + 1, 100))) * dt)
    n_d = durations.size
    n_f = int(math.ceil(cells / n_d))
    forces = np.linspace(0.0, 150.0, n_f)
    t0 = time.perf_counter()
    with folder_lock(out):  # this child's run: its entry takes the folder's lock
        result = sweep.run_sweep(
            out, config, Grid.of(forces, durations, config), chunk=chunk, progress=False, say=None
        )
    seconds = time.perf_counter() - t0
    import pandas as pd

    # Only the outcome column: reading the whole region back would add the table to the peak.
    outcomes = pd.read_parquet(result.region_path, columns=["outcome"])["outcome"]
    counts = outcomes.value_counts().to_dict()
    print(
        json.dumps(
            dict(
                cells=n_f * n_d,
                seconds=seconds,
                peak_rss_mib=peak_rss_mib(resource.RUSAGE_SELF),
                chunks=result.computed_chunks,
                outcomes=counts,
            )
        ),
        flush=True,
    )


def memory_sweep(
    cells: int, t_end: float, chunk: int | None, timeout: float
) -> tuple[dict[str, Any], str]:
    """One sweep of about ``cells`` cells in a fresh process (:func:`memory_child`).

    Returns (row, error): row is the child's figures (cells, seconds, peak_rss_mib, chunks,
    outcomes), or {cells, timed_out, seconds} / {cells, failed}; error is the end of the
    child's stderr when it failed, else "".
    """
    with tempfile.TemporaryDirectory() as out:
        cmd = [
            sys.executable,
            "-m",
            "mjx_balance.bench.pipeline",
            "--memory-child",
            str(cells),
            str(t_end),
            str(chunk or 0),
            out,
        ]
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return dict(cells=cells, timed_out=True, seconds=time.perf_counter() - t0), ""
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
        if proc.returncode or not lines:
            return dict(cells=cells, failed=True), proc.stderr.strip()[-400:]
        return json.loads(lines[-1]), ""


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "--memory-child":
        memory_child(int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]) or None, sys.argv[5])
    else:
        print("usage: mjx-balance bench [options]", file=sys.stderr)
        sys.exit(2)


# One compile of the benchmark's engine in a fresh process, with the persistent compilation
# cache in the folder given by MJX_BALANCE_CACHE_DIR: seconds, and JAX's compile events.
COMPILE_SCRIPT = """
import json, sys, time
from mjx_balance.cli.main import use_host_cores
use_host_cores()
from mjx_balance.runtime import cache
from mjx_balance.bench import pipeline
from mjx_balance.model.config_files import load_config
cache.enable()
config = load_config(sys.argv[1])
slots = None if sys.argv[2] == "none" else int(sys.argv[2])
with cache.CompileCounter() as counter:
    built = pipeline.build_batched(config, slots=slots, early_stop=sys.argv[3] == "1",
                                   physics=sys.argv[4])
print(json.dumps({"compile_s": built["compile_s"], **counter.as_dict()}))
"""


def compile_cache_times(
    config: Config,
    slots: int | None,
    early_stop: bool,
    timeout: float = 1800.0,
    physics: str = "mjx",
) -> dict:
    """The engine's compile time in a first process (an empty persistent cache) and in a
    second one (the cache the first filled), each a fresh interpreter: compile_first_s,
    compile_cached_s, and the second's cache hits and XLA compilations (0: nothing compiled).
    On a failure: {"compile_cache_error": the reason}."""
    with tempfile.TemporaryDirectory(prefix="mjx_balance-bench-cache-") as tmp:
        config_path = Path(tmp) / "config.toml"
        write_text(dumps_config(config), config_path)
        env = {**os.environ, "MJX_BALANCE_CACHE_DIR": str(Path(tmp) / "jax")}
        argv = [
            sys.executable,
            "-c",
            COMPILE_SCRIPT,
            str(config_path),
            "none" if slots is None else str(slots),
            "1" if early_stop else "0",
            physics,
        ]
        runs = []
        for _ in range(2):
            try:
                proc = subprocess.run(
                    argv, env=env, capture_output=True, text=True, timeout=timeout
                )
            except subprocess.TimeoutExpired:
                return {"compile_cache_error": f"a compile took over {timeout:.0f} s"}
            if proc.returncode != 0:
                last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
                return {"compile_cache_error": last}
            runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    first, cached = runs
    return {
        "compile_first_s": round(first["compile_s"], 3),
        "compile_cached_s": round(cached["compile_s"], 3),
        "compile_cached_hits": cached["cache_hits"],
        "compile_cached_compiles": cached["compiles"],
    }


def pool_line(result: dict, workers: int, label: str) -> str:
    """One worker pool's figures in a line."""
    per = result["per"]
    return (
        f"  {label}: {len(per)} scenarios in {result['seconds']:.1f} s on {workers} processes "
        f"(warm-up {result['warm_s']:.1f} s; per scenario median {np.median(per):.2f} s, "
        f"max {per.max():.2f} s)"
    )


def run_pools(
    config: Config,
    ref_config: Config,
    forces: Any,
    durations: Any,
    counts: tuple[int, int, int],
    workers: int,
    say: Callable[[str], None],
) -> tuple[Any, Any, Any]:
    """The scalar reference and the study toolchain in worker processes (each skipped at a
    count of 0; IPOPT also without casadi): (reference, ipopt, the IPOPT scenarios' indices,
    with the reference's outcome mix when it ran)."""
    _, n_ref, n_ipopt = counts
    ref = ipopt = None
    if n_ref:
        cap = ref_config.controller.osqp_max_iter
        ref = run_reference_pool(ref_config, forces[:n_ref], durations[:n_ref], workers)
        say(pool_line(ref, workers, f"reference (MuJoCo C + OSQP, max_iter {cap})"))
    ipopt_idx = np.arange(n_ipopt)
    if n_ipopt and ref is not None:
        ipopt_idx = stratified_subset(ref["outcomes"], n_ipopt)
    if n_ipopt:
        if not casadi_available():
            say("  CasADi/IPOPT: casadi not installed, skipped")
        else:
            ipopt = run_ipopt_pool(config, forces[ipopt_idx], durations[ipopt_idx], workers)
            say(pool_line(ipopt, workers, "study toolchain (MuJoCo C + CasADi/IPOPT)"))
    return ref, ipopt, ipopt_idx


PATH_NAMES = {"mjx": "MJX + ADMM", "c": "MuJoCo C + ADMM"}


def run_physics_paths(
    config: Config,
    forces: Any,
    durations: Any,
    *,
    physics: str | None,
    slots: int | None,
    full_length: bool,
    repeats: int,
    say: Callable[[str], None],
) -> tuple[str, dict, dict]:
    """Every physics path on the same scenarios: the default one with continuous batching and
    --full-length (or only --full-length), the others with continuous batching. Returns (the
    default path, label -> (built, result) of the default path's runs, path -> its figures)."""

    n_mjx = len(forces)
    default = resolve(physics or "auto", config)
    paths = [default] + [
        p for p in PATHS[1:] if p != default and not (p == "c" and unsupported(config))
    ]
    runs, backends = {}, {}
    for path in paths:
        modes = [("--full-length", False)] if path == default else []
        if not full_length:  # both on the same scenarios, compared
            modes.insert(0, ("continuous batching", True))
        for label, early in modes:
            built = build_batched(config, slots=slots, early_stop=early, physics=path)
            name = f"{PATH_NAMES[path]}, {label}"
            say(
                f"  {name}: build {built['build_s']:.1f} s, compile {built['compile_s']:.1f} s "
                f"({built['slots']} slots on each of {built['devices']} {built['platform']} "
                "device(s))"
            )
            result = run_batched(built, config, forces, durations, repeats)
            say(
                f"  {name}: {n_mjx} scenarios in {result['seconds']:.1f} s (median of "
                f"{result['repeats']}; {n_mjx / result['seconds']:.1f} scen/s; mean simulated "
                f"{result['simulated_s']:.2f} s per scenario, {result['certified']} certified; "
                f"{result['physics_steps_per_s']:,.0f} physics steps/s; mean ADMM iterations "
                f"per period {result['admm_iterations_per_period']:.1f})"
            )
            if path == default:
                runs[label] = (built, result)
            if early or full_length:
                backends[path] = dict(
                    scen_per_s=round(n_mjx / result["seconds"], 3),
                    seconds=round(result["seconds"], 3),
                    compile_s=round(built["compile_s"], 3),
                    slots=built["slots"],
                    outcomes=result["outcomes"],
                )
    return default, runs, backends
