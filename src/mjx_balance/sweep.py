"""Sweeps over pushes: the recoverable region and the max-acting-time table (SPEC §4, §6.3–6.4).

Two products, both written into one output folder ``DIR``:

region   every cell of a force x duration grid, one summary row per cell
         (``metrics.SUMMARY_COLUMNS``) -> ``DIR/region.parquet``
table    for each force, the max acting time: the largest duration T (to ``resolution``, 0.01 s)
         such that every duration up to T recovers -> ``DIR/table.csv``

Scenarios are evaluated by a *batch function* ``run_batch(forces, durations)`` taking two
equal-length float arrays and returning one summary row per scenario, in order (a DataFrame
with outcome strings or a dict of columns with integer outcome codes). By default it is
``rollout.BatchRunner(config).run_frame``; every function here takes it as an argument, so the
bookkeeping (chunking, resume, bisection) can be tested with a cheap stand-in.

The region sweep is resumable. The grid (force-major: all durations of the first force, then the
next force) is split into chunks of one size (a power of two that fits the memory budget; every
call padded to it, so the rollout compiles one function); each chunk is written to
``DIR/chunks/chunk-NNNNN.parquet`` atomically (temporary file in the same folder, then
``os.replace``), so a chunk file is either complete or absent. On restart, chunk files that read
back with exactly their cells are kept and the others (damaged, partial, from another grid) are
recomputed. ``DIR/manifest.json`` records the package version, the configuration and the grid
(``DIR/config.toml`` the configuration as TOML); a folder made with another configuration or
grid is refused.

The table uses a batched bisection: one coarse scan of durations for all forces in one batch
(it brackets the max acting time and checks that recovery is monotone in duration), then rounds
that each evaluate one midpoint per force, all forces in one batch, until the bracket is one
``resolution`` step wide. Given a fixed batch size (the commands use one), each round evaluates
several points per bracket instead (k-section), so every call has that size.

Commands: ``sweep_command`` (region.parquet, region.png, energy.png; with no grid given, the
built-in DEFAULT_SWEEP, which also writes the table) and ``table_command`` (table.csv,
table.png). A sweep definition (sweeps/*.toml) holds [body]/[controller]/[scenario] overrides
and a [sweep] table; the command line overrides both.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np
import pandas as pd

from . import __version__
from .metrics import OUTCOMES, SUMMARY_COLUMNS
from .cli import base_config
from .params import Config, ParameterError, save_config

RunBatch = Callable[[np.ndarray, np.ndarray], "pd.DataFrame | dict[str, np.ndarray]"]

RECOVERED = OUTCOMES[0]

# The robustness table of the study (SPEC §6.3).
STUDY_TABLE_FORCES = (5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 120)

# Coarse scan of the table: durations [s] tried for every force before bisecting. 0.1 s is
# always included (the table reports the energies there); t_end is added.
COARSE_DURATIONS = (0.01, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)

# The built-in default sweep (the README's main job; the same as sweeps/default.toml): a coarse
# region map and a short table that finish in a few minutes on a 2-core CPU.
DEFAULT_SWEEP = {
    "forces": "0:150:10",
    "durations": "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5",
    "table_forces": "20,50,80,100,120",
    "chunk": 64,
}

MANIFEST = "manifest.json"
REGION = "region.parquet"
TABLE = "table.csv"
TABLE_RUNS = "table_runs.parquet"

_GRID_TOL = 1e-9  # how far a value may sit beyond a limit (float error) and still count


# ---------------------------------------------------------------------------------------------
# Grids


def parse_grid(spec: str | float | Sequence[float], name: str = "grid") -> np.ndarray:
    """Values of a grid: ``"start:stop:step"`` (stop included when it lands on the grid, up to
    float error), a comma list ``"a,b,c"``, a number or a list of numbers.

    Returns the values sorted ascending (float64). Raises ParameterError for an empty grid, a
    non-finite value, a step <= 0, a repeated value or text that is not a number.
    """
    if isinstance(spec, str):
        text = spec.strip()
        if not text:
            raise ParameterError(f"{name}: empty grid")
        if ":" in text:
            values = _parse_range(text, name)
        else:
            values = [_number(item, name) for item in text.split(",") if item.strip()]
    elif isinstance(spec, (int, float)) and not isinstance(spec, bool):
        values = [float(spec)]
    elif isinstance(spec, (list, tuple, np.ndarray)):
        values = [_number(item, name) for item in spec]
    else:
        raise ParameterError(f"{name} = {spec!r}: must be 'start:stop:step', a comma list or numbers")
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        raise ParameterError(f"{name}: empty grid")
    if not np.all(np.isfinite(values)):
        raise ParameterError(f"{name}: every value must be finite, got {values[~np.isfinite(values)][:3]}")
    values = np.sort(values)
    repeated = values[1:][np.diff(values) == 0]
    if repeated.size:
        raise ParameterError(f"{name}: value {repeated[0]:g} appears more than once")
    return values


def _number(item: Any, name: str) -> float:
    if isinstance(item, bool):
        raise ParameterError(f"{name}: {item!r} is not a number")
    try:
        return float(item.strip() if isinstance(item, str) else item)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}: {item!r} is not a number") from None


def _parse_range(text: str, name: str) -> list[float]:
    parts = text.split(":")
    if len(parts) != 3:
        raise ParameterError(f"{name} = {text!r}: a range is start:stop:step")
    start, stop, step = (_number(p, name) for p in parts)
    if not all(math.isfinite(v) for v in (start, stop, step)):
        raise ParameterError(f"{name} = {text!r}: start, stop and step must be finite")
    if step <= 0:
        raise ParameterError(f"{name} = {text!r}: step must be > 0")
    if stop < start:
        raise ParameterError(f"{name} = {text!r}: empty grid (stop < start)")
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > 10_000_000:
        raise ParameterError(f"{name} = {text!r}: {count} values is too many")
    values = start + step * np.arange(count)
    # Remove float error (0.1 * 3 = 0.30000000000000004) without moving any real grid value.
    return [float(v) for v in np.round(values, 12)]


def check_durations(durations: np.ndarray, t_end: float, name: str = "durations") -> np.ndarray:
    """Durations must lie in [0, t_end] (t_end = scenario.t_end); returns them unchanged."""
    if np.any(durations < 0):
        raise ParameterError(f"{name}: push durations must be >= 0, got {durations.min():g}")
    if np.any(durations > t_end + _GRID_TOL):
        raise ParameterError(
            f"{name}: push durations must not exceed scenario.t_end = {t_end:g} s, "
            f"got {durations.max():g}")
    return durations


def grid_cells(forces: np.ndarray, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All (force, duration) cells, force-major: [F0 d0, F0 d1, ..., F1 d0, ...]."""
    f, d = np.meshgrid(forces, durations, indexing="ij")
    return f.ravel(), d.ravel()


