"""How many scenarios go into one batch call: the memory budget, power-of-two chunk sizes."""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

from ..model.params import Config, ParameterError


def scenario_bytes(config: Config, dtype_bytes: int = 4) -> int:
    """Rough device memory of one scenario in a batched rollout [bytes].

    Counts the per-scenario arrays that live through the rollout: the MJX data of the five-dof,
    four-contact model (about 4000 numbers: positions, velocities, mass matrix, contact Jacobians
    and constraint rows, body frames) and the ADMM iterates and warm start (about 8 vectors of the
    QP size n + m), times a factor of 16 for XLA's temporaries inside one physics step and one
    ADMM iteration, which the scan keeps alive at once. The estimate only has to be right to a
    factor of a few: chunks sized from it use a fraction of the budget.
    """
    n = 2 * config.controller.horizon
    m = 6 * config.controller.horizon
    numbers = 4000 + 8 * (n + m) + 2 * n * n  # n^2: per-scenario factor slices in some solvers
    return int(numbers * dtype_bytes * 16)


def memory_budget() -> int:
    """Bytes a chunk may use: a quarter of the device memory (GPU) or of the free RAM (CPU)."""
    try:
        import jax

        device = jax.devices()[0]
        stats = device.memory_stats() if device.platform != "cpu" else None
        if stats and "bytes_limit" in stats:
            return int(0.25 * (stats["bytes_limit"] - stats.get("bytes_in_use", 0)))
    except Exception:
        pass
    try:
        with open("/proc/meminfo") as fh:
            info = {line.split(":")[0]: int(line.split()[1]) * 1024 for line in fh}
        return int(0.25 * info.get("MemAvailable", info["MemTotal"]))
    except (OSError, KeyError, ValueError):
        return 1 << 30


def _is_cpu() -> bool:
    try:
        import jax

        return jax.default_backend() == "cpu"
    except Exception:
        return True


# On a CPU the throughput stops growing beyond batches of a few dozen scenarios (compare
# `mjx-balance bench --chunk N --reference 0 --ipopt 0` for N = 8, 64, 256), and a smaller
# chunk shows progress sooner and loses less when interrupted.
CPU_CHUNK_CAP = 128
ACCELERATOR_CHUNK_CAP = 16384


