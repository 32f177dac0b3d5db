"""The region sweep and the robustness table run into an output folder, as every caller runs
them: grids read as the command line reads them, the batch function of the continuous-batching
engine, the persistent compilation cache on, the folder's lock held.

The public API (``api.sweep``, ``api.table``), the command line and the studies (compare,
landscape, sensitivity) all call these, so the three run a folder the same way.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Union

from ..model.params import Config
from ..runtime import cache
from ..store.folder import folder_lock
from .acting_time import TableResult, run_table, table_batch_size
from .batch import LazyBatch
from .grid import check_durations, parse_grid
from .region import SweepResult, run_sweep

if TYPE_CHECKING:
    import numpy as np

log = logging.getLogger("mjx_balance")

Values = Union[str, float, Sequence[float], "np.ndarray"]

def grid_values(values: Values, name: str) -> "np.ndarray":
    """Forces or durations as ``sweep`` reads a grid: sorted, each value once."""
    if isinstance(values, (int, float)) and not isinstance(values, bool):
        values = [values]
    if not isinstance(values, str):
        values = [float(v) for v in values]
    return parse_grid(values, name)

def duration_values(values: Values, config: Config, name: str = "durations") -> "np.ndarray":
    """Durations on the grid, in [0, t_end] and whole physics steps (snapped to them)."""
    return check_durations(grid_values(values, name), config.scenario.t_end, name,
                           physics_dt=config.scenario.physics_dt)

def batch_function(config: Config, *, slots: int | None = None, full_length: bool = False,
                   physics: str = "auto"):
    """The batch function of ``sweep`` and ``table``: the batched closed loop of ``config`` on
    the continuous-batching engine, built and compiled on its first call (with the persistent
    compilation cache on, :func:`mjx_balance.runtime.cache.enable`). ``physics``: "mjx", "c" (MuJoCo C
    stepped on a thread pool, the ADMM in JAX) or "auto" (docs/engine.md)."""
    return LazyBatch(config, slots=slots, early_stop=not full_length, physics=physics)

def run_region(out: str | os.PathLike[str], config: Config, forces: Values, durations: Values,
               *, run_batch: Any = None, chunk: int | None = None, slots: int | None = None,
               full_length: bool = False, progress: bool = False,
               wait: bool = False, cluster: Any = None, physics: str = "auto") -> "SweepResult":
    """The region sweep into the folder ``out`` (resumable; ``sweep.run_sweep``) under its lock
    (``wait``: wait for another run that holds it). ``run_batch``: a batch function (default:
    :func:`batch_function`); ``cluster``: run the chunks on a Dask cluster (``"local:N"``, a
    scheduler address or file, or a ``distributed.Client``; docs/cluster.md). Returns the
    SweepResult (the command line draws its figures)."""
    forces = grid_values(forces, "forces")
    durations = duration_values(durations, config)
    if run_batch is None:
        run_batch = batch_function(config, slots=slots, full_length=full_length,
                                   physics=physics)
    cache.enable()
    with folder_lock(out, wait=wait):
        return run_sweep(out, config, forces, durations, run_batch=run_batch, chunk_size=chunk,
                         progress=progress, log=log.info, cluster=cluster)

def run_table_folder(out: str | os.PathLike[str], config: Config, forces: Values, *,
                     run_batch: Any = None, batch: int | None = None, slots: int | None = None,
                     full_length: bool = False, progress: bool = False,
                     wait: bool = False, cluster: Any = None,
                     physics: str = "auto") -> "TableResult | None":
    """The max-acting-time table into the folder ``out`` (``sweep.run_table``: resumable, the
    scenarios it ran kept) under its lock. ``batch``: scenarios per call (default:
    ``sweep.table_batch_size``); ``cluster``: run each round's calls on a Dask cluster (as
    :func:`run_region`; the same table). Returns None when the folder already held this
    table."""
    forces = grid_values(forces, "forces")
    if run_batch is None:
        run_batch = batch_function(config, slots=slots, full_length=full_length,
                                   physics=physics)
    if batch is None:
        batch = table_batch_size(config, forces.size)
    cache.enable()
    with folder_lock(out, wait=wait):
        return run_table(out, config, forces, run_batch=run_batch, batch=batch,
                         progress=progress, log=log.info, cluster=cluster)