# ---------------------------------------------------------------------------------------------
# Chunking


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
    except Exception:  # noqa: BLE001 - no device information: fall back to host memory
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
    except Exception:  # noqa: BLE001
        return True


# On a CPU the throughput stops growing at about 64 scenarios per batch (2-core CPU, 12 s
# scenarios: 14 simulated s/s at 8, 41 at 64, 34 at 256), and a smaller chunk shows progress
# sooner and loses less when interrupted.
CPU_CHUNK_CAP = 128
ACCELERATOR_CHUNK_CAP = 16384


def batch_limit(config: Config) -> int:
    """Most scenarios per batch call: what fits the memory budget, capped (CPU_CHUNK_CAP)."""
    fit = max(1, memory_budget() // scenario_bytes(config))
    return min(fit, CPU_CHUNK_CAP if _is_cpu() else ACCELERATOR_CHUNK_CAP)


def default_chunk_size(config: Config, n_cells: int) -> int:
    """Scenarios per chunk: a power of two within ``batch_limit`` (the rollout compiles one
    function per power-of-two batch size and pads to it, and every chunk call is padded to the
    chunk size, so one size is compiled and little is wasted), see ``power_of_two_chunk``."""
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


# ---------------------------------------------------------------------------------------------
# Evaluating a batch


def default_batch(config: Config) -> RunBatch:
    """The MJX batched rollout for this configuration (compiled on first call)."""
    from .rollout import BatchRunner

    return BatchRunner(config).run_frame


class LazyBatch:
    """The default batch function, built on its first call (a finished sweep builds nothing)."""

    def __init__(self, config: Config):
        self.config = config
        self._run: RunBatch | None = None

    def __call__(self, forces: np.ndarray, durations: np.ndarray):
        if self._run is None:
            self._run = default_batch(self.config)
        return self._run(forces, durations)

    def prepare(self, batch: int, log: Callable[[str], None] | None = print) -> None:
        """Build the rollout and compile it for ``batch`` scenarios now (before a progress bar
        starts, so that its rate and time left are those of the runs)."""
        say = log or (lambda _msg: None)
        start = time.perf_counter()
        if self._run is None:
            say("building the MJX rollout ...")
            self._run = default_batch(self.config)
        runner = getattr(self._run, "__self__", None)
        if hasattr(runner, "compiled"):  # rollout.BatchRunner: one function per power of two
            size = 1 << max(3, math.ceil(math.log2(max(batch, 1))))
            if size not in getattr(runner, "_compiled_fns", {}):
                say(f"compiling the rollout for batches of {size} scenarios ...")
            runner.compiled(size)
        seconds = time.perf_counter() - start
        if seconds > 1:
            say(f"rollout ready ({seconds:.0f} s)")


def evaluate(run_batch: RunBatch, forces: np.ndarray, durations: np.ndarray, config: Config,
             pad_to: int | None = None) -> pd.DataFrame:
    """Summary rows for the scenarios (forces[i], durations[i]), in order.

    The batch is padded to ``pad_to`` scenarios by repeating its last one (a batch of a fixed
    size is compiled once), and the padding is dropped. The result has the SUMMARY_COLUMNS in
    order (extra columns after them), outcome as strings, and force/duration equal to the values
    asked for (a float32 rollout hands them back rounded).
    """
    forces = np.asarray(forces, dtype=np.float64)
    durations = np.asarray(durations, dtype=np.float64)
    count = forces.size
    if count == 0:
        return pd.DataFrame(columns=SUMMARY_COLUMNS)
    if pad_to is not None and pad_to > count:
        extra = pad_to - count
        forces_in = np.concatenate([forces, np.full(extra, forces[-1])])
        durations_in = np.concatenate([durations, np.full(extra, durations[-1])])
    else:
        forces_in, durations_in = forces, durations
    frame = summary_frame(run_batch(forces_in, durations_in), config)
    if len(frame) != forces_in.size:
        raise RuntimeError(f"batch function returned {len(frame)} rows for {forces_in.size} scenarios")
    frame = frame.iloc[:count].reset_index(drop=True)
    for column, asked in (("force", forces), ("duration", durations)):
        got = frame[column].to_numpy(dtype=np.float64)
        if not np.allclose(got, asked, rtol=1e-5, atol=1e-6):
            raise RuntimeError(f"batch function returned rows for other {column}s than asked")
        frame[column] = asked
    return frame


def summary_frame(result: pd.DataFrame | dict[str, Any], config: Config) -> pd.DataFrame:
    """A batch result as a DataFrame in SUMMARY_COLUMNS order with outcome strings."""
    frame = result.copy() if isinstance(result, pd.DataFrame) else pd.DataFrame(
        {k: np.asarray(v) for k, v in result.items()})
    if "convention" not in frame:
        frame["convention"] = config.controller.convention
    missing = [c for c in SUMMARY_COLUMNS if c not in frame]
    if missing:
        raise RuntimeError(f"batch result lacks column(s) {', '.join(missing)}")
    if pd.api.types.is_numeric_dtype(frame["outcome"]):
        codes = frame["outcome"].to_numpy()
        if np.any((codes < 0) | (codes >= len(OUTCOMES))):
            raise RuntimeError(f"batch result has outcome codes outside 0..{len(OUTCOMES) - 1}")
        frame["outcome"] = np.asarray(OUTCOMES, dtype=object)[codes.astype(int)]
    bad = set(frame["outcome"]) - set(OUTCOMES)
    if bad:
        raise RuntimeError(f"batch result has unknown outcome(s) {sorted(bad)}")
    frame["outcome"] = frame["outcome"].astype(str)
    frame["convention"] = frame["convention"].astype(str)
    extra = [c for c in frame.columns if c not in SUMMARY_COLUMNS]
    return frame[SUMMARY_COLUMNS + extra].reset_index(drop=True)


# ---------------------------------------------------------------------------------------------
# The output folder


def write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    """Write a file atomically: ``write(tmp)`` to a temporary file beside it, then rename."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _write_parquet(frame: pd.DataFrame, path: Path) -> None:
    write_atomic(path, lambda tmp: frame.to_parquet(tmp, index=False))


def _write_text(text: str, path: Path) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(text))


def _config_dict(config: Config) -> dict[str, Any]:
    return json.loads(json.dumps(config.to_dict()))


def _config_differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    out = []
    for section in sorted(set(old) | set(new)):
        a, b = old.get(section, {}), new.get(section, {})
        for key in sorted(set(a) | set(b)):
            if a.get(key) != b.get(key):
                out.append(f"{section}.{key}: folder has {a.get(key)!r}, this run {b.get(key)!r}")
    return out


def _same_values(a: Sequence[float], b: Sequence[float]) -> bool:
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=0, atol=_GRID_TOL))


class OutputFolder:
    """The output folder DIR: manifest.json, config.toml, chunks/, region.parquet, table.csv."""

    def __init__(self, path: str | Path, config: Config):
        self.path = Path(path)
        self.config = config
        self.manifest_path = self.path / MANIFEST

    def read_manifest(self) -> dict[str, Any] | None:
        if not self.manifest_path.exists():
            return None
        try:
            return json.loads(self.manifest_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ParameterError(f"{self.manifest_path}: unreadable manifest ({exc}); "
                                 "use another --out folder") from None

    def open(self) -> dict[str, Any]:
        """Create the folder or check that it was made with this configuration."""
        self.path.mkdir(parents=True, exist_ok=True)
        for stale in self.path.glob(".*.tmp"):
            stale.unlink(missing_ok=True)
        manifest = self.read_manifest()
        config = _config_dict(self.config)
        if manifest is None:
            if any(self.path.glob("*.parquet")) or (self.path / "chunks").exists():
                raise ParameterError(f"{self.path} holds results but no {MANIFEST}; "
                                     "use another --out folder")
            manifest = {"package": "mjx_balance", "version": __version__, "config": config}
            self.write_manifest(manifest)
            save_config(self.config, self.path / "config.toml")
            return manifest
        differences = _config_differences(manifest.get("config", {}), config)
        if differences:
            raise ParameterError(
                f"{self.path} was made with a different configuration; use another --out folder "
                "or the same configuration (its config.toml). Differences: "
                + "; ".join(differences[:6]) + (" ..." if len(differences) > 6 else ""))
        if manifest.get("version") != __version__:
            print(f"note: {self.path} was made by mjx_balance {manifest.get('version')}, "
                  f"this is {__version__}; continuing", file=sys.stderr)
        return manifest

    def write_manifest(self, manifest: dict[str, Any]) -> None:
        _write_text(json.dumps(manifest, indent=2) + "\n", self.manifest_path)


# ---------------------------------------------------------------------------------------------
# Region sweep


@dataclass
class SweepResult:
    region_path: Path  # region.parquet, every cell once, in grid order
    computed_chunks: int  # chunks evaluated in this call
    reused_chunks: int  # chunks read back from an earlier call
    recomputed_chunks: int  # damaged chunk files found and recomputed
    seconds: float
    already_complete: bool

    @property
    def region(self) -> pd.DataFrame:
        """The merged table, read from disk on demand (the sweep itself never holds it all)."""
        return pd.read_parquet(self.region_path)


def _chunk_path(folder: Path, index: int) -> Path:
    return folder / "chunks" / f"chunk-{index:05d}.parquet"


def read_chunk(path: Path, forces: np.ndarray, durations: np.ndarray,
               convention: str) -> tuple[pd.DataFrame | None, str]:
    """A chunk file if it holds exactly the given cells in order, else (None, reason)."""
    if not path.exists():
        return None, "missing"
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:  # noqa: BLE001 - any read failure means: recompute
        return None, f"unreadable ({type(exc).__name__})"
    if len(frame) != forces.size:
        return None, f"{len(frame)} rows, expected {forces.size}"
    missing = [c for c in SUMMARY_COLUMNS if c not in frame]
    if missing:
        return None, f"missing column(s) {', '.join(missing[:3])}"
    if not (_same_values(frame["force"], forces) and _same_values(frame["duration"], durations)):
        return None, "cells differ from the grid"
    if not set(frame["outcome"]) <= set(OUTCOMES):
        return None, "unknown outcomes"
    if not (frame["convention"] == convention).all():
        return None, "other convention"
    return frame, "ok"


def _check_region(region: pd.DataFrame, forces: np.ndarray, durations: np.ndarray) -> None:
    """Every grid cell exactly once, in grid order."""
    cell_f, cell_d = grid_cells(forces, durations)
    if len(region) != cell_f.size:
        raise RuntimeError(f"region has {len(region)} rows for {cell_f.size} cells")
    if region.duplicated(["force", "duration"]).any():
        raise RuntimeError("region has a repeated cell")
    if not (_same_values(region["force"], cell_f) and _same_values(region["duration"], cell_d)):
        raise RuntimeError("region cells differ from the grid")


def run_sweep(out: str | Path, config: Config, forces: np.ndarray, durations: np.ndarray, *,
              run_batch: RunBatch | None = None, chunk_size: int | None = None,
              progress: bool = True, log: Callable[[str], None] | None = print) -> SweepResult:
    """Evaluate every (force, duration) cell, resumably, into ``out/region.parquet``.

    run_batch: batch function (default: the MJX rollout of ``config``), called with at most
    ``chunk_size`` scenarios at a time (every call padded to exactly chunk_size).
    chunk_size: scenarios per chunk (default: from the memory budget). A folder keeps the chunk
    size it was started with.
    """
    say = log or (lambda _msg: None)
    start = time.perf_counter()
    forces = parse_grid(forces, "forces")
    durations = check_durations(parse_grid(durations, "durations"), config.scenario.t_end)
    cell_f, cell_d = grid_cells(forces, durations)
    n_cells = cell_f.size
    folder = OutputFolder(out, config)
    manifest = folder.open()
    region_path = folder.path / REGION

    recorded = manifest.get("region")
    if recorded is not None:
        if not (_same_values(recorded["forces"], forces)
                and _same_values(recorded["durations"], durations)):
            raise ParameterError(
                f"{folder.path} holds a sweep over another grid (forces {_describe(recorded['forces'])}, "
                f"durations {_describe(recorded['durations'])}); use another --out folder or the "
                "same grid")
        if chunk_size is not None and chunk_size != recorded["chunk_size"]:
            say(f"note: {folder.path} was started with chunks of {recorded['chunk_size']} "
                f"scenarios; keeping that (ignoring --chunk {chunk_size})")
        chunk_size = int(recorded["chunk_size"])
    else:
        if chunk_size is None:
            chunk_size = default_chunk_size(config, n_cells)
        elif chunk_size < 1:
            raise ParameterError(f"--chunk must be >= 1, got {chunk_size}")
        manifest["region"] = {"forces": forces.tolist(), "durations": durations.tolist(),
                              "chunk_size": int(chunk_size), "cells": int(n_cells)}
        folder.write_manifest(manifest)

    slices = chunk_slices(n_cells, chunk_size)
    convention = config.controller.convention

    # A finished sweep: region.parquet that holds exactly the grid.
    if region_path.exists():
        try:
            _check_region(pd.read_parquet(region_path, columns=["force", "duration"]),
                          forces, durations)
            say(f"sweep already complete: {region_path} ({n_cells} cells); nothing to do")
            return SweepResult(region_path, 0, len(slices), 0, time.perf_counter() - start, True)
        except Exception as exc:  # noqa: BLE001 - rebuild it from the chunks
            say(f"{region_path} is damaged ({exc}); rebuilding it")

    (folder.path / "chunks").mkdir(exist_ok=True)
    # Chunk files are checked one at a time and not kept: peak memory is one chunk, not the grid.
    todo: list[int] = []
    recomputed = 0
    for index, cells in enumerate(slices):
        path = _chunk_path(folder.path, index)
        frame, reason = read_chunk(path, cell_f[cells], cell_d[cells], convention)
        if frame is None:
            todo.append(index)
            if reason != "missing":
                recomputed += 1
                say(f"chunk {index} ({path.name}) is damaged: {reason}; recomputing it")
    reused = len(slices) - len(todo)
    remaining = sum(slices[i].stop - slices[i].start for i in todo)
    if reused:
        say(f"resuming: {reused} of {len(slices)} chunks already done, {remaining} cells to go")
    say(f"sweep: {forces.size} forces x {durations.size} durations = {n_cells} cells in "
        f"{len(slices)} chunks of {chunk_size}; convention {convention}; output {folder.path}")

    if todo:
        run_batch = run_batch or LazyBatch(config)
        if hasattr(run_batch, "prepare"):
            run_batch.prepare(chunk_size, log=log)
        bar = _progress_bar(n_cells, n_cells - remaining, progress)
        try:
            for index in todo:
                cells = slices[index]
                frame = evaluate(run_batch, cell_f[cells], cell_d[cells], config, pad_to=chunk_size)
                _write_parquet(frame, _chunk_path(folder.path, index))
                bar.update(cells.stop - cells.start)
        finally:
            bar.close()

    write_atomic(region_path, lambda tmp: _merge_chunks(folder.path, slices, cell_f, cell_d,
                                                        convention, tmp))
    seconds = time.perf_counter() - start
    say(f"wrote {region_path} ({n_cells} cells; {len(todo)} chunks computed in {seconds:.1f} s)")
    return SweepResult(region_path, len(todo), reused, recomputed, seconds, False)


def _merge_chunks(folder: Path, slices: list[slice], cell_f: np.ndarray, cell_d: np.ndarray,
                  convention: str, out: Path) -> None:
    """Stream the chunk files into one parquet file, one chunk in memory at a time.

    Each chunk is checked again against its slice of the grid (read_chunk), so the merged file
    holds every cell exactly once and in grid order without ever being held whole.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    # Row groups of ~64k rows: one per chunk would make the file's metadata, which the writer
    # holds until it closes, grow by ~50 kB per chunk (measured: +150 MiB at 400k cells).
    rows_per_group = 65536
    writer, schema, pending, pending_rows = None, None, [], 0

    def flush() -> None:
        nonlocal pending, pending_rows
        if pending:
            writer.write_table(pa.concat_tables(pending), row_group_size=rows_per_group)
            pending, pending_rows = [], 0

    try:
        for index, cells in enumerate(slices):
            frame, reason = read_chunk(_chunk_path(folder, index), cell_f[cells], cell_d[cells],
                                       convention)
            if frame is None:
                raise RuntimeError(f"chunk {index} changed while merging: {reason}")
            table = pa.Table.from_pandas(frame, preserve_index=False)
            if writer is None:
                schema = table.schema
                writer = pq.ParquetWriter(out, schema)
            pending.append(table.cast(schema))
            pending_rows += table.num_rows
            if pending_rows >= rows_per_group:
                flush()
        flush()
    finally:
        if writer is not None:
            writer.close()


def _describe(values: Sequence[float]) -> str:
    values = list(values)
    if len(values) <= 4:
        return ",".join(f"{v:g}" for v in values)
    return f"{values[0]:g}..{values[-1]:g} ({len(values)} values)"


class _NoBar:
    def update(self, _n: int) -> None:
        pass

    def close(self) -> None:
        pass


def _progress_bar(total: int, done: int, enabled: bool):
    if not enabled:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=done, unit="scen", desc="scenarios", dynamic_ncols=True,
                smoothing=0.1, file=sys.stderr)