def batch_limit(config: Config) -> int:
    """Most scenarios per batch call: what fits the memory budget, capped (CPU_CHUNK_CAP)."""
    fit = max(1, memory_budget() // scenario_bytes(config))
    return min(fit, CPU_CHUNK_CAP if _is_cpu() else ACCELERATOR_CHUNK_CAP)


def default_chunk_size(config: Config, n_cells: int) -> int:
    """Scenarios per chunk file: a power of two within ``batch_limit``, see
    ``power_of_two_chunk``. (The engine streams every chunk through one queue of fixed slots,
    so the chunk size only sets how much a killed sweep loses; batch functions that run fixed
    batches are padded to it.)"""
    return power_of_two_chunk(n_cells, batch_limit(config))


def power_of_two_chunk(n_cells: int, limit: int, minimum: int = 64, waste: float = 0.1) -> int:
    """The largest power of two c (minimum <= c <= limit, as far as possible) whose chunks,
    all padded to c, evaluate at most ``(1 + waste) * n_cells`` scenarios; if none does, the
    one that wastes least."""
    limit = max(1, int(limit))
    sizes = [1 << e for e in range(0, max(1, limit).bit_length()) if (1 << e) <= limit]
    small = 1 << max(3, math.ceil(math.log2(max(n_cells, 1))))  # a batch as small as the grid
    sizes = [c for c in sizes if c >= min(minimum, small, sizes[-1])]
    cost = {c: math.ceil(n_cells / c) * c for c in sizes}
    good = [c for c in sizes if cost[c] <= (1 + waste) * n_cells]
    return max(good) if good else min(sizes, key=lambda c: (cost[c], -c))


def chunk_slices(n_cells: int, chunk_size: int) -> list[slice]:
    """Consecutive slices of size chunk_size (the last may be shorter) covering range(n_cells)."""
    if chunk_size < 1:
        raise ParameterError(f"chunk size must be >= 1, got {chunk_size}")
    return [slice(i, min(i + chunk_size, n_cells)) for i in range(0, n_cells, chunk_size)]


# The guard on enormous work. The rate is the engine's throughput on the 2-core CPU of this
# project with two host devices, counted in scenario windows (a scenario stops when decided, so
# what it simulates depends on the grid), slowest and fastest: the benchmark's mix (BENCHMARKS.md,
# "The pipeline benchmark") and the dense study map ("The dense study map"). A GPU is far
# faster (the estimate is then pessimistic: --yes).
SIMULATED_SECONDS_PER_SECOND = (88 * 12.0, 130 * 12.0)
# Those rates were measured on 12-s windows whose scenarios the engine decides early (a fall, a
# certified recovery: 1.29 s simulated per scenario on average, BENCHMARKS.md), so a shorter
# window does not make a scenario cheaper: the engine's work is planned as at least a 12-s
# window each (a plan proportional to the window said 21-32 min for 1,001,000 cells of 2 s, which
# ran at the 2-3.5 h its progress bar showed). The scalar reference runs every window whole.
RATE_WINDOW = 12.0
# Disk per scenario in a chunk file, rounded up from a default sweep's 64-row chunks
# (BENCHMARKS.md, "Disk"); the merged region.parquet holds the same rows again.
CHUNK_BYTES_PER_SCENARIO = 650
# The scalar reference (MuJoCo C + OSQP, one scenario at a time: simulate), hard pushes (bounds
# active: OSQP iterates long) to light ones (BENCHMARKS.md, "The scalar reference's rate").
REFERENCE_SECONDS_PER_SECOND = (1.0, 15.0)
# What a cohort spends on a subject outside the engine: its configuration checked before the
# folder is made (studies.cohort.plan_cohort: the QP, its conditioning, the batched closed
# loop's build; every subject of a small cohort, a large one's representatives), and its map
# set up in the one queue (runs.population: its closed loop built and checked when its queue
# starts, its folder written from the queue's results), on the 2-core CPU (python
# docs/scripts/cohort_setup.py; BENCHMARKS.md, "A cohort's set-up").
SUBJECT_CHECK_SECONDS = 0.05
# What a command spends before its first scenario, besides its own checks: on the batched path
# the engine's program loaded from the compile cache or compiled, with the process's start
# (JAX, the runners); the scalar reference starts MuJoCo and OSQP and draws each push's
# figures. Fewest and most seconds on the 2-core CPU, rounded out from tiny runs' 8.9-10.6 s
# with the compile cache warm and 25.6-28.0 s cold, and simulate's 4.4-4.5 s for one push
# (python docs/scripts/startup.py; BENCHMARKS.md, "A cohort's set-up and memory").
ENGINE_STARTUP = (10.0, 30.0, "the engine's program loaded from the compile cache, or compiled")
REFERENCE_STARTUP = (4.0, 5.0, "the process started, the models built")
SUBJECT_SETUP_SECONDS = 0.09
MAX_PLANNED_SCENARIOS = 2_000_000  # more than this needs --yes
MAX_PLANNED_HOURS = 24.0  # an estimate (at the slower rate) beyond this needs --yes


def _wall_time(seconds: float) -> str:
    """A duration in the unit that reads best (s, min or h)."""
    if seconds < 120:
        return f"{max(1, round(seconds))} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:,.1f} h"


def wall_span(shortest: float, longest: float) -> str:
    """An estimated wall time between ``shortest`` and ``longest`` seconds, rounded as it
    reads: "under 1 s", "about 3 s", "about 2 to 4 min"."""
    if longest < 1:
        return "under 1 s"
    low, high = _wall_time(shortest), _wall_time(longest)
    if low == high:
        return f"about {low}"
    if low.split()[-1] == high.split()[-1]:  # one unit: "about 2 to 4 min"
        return f"about {low.rsplit(' ', 1)[0]} to {high}"
    return f"about {low} to {high}"


def planned_seconds(n_scenarios: int, t_end: float, rate: float, window_floor: float) -> float:
    """Wall seconds of ``n_scenarios`` windows of ``t_end`` at ``rate`` window-s/s, each
    counted as at least ``window_floor`` seconds (RATE_WINDOW)."""
    return n_scenarios * max(t_end, window_floor) / rate


def planned_work(
    n_scenarios: int,
    t_end: float,
    chunk_size: int | None,
    what: str = "cells",
    *,
    rate: tuple[float, float] = SIMULATED_SECONDS_PER_SECOND,
    bytes_per_scenario: int = 2 * CHUNK_BYTES_PER_SCENARIO,
    setup: tuple[float, str] = (0.0, ""),
    window_floor: float = RATE_WINDOW,
    during: tuple[float, str] = (0.0, ""),
    startup: tuple[float, float, str] = (0.0, 0.0, ""),
) -> str:
    """One line: scenarios, chunks (unless ``chunk_size`` is None), simulated time, estimated
    wall time at ``rate`` (window-s/s: slower, faster; each scenario at least ``window_floor``
    seconds of window, RATE_WINDOW), ``startup``: (fewest, most seconds, what) before the work
    starts (ENGINE_STARTUP, REFERENCE_STARTUP), disk, ``during``: (seconds, what) of set-up
    spread over the run (a cohort's subjects built queue by queue), and ``setup``: (seconds,
    what) spent before the first scenario, each when there is any."""
    simulated = n_scenarios * t_end
    longest, shortest = (planned_seconds(n_scenarios, t_end, r, window_floor) for r in rate)
    disk = n_scenarios * bytes_per_scenario  # (chunks + the merged table, by default)
    low, high = rate
    chunks = "" if chunk_size is None else math.ceil(n_scenarios / chunk_size)
    chunks = (
        ""
        if chunk_size is None
        else (f" in {chunks:,} chunk{'' if chunks == 1 else 's'} of {chunk_size}")
    )
    return (
        f"planned work: {n_scenarios:,} {what}{chunks}, {simulated:,.0f} s of scenario "
        f"windows, {wall_span(shortest, longest)} at {low:g}-{high:g} window-s/s "
        + (
            f"(each scenario as a {window_floor:g}-s window: decided early, a shorter one costs "
            "no less; "
            if t_end < window_floor
            else "("
        )
        + "2-core CPU, BENCHMARKS.md)"
        + (
            f" plus {wall_span(startup[0], startup[1])} of start-up ({startup[2]})"
            if startup[1] >= 1
            else ""
        )
        + (
            f" plus {wall_span(during[0], during[0])} of {during[1]} during the run"
            if during[0] >= 1
            else ""
        )
        + f", about {_size(disk)} on disk"
        + (
            f", after {wall_span(setup[0], setup[0])} of {setup[1]} before the first scenario"
            if setup[0] >= 1
            else ""
        )
    )


def _size(n: float) -> str:
    """Bytes as they read: 0.5 MB, 12 MB, 3.4 GB."""
    return f"{n / 1e9:.3g} GB" if n >= 1e9 else f"{n / 1e6:.3g} MB"


def check_planned_work(
    n_scenarios: int,
    t_end: float,
    what: str = "cells",
    *,
    rate: tuple[float, float] = SIMULATED_SECONDS_PER_SECOND,
    scenarios_limit: int = MAX_PLANNED_SCENARIOS,
    setup_s: float = 0.0,
    window_floor: float = RATE_WINDOW,
) -> None:
    """Refuse work above ``scenarios_limit`` or MAX_PLANNED_HOURS at the slower ``rate`` (each
    scenario at least ``window_floor`` seconds of window), the set-up before the first
    scenario (``setup_s``) included (ParameterError, one line saying how to go ahead anyway:
    --yes)."""
    hours = (planned_seconds(n_scenarios, t_end, rate[0], window_floor) + setup_s) / 3600
    if n_scenarios > scenarios_limit or hours > MAX_PLANNED_HOURS:
        raise ParameterError(
            f"{n_scenarios:,} {what} of {t_end:g} s (up to {hours:,.1f} h on a 2-core CPU) is "
            f"beyond the limit of {scenarios_limit:,} {what} or {MAX_PLANNED_HOURS:g} h; "
            "use a coarser grid, or pass --yes to run it anyway"
        )


class PlannedWork(NamedTuple):
    """The work a request is about to do, said and guarded before anything is compiled or
    written (the command line's plan line and its refusal above the limit without --yes).
    An API function that takes a ``plan`` callable calls it once with this, after every
    check and before the folder is touched."""

    config: Config  # the configuration whose window and rate the estimate uses
    scenarios: int  # region cells (or table scenarios)
    what: str = "cells"  # what they are, for the line
    extra: int = 0  # table scenarios beyond them, at most
    chunk_size: int | None = None
    reference: bool = False  # run one at a time by the scalar reference (its rate)
    note: str = ""  # what the work gives, after a semicolon


PlanHook = Callable[[PlannedWork], None]  # what a request calls with its planned work
