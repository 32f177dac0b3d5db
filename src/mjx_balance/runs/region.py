"""The recoverable region: every cell of a force x duration grid, resumably.

The grid (force-major: all durations of the first force, then the next force) is split into
chunks of one size (a power of two that fits the memory budget, ``chunks.py``; every call
padded to it, so the rollout compiles one function); each chunk is written to its own file as
soon as it is done (``store/folder.py``). On restart, chunk files that read back with exactly their
cells are kept and the others (damaged, partial, from another grid) are recomputed; a folder
made with another configuration or grid is refused. A folder that lost its manifest but whose
config.toml matches is taken up again once its chunk files (or region.parquet) check out
against the grid. The run's entry holds the folder's lock (``store.folder.folder_lock``)
throughout; :func:`run_sweep` checks that it does.

With ``cluster`` (``cluster.py``, docs/cluster.md) the chunks run as Dask tasks on a cluster's
workers; everything else (the manifest, the chunk plan, the resume check, writing each chunk
file, the merge) stays here, on the driver.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from ..measures.outcomes import check_results
from ..model.params import Config, ParameterError
from .batch import LazyBatch, RunBatch, chunk_frames, evaluate, resume_engine, streams
from .chunks import chunk_slices, default_chunk_size
from .cluster import ClusterBatch
from .grid import Grid, describe
from .progress import progress_bar
from ..store.files import MANIFEST, REGION, write_atomic
from ..store.folder import (
    OutputFolder,
    chunk_path,
    require_lock,
    merge_chunks,
    read_chunk,
    same_values,
    write_chunk,
)


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


def check_region(region: pd.DataFrame, grid: Grid) -> None:
    """Every grid cell exactly once, in grid order."""
    cell_f, cell_d = grid.cells
    if len(region) != cell_f.size:
        raise RuntimeError(f"region has {len(region)} rows for {cell_f.size} cells")
    if region.duplicated(["force", "duration"]).any():
        raise RuntimeError("region has a repeated cell")
    if not (same_values(region["force"], cell_f) and same_values(region["duration"], cell_d)):
        raise RuntimeError("region cells differ from the grid")


def run_sweep(
    out: str | os.PathLike[str],
    config: Config,
    grid: Grid,
    *,
    run_batch: RunBatch | None = None,
    chunk: int | None = None,
    progress: bool | None = True,
    say: Callable[[str], None] | None = print,
    cluster: Any = None,
) -> SweepResult:
    """Evaluate every cell of ``grid`` (:class:`grid.Grid`, checked for ``config``),
    resumably, into ``out/region.parquet``.

    run_batch: batch function (default: the MJX rollout of ``config``), called with at most
    ``chunk`` scenarios at a time (every call padded to exactly ``chunk``).
    chunk: scenarios per chunk file and per call (default: from the memory budget; the
    manifest records it as ``chunk_size``). A folder keeps the chunk size it was started with.
    cluster: run the chunks on a Dask cluster (``cluster.ClusterBatch``): ``"local:N"`` (N
    local worker processes), a scheduler address, or a ``distributed.Client``; None: here.
    """
    grid.fits(config)
    # the run's entry holds the folder's lock: a failure below marks the run failed
    require_lock(out)
    if cluster is None:
        result = _run_sweep(out, config, grid, run_batch, chunk, progress, say)
    else:
        with ClusterBatch(cluster, run_batch or LazyBatch(config), config, say) as on_cluster:
            result = _run_sweep(out, config, grid, on_cluster, chunk, progress, say)
    check_results(pd.read_parquet(result.region_path, columns=["outcome"])["outcome"], "cells")
    return result


def _run_sweep(
    out: str | os.PathLike[str],
    config: Config,
    grid: Grid,
    run_batch: Any,
    chunk_size: int | None,
    progress: bool | None,
    say: Callable[[str], None] | None,
) -> SweepResult:
    # (run_batch: a batch function, None, or a cluster.ClusterBatch, found by its methods)
    say = say or (lambda _msg: None)
    start = time.perf_counter()
    cell_f, cell_d = grid.cells
    n_cells = cell_f.size
    folder = OutputFolder(out, config)
    manifest = folder.open()
    region_path = folder.path / REGION
    convention = config.controller.convention
    run_batch = run_batch or LazyBatch(config)

    chunk_size = _region_record(folder, manifest, config, grid, chunk_size, run_batch, say)
    slices = chunk_slices(n_cells, chunk_size)

    # A finished sweep: region.parquet that holds exactly the grid.
    if region_path.exists():
        try:
            check_region(pd.read_parquet(region_path, columns=["force", "duration"]), grid)
            say(f"sweep already complete: {region_path} ({n_cells} cells); nothing to do")
            return SweepResult(region_path, 0, len(slices), 0, time.perf_counter() - start, True)
        except Exception as exc:
            say(f"{region_path} is damaged ({exc}); rebuilding it")

    (folder.path / "chunks").mkdir(exist_ok=True)
    todo, recomputed = _chunks_to_do(folder.path, slices, cell_f, cell_d, convention, say)
    reused = len(slices) - len(todo)
    remaining = sum(slices[i].stop - slices[i].start for i in todo)
    if reused:
        say(f"resuming: {reused} of {len(slices)} chunks already done, {remaining} cells to go")
    say(
        f"sweep: {grid.describe()} in {len(slices)} chunks of {chunk_size}; convention "
        f"{convention}; output {folder.path}"
    )

    if todo:
        folder.check_numerics(manifest)  # new rows: computed as the folder's were
        if hasattr(run_batch, "prepare"):
            run_batch.prepare(chunk_size, say=say)
        bar = progress_bar(n_cells, n_cells - remaining, progress)
        try:
            _compute_chunks(
                run_batch,
                folder.path,
                slices,
                todo,
                cell_f,
                cell_d,
                config=config,
                chunk_size=chunk_size,
                bar=bar,
            )
        finally:
            bar.close()

    write_atomic(
        region_path, lambda tmp: merge_chunks(folder.path, slices, cell_f, cell_d, convention, tmp)
    )
    seconds = time.perf_counter() - start
    say(f"wrote {region_path} ({n_cells} cells; {len(todo)} chunks computed in {seconds:.1f} s)")
    return SweepResult(region_path, len(todo), reused, recomputed, seconds, False)


def _region_record(
    folder: OutputFolder,
    manifest: dict,
    config: Config,
    grid: Grid,
    chunk_size: int | None,
    run_batch: RunBatch,
    say: Callable[[str], None],
) -> int:
    """The chunk size of the sweep in ``folder``: the recorded one (and the recorded engine
    settings) when resuming, else a new record written to the manifest (after adopting results
    that lost their manifest, if they match the grid)."""
    region_path = folder.path / REGION
    convention = config.controller.convention
    n_cells = grid.n_cells
    recorded = manifest.get("region")
    if recorded is not None:
        if not grid.matches(recorded):
            raise ParameterError(
                f"{folder.path} holds a sweep over another grid (forces "
                f"{describe(recorded['forces'])}, durations {describe(recorded['durations'])}); "
                "use another --out folder or the same grid"
            )
        if chunk_size is not None and chunk_size != recorded["chunk_size"]:
            say(
                f"note: {folder.path} was started with chunks of {recorded['chunk_size']} "
                f"scenarios; keeping that (ignoring --chunk {chunk_size})"
            )
        chunk_size = int(recorded["chunk_size"])
        resume_engine(run_batch, recorded.get("engine"), folder.path, say)
    else:
        if chunk_size is not None and chunk_size < 1:
            raise ParameterError(f"--chunk must be >= 1, got {chunk_size}")
        chunk_size = chunk_size or default_chunk_size(config, n_cells)
        found = sorted((folder.path / "chunks").glob("chunk-*.parquet"))
        if found or (folder.rebuilt and region_path.exists()):
            # Region results without a record of their grid (a lost manifest): adopt them only
            # if they check out against this grid.
            chunk_size, adopted = _adopt_results(folder.path, found, grid, convention, chunk_size)
            say(
                f"note: {folder.path} had lost its {MANIFEST}; rebuilt it: config.toml matches "
                f"this run and {adopted} match the grid"
            )
        elif folder.rebuilt:
            say(
                f"note: {folder.path} had lost its {MANIFEST}; rebuilt it: config.toml matches "
                "this run"
            )
        manifest["region"] = {**grid.record(), "chunk_size": int(chunk_size), "cells": int(n_cells)}
        record = run_batch.engine_record() if hasattr(run_batch, "engine_record") else None
        if record is not None:
            manifest["region"]["engine"] = record
        folder.write_manifest(manifest)
    return int(chunk_size)


def _chunks_to_do(
    path: Path,
    slices: list[slice],
    cell_f: np.ndarray,
    cell_d: np.ndarray,
    convention: str,
    say: Callable[[str], None],
) -> tuple[list[int], int]:
    """(chunks to compute, how many of them were damaged). Chunk files are checked one at a
    time and not kept: peak memory is one chunk, not the grid."""
    todo: list[int] = []
    recomputed = 0
    for index, cells in enumerate(slices):
        file = chunk_path(path, index)
        frame, reason = read_chunk(file, cell_f[cells], cell_d[cells], convention)
        if frame is None:
            todo.append(index)
            if reason != "missing":
                recomputed += 1
                say(f"chunk {index} ({file.name}) is damaged: {reason}; recomputing it")
    return todo, recomputed


def _compute_chunks(
    run_batch: RunBatch,
    path: Path,
    slices: list[slice],
    todo: list[int],
    cell_f: np.ndarray,
    cell_d: np.ndarray,
    *,
    config: Config,
    chunk_size: int,
    bar: Any,
) -> None:
    """Compute the chunks ``todo`` and write each chunk file: through the engine's queue when
    the batch function streams, else one padded call per chunk (or on a cluster's workers)."""
    if hasattr(run_batch, "compute_chunks"):  # cluster.ClusterBatch: written here as they return
        run_batch.compute_chunks(
            slices,
            todo,
            cell_f,
            cell_d,
            chunk_size,
            lambda index, frame: write_chunk(frame, path, index),
            bar,
        )
        return
    if streams(run_batch):
        _stream_chunks(
            run_batch, path, [slices[i] for i in todo], todo, cell_f, cell_d, config, bar
        )
        return
    for index in todo:
        cells = slices[index]
        frame = evaluate(run_batch, cell_f[cells], cell_d[cells], config, pad_to=chunk_size)
        write_chunk(frame, path, index)
        bar.update(cells.stop - cells.start)


def _stream_chunks(
    run_batch: Any,
    path: Path,
    slices: list[slice],
    indices: list[int],
    cell_f: np.ndarray,
    cell_d: np.ndarray,
    config: Config,
    bar: Any,
) -> None:
    """Every cell of the chunks through the engine's queue at once (its slots stay busy across
    chunk boundaries); a chunk file is written as soon as its last cell is decided."""
    for k, rows in chunk_frames(run_batch, slices, cell_f, cell_d, config, bar.update):
        write_chunk(rows, path, indices[k])


def _adopt_results(
    path: Path, found: list[Path], grid: Grid, convention: str, chunk_size: int
) -> tuple[int, str]:
    """The chunk size of results found without a manifest, and what matched (for the message).

    Every chunk but the last holds chunk_size cells, so the largest chunk file gives it; the
    chunk files that then read back with exactly their cells are kept (the others are
    recomputed as damaged). With no chunk files, a region.parquet that holds exactly the grid
    is kept. Raises ParameterError when nothing matches this grid.
    """
    import pyarrow.parquet as pq

    cell_f, cell_d = grid.cells
    rows = []
    for file in found:
        try:
            rows.append(pq.ParquetFile(file).metadata.num_rows)
        except Exception:
            pass
    if rows:
        size = max(rows)
        slices = chunk_slices(cell_f.size, size)
        good = sum(
            read_chunk(chunk_path(path, i), cell_f[cells], cell_d[cells], convention)[0] is not None
            for i, cells in enumerate(slices)
        )
        if good:
            return size, f"{good} of {len(found)} chunk files"
    elif (path / REGION).exists():
        try:
            check_region(pd.read_parquet(path / REGION, columns=["force", "duration"]), grid)
            return chunk_size, REGION
        except Exception:
            pass
    raise ParameterError(
        f"{path} holds results but no {MANIFEST}, and they do not match this "
        "grid; use another --out folder or the grid they were made with"
    )