# ---------------------------------------------------------------------------------------------
# Max acting time


TABLE_COLUMNS = [
    "force", "max_acting_time",
    "energy_ankle_01", "energy_hip_01", "energy_total_01",
    "energy_ankle_max", "energy_hip_max", "energy_total_max",
    "ending_outcome", "monotone", "recovered_beyond_failure",
    "outcome_01", "settle_time_01", "settle_time_max",
    "energy_u1_01", "energy_u2_01", "energy_u1_max", "energy_u2_max",
    "convention", "evaluations", "note",
]


@dataclass
class TableResult:
    table: pd.DataFrame  # TABLE_COLUMNS, one row per force
    runs: pd.DataFrame  # every scenario evaluated (summary rows), in evaluation order
    seconds: float


def coarse_steps(t_end: float, resolution: float,
                 durations: Iterable[float] = COARSE_DURATIONS) -> np.ndarray:
    """Coarse scan durations in units of ``resolution``: the given ones that fit in t_end, 0.1 s,
    and t_end itself (at least one step)."""
    n_max = int(math.floor(t_end / resolution + 1e-9))
    if n_max < 1:
        raise ParameterError(f"scenario.t_end = {t_end:g} s is shorter than the resolution {resolution:g} s")
    steps = {int(round(d / resolution)) for d in (*durations, 0.1) if d <= t_end + _GRID_TOL}
    steps.add(n_max)
    return np.array(sorted(s for s in steps if 1 <= s <= n_max), dtype=np.int64)


def table_batch_size(config: Config, n_forces: int, resolution: float = 0.01) -> int:
    """Default batch of the table: the coarse scan in one call (rounded up to a power of two,
    as the rollout compiles), within ``batch_limit``."""
    n = n_forces * coarse_steps(config.scenario.t_end, resolution).size
    limit = batch_limit(config)
    return min(1 << max(3, math.ceil(math.log2(max(n, 1)))), max(limit, n_forces))


def _evaluate_batches(run_batch: RunBatch, forces: np.ndarray, durations: np.ndarray,
                      config: Config, batch: int | None) -> pd.DataFrame:
    """``evaluate`` in calls of exactly ``batch`` scenarios (padded), or one call if None."""
    if batch is None:
        return evaluate(run_batch, forces, durations, config)
    return pd.concat([evaluate(run_batch, forces[s], durations[s], config, pad_to=batch)
                      for s in chunk_slices(forces.size, batch)], ignore_index=True)


def max_acting_time(forces: np.ndarray | str | Sequence[float], config: Config, *,
                    run_batch: RunBatch | None = None, resolution: float = 0.01,
                    coarse: Iterable[float] = COARSE_DURATIONS, batch: int | None = None,
                    points_per_round: int | None = None, progress: bool = True,
                    log: Callable[[str], None] | None = print) -> TableResult:
    """Max acting time of every force (SPEC §4): the largest T, a multiple of ``resolution`` in
    [0, t_end], such that the push (F, T) recovers and so does every duration tried below it.

    1. Coarse scan: the durations ``coarse_steps`` for every force, one batch. The first failure
       brackets T between the last recovered coarse duration and it. A recovered coarse duration
       beyond the first failure means recovery is not monotone in duration: the row says
       ``monotone = False`` and gives the largest such duration (``recovered_beyond_failure``);
       the max acting time is still the end of the first recovered range.
    2. Bisection: every round evaluates the midpoint of each force's bracket, all forces in one
       batch of a fixed size, until every bracket is one resolution step wide. This assumes
       monotone recovery inside a bracket (the coarse scan found no exception there).
       ``points_per_round = k > 1`` evaluates k evenly spaced points per bracket per round
       instead (k-section: fewer, larger batches; worth it where a batch of n_f * k scenarios
       costs about as much as one of n_f, as on a GPU, or to reuse a compiled batch size).

    batch: if given, every call has exactly this many scenarios (padded, or split), so a
    rollout compiles one function for the whole table; points_per_round then defaults to
    max(1, batch // n_f). Without it, the coarse scan is one call of n_f * n_coarse and every
    round one call of n_f * points_per_round (default 1: bisection).

    A force whose shortest push (one resolution step) fails gets max_acting_time 0; one that
    recovers up to t_end gets t_end and no ending outcome. The energies "_01" are at T = 0.1 s
    (whatever its outcome; see outcome_01), "_max" at the max acting time.
    """
    say = log or (lambda _msg: None)
    start = time.perf_counter()
    forces = parse_grid(forces, "table forces")
    t_end = config.scenario.t_end
    if not resolution > 0:
        raise ParameterError(f"resolution must be > 0, got {resolution}")
    if batch is not None and not (isinstance(batch, int) and batch >= 1):
        raise ParameterError(f"batch must be an integer >= 1, got {batch!r}")
    if points_per_round is None:
        points_per_round = max(1, batch // forces.size) if batch else 1
    if not (isinstance(points_per_round, int) and points_per_round >= 1):
        raise ParameterError(f"points_per_round must be an integer >= 1, got {points_per_round!r}")
    steps = coarse_steps(t_end, resolution, coarse)
    n_max = int(math.floor(t_end / resolution + 1e-9))
    run_batch = run_batch or LazyBatch(config)
    n_f, n_c = forces.size, steps.size
    if hasattr(run_batch, "prepare"):
        run_batch.prepare(batch or n_f * n_c, log=log)
    widest = int(np.diff(np.concatenate([[0], steps])).max())
    rounds = math.ceil(math.log(max(2, widest)) / math.log(points_per_round + 1))
    say(f"table: {n_f} forces; coarse scan of {n_c} durations, then "
        + ("bisection" if points_per_round == 1 else f"{points_per_round + 1}-section")
        + f" to {resolution:g} s" + (f" in batches of {batch}" if batch else "")
        + f"; convention {config.controller.convention}")
    bar = _progress_bar(n_f * (n_c + rounds * points_per_round), 0, progress)
    runs: list[pd.DataFrame] = []
    try:
        # 1. Coarse scan, one batch.
        grid_f = np.repeat(forces, n_c)
        grid_d = np.tile(steps * resolution, n_f)
        coarse_frame = _evaluate_batches(run_batch, grid_f, np.round(grid_d, 12), config, batch)
        runs.append(coarse_frame)
        bar.update(n_f * n_c)
        recovered = (coarse_frame["outcome"].to_numpy() == RECOVERED).reshape(n_f, n_c)
        rows = coarse_frame.to_dict("records")
        coarse_rows = [rows[i * n_c:(i + 1) * n_c] for i in range(n_f)]

        first_fail = np.where(recovered.all(axis=1), n_c, np.argmin(recovered, axis=1))
        lo = np.zeros(n_f, dtype=np.int64)  # recovered (0: nothing recovered yet)
        hi = np.full(n_f, n_max + 1, dtype=np.int64)  # failed (n_max + 1: nothing failed)
        lo_row: list[dict | None] = [None] * n_f
        hi_row: list[dict | None] = [None] * n_f
        monotone = np.ones(n_f, dtype=bool)
        beyond = np.full(n_f, np.nan)
        evaluations = np.full(n_f, n_c, dtype=np.int64)
        for i in range(n_f):
            j = first_fail[i]
            if j > 0:
                lo[i], lo_row[i] = steps[j - 1], coarse_rows[i][j - 1]
            if j < n_c:
                hi[i], hi_row[i] = steps[j], coarse_rows[i][j]
                later = np.flatnonzero(recovered[i, j + 1:])
                if later.size:
                    monotone[i] = False
                    beyond[i] = steps[j + 1 + later[-1]] * resolution

        # 2. Bisection (k-section for points_per_round = k > 1): one batch per round, of the
        #    fixed size n_f * k; a force's bracket (lo, hi) shrinks to the gap around its first
        #    failing point.
        k_points = int(points_per_round)
        for _round in range(64):
            active = np.flatnonzero((hi - lo > 1) & (hi <= n_max))
            if active.size == 0:
                break
            owner, points = [], []
            for i in active:
                split = lo[i] + (hi[i] - lo[i]) * np.arange(1, k_points + 1) // (k_points + 1)
                split = np.unique(split[(split > lo[i]) & (split < hi[i])])
                owner += [i] * split.size
                points += split.tolist()
            owner, points = np.asarray(owner), np.asarray(points, dtype=np.int64)
            durations = np.round(points * resolution, 12)
            frame = (_evaluate_batches(run_batch, forces[owner], durations, config, batch)
                     if batch else evaluate(run_batch, forces[owner], durations, config,
                                            pad_to=n_f * k_points))
            runs.append(frame)
            bar.update(points.size)
            ok = frame["outcome"].to_numpy() == RECOVERED
            rows = frame.to_dict("records")
            for i in active:
                mine = np.flatnonzero(owner == i)  # ascending durations
                evaluations[i] += mine.size
                failing = mine[~ok[mine]]
                if failing.size:
                    first = failing[0]
                    hi[i], hi_row[i] = points[first], rows[first]
                    below = mine[mine < first]
                else:
                    below = mine
                if below.size:
                    lo[i], lo_row[i] = points[below[-1]], rows[below[-1]]
        else:  # pragma: no cover - the bracket halves every round
            raise RuntimeError("bisection did not converge")
        if not isinstance(bar, _NoBar):
            bar.total = bar.n  # the round count was an upper estimate
            bar.refresh()
    finally:
        bar.close()

    index_01 = int(round(0.1 / resolution))
    table_rows = []
    for i, force in enumerate(forces):
        at_01 = next((r for s, r in zip(steps, coarse_rows[i]) if s == index_01), None)
        at_max = lo_row[i]
        note = ""
        if lo[i] == 0:
            note = f"fails at the shortest push tried ({steps[0] * resolution:g} s)"
        elif hi[i] > n_max:
            note = f"recovers for every duration up to t_end = {t_end:g} s"
        elif hi_row[i] is not None and hi_row[i]["outcome"] == "not_settled":
            note = (f"a longer push does not fall but is not settled by t_end = {t_end:g} s "
                    "(limited by the time window)")
        if not monotone[i]:
            note = (note + "; " if note else "") + (
                f"not monotone: fails at {hi[i] * resolution:g} s but recovers again at "
                f"{beyond[i]:g} s (coarse scan)")
        table_rows.append({
            "force": float(force),
            "max_acting_time": round(float(lo[i] * resolution), 12),
            "energy_ankle_01": _get(at_01, "energy_ankle"),
            "energy_hip_01": _get(at_01, "energy_hip"),
            "energy_total_01": _get(at_01, "energy_total"),
            "energy_ankle_max": _get(at_max, "energy_ankle"),
            "energy_hip_max": _get(at_max, "energy_hip"),
            "energy_total_max": _get(at_max, "energy_total"),
            "ending_outcome": hi_row[i]["outcome"] if hi_row[i] is not None else "",
            "monotone": bool(monotone[i]),
            "recovered_beyond_failure": beyond[i],
            "outcome_01": at_01["outcome"] if at_01 is not None else "",
            "settle_time_01": _get(at_01, "settle_time"),
            "settle_time_max": _get(at_max, "settle_time"),
            "energy_u1_01": _get(at_01, "energy_u1"),
            "energy_u2_01": _get(at_01, "energy_u2"),
            "energy_u1_max": _get(at_max, "energy_u1"),
            "energy_u2_max": _get(at_max, "energy_u2"),
            "convention": config.controller.convention,
            "evaluations": int(evaluations[i]),
            "note": note,
        })
    table = pd.DataFrame(table_rows, columns=TABLE_COLUMNS)
    runs_frame = pd.concat(runs, ignore_index=True)
    seconds = time.perf_counter() - start
    say(f"table: {len(runs_frame)} scenarios in {seconds:.1f} s")
    return TableResult(table, runs_frame, seconds)


def _get(row: dict | None, key: str) -> float:
    return float(row[key]) if row is not None else float("nan")


def run_table(out: str | Path, config: Config, forces: np.ndarray | str | Sequence[float], *,
              run_batch: RunBatch | None = None, progress: bool = True,
              log: Callable[[str], None] | None = print, **options: Any) -> TableResult | None:
    """``max_acting_time`` into ``out/table.csv`` (+ table_runs.parquet, every scenario run).

    Returns None (and does nothing) when the folder already holds the table for these forces.
    """
    say = log or (lambda _msg: None)
    forces = parse_grid(forces, "table forces")
    folder = OutputFolder(out, config)
    manifest = folder.open()
    recorded = manifest.get("table")
    table_path = folder.path / TABLE
    if recorded is not None and _same_values(recorded["forces"], forces) and table_path.exists():
        try:
            done = pd.read_csv(table_path)
            if _same_values(done["force"], forces):
                say(f"table already complete: {table_path} ({forces.size} forces); nothing to do")
                return None
        except Exception:  # noqa: BLE001 - recompute a damaged table
            pass
    if recorded is not None and not _same_values(recorded["forces"], forces):
        say(f"replacing the table for forces {_describe(recorded['forces'])} in {folder.path}")
    result = max_acting_time(forces, config, run_batch=run_batch, progress=progress, log=log,
                             **options)
    _write_parquet(result.runs, folder.path / TABLE_RUNS)
    write_atomic(table_path, lambda tmp: result.table.to_csv(tmp, index=False))
    manifest = folder.read_manifest() or manifest
    manifest["table"] = {"forces": forces.tolist(), "resolution": options.get("resolution", 0.01)}
    folder.write_manifest(manifest)
    say(f"wrote {table_path}")
    return result


# ---------------------------------------------------------------------------------------------
# Sweep definitions and the commands


_SWEEP_KEYS = ("forces", "durations", "table_forces", "chunk")


@dataclass
class SweepDefinition:
    """A sweep TOML: configuration overrides plus the [sweep] table."""

    config: Config
    forces: Any = None
    durations: Any = None
    table_forces: Any = None
    chunk: int | None = None


def load_sweep(path: str | Path | None, base: Config) -> SweepDefinition:
    """Read a sweep definition: optional [body]/[controller]/[scenario] (overriding ``base``)
    and a [sweep] table with forces, durations, table_forces (grid strings or number lists) and
    chunk. ``None`` gives the built-in default sweep (DEFAULT_SWEEP)."""
    if path is None:
        return SweepDefinition(base, **DEFAULT_SWEEP)
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ParameterError(f"sweep definition not found: {path}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{path}: not valid TOML: {exc}") from None
    sweep = data.pop("sweep", {})
    if not isinstance(sweep, dict):
        raise ParameterError(f"{path}: [sweep] must be a table")
    unknown = sorted(set(sweep) - set(_SWEEP_KEYS))
    if unknown:
        raise ParameterError(f"{path}: [sweep] has unknown key(s) {', '.join(unknown)}; "
                             f"known: {', '.join(_SWEEP_KEYS)}")
    try:
        config = base.replace(**data) if data else base
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None
    chunk = sweep.get("chunk")
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1):
        raise ParameterError(f"{path}: [sweep] chunk must be an integer >= 1, got {chunk!r}")
    return SweepDefinition(config, sweep.get("forces"), sweep.get("durations"),
                           sweep.get("table_forces"), chunk)


def _with_convention(config: Config, convention: str | None) -> Config:
    return config.replace(controller={"convention": convention}) if convention else config


def sweep_command(args: Any) -> int:
    """``mjx-balance sweep``: region.parquet, region.png, energy.png in --out.

    Without --forces, --durations or --sweep it runs the built-in default sweep and also writes
    the table (table.csv, table.png) into the same folder.
    """
    from . import region_plots

    use_default = args.sweep is None and args.forces is None and args.durations is None
    definition = load_sweep(args.sweep, base_config(args))
    if args.sweep is None and not use_default:
        # A grid from the command line: the region only, chunk size from the memory budget.
        definition.table_forces = definition.chunk = None
    config = _with_convention(definition.config, args.convention)
    forces = args.forces if args.forces is not None else (
        definition.forces if definition.forces is not None else DEFAULT_SWEEP["forces"])
    durations = args.durations if args.durations is not None else (
        definition.durations if definition.durations is not None else DEFAULT_SWEEP["durations"])
    chunk = args.chunk if args.chunk is not None else definition.chunk
    # Check everything before any work.
    forces = parse_grid(forces, "forces")
    durations = check_durations(parse_grid(durations, "durations"), config.scenario.t_end)
    table_forces = (parse_grid(definition.table_forces, "table_forces")
                    if definition.table_forces is not None else None)
    reference = region_plots.load_reference(args.reference) if args.reference else None
    if use_default:
        print("no grid given: running the built-in default sweep "
              f"(forces {DEFAULT_SWEEP['forces']} N, durations {DEFAULT_SWEEP['durations']} s, "
              f"table forces {DEFAULT_SWEEP['table_forces']} N)")

    out = Path(args.out)
    run_batch = LazyBatch(config)  # built (and compiled) only if a scenario must run
    result = run_sweep(out, config, forces, durations, run_batch=run_batch, chunk_size=chunk)
    _make_region_figures(out, result.region, config, reference, force=not result.already_complete)
    if table_forces is not None:
        # The table in calls of the sweep's chunk size: the rollout compiled for it already.
        chunk_used = json.loads((out / MANIFEST).read_text())["region"]["chunk_size"]
        table = run_table(out, config, table_forces, run_batch=run_batch, batch=int(chunk_used))
        _make_table_figure(out, config, force=table is not None)
    return 0


def table_command(args: Any) -> int:
    """``mjx-balance table``: table.csv and table.png in --out."""
    definition = load_sweep(args.sweep, base_config(args)) if args.sweep else None
    config = _with_convention(definition.config if definition else base_config(args),
                              args.convention)
    if args.forces is not None:
        forces = args.forces
    elif definition is not None and definition.table_forces is not None:
        forces = definition.table_forces
    else:
        forces = list(STUDY_TABLE_FORCES)
    forces = parse_grid(forces, "forces")
    out = Path(args.out)
    table = run_table(out, config, forces, run_batch=LazyBatch(config),
                      batch=table_batch_size(config, forces.size))
    _make_table_figure(out, config, force=table is not None)
    return 0


def _make_region_figures(out: Path, region: pd.DataFrame, config: Config,
                         reference: pd.DataFrame | None, force: bool) -> None:
    from . import region_plots

    targets = {"region.png": region_plots.plot_region, "energy.png": region_plots.plot_energy}
    for name, plot in targets.items():
        path = out / name
        if force or not path.exists() or reference is not None:
            kwargs = {"reference": reference} if name == "region.png" else {}
            plot(region, path, config=config, **kwargs)
            print(f"wrote {path}")


def _make_table_figure(out: Path, config: Config, force: bool) -> None:
    from . import region_plots

    path = out / "table.png"
    if force or not path.exists():
        region_plots.plot_table(pd.read_csv(out / TABLE, keep_default_na=True), path, config=config)
        print(f"wrote {path}")
