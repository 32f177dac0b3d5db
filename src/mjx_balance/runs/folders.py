"""The region sweep and the robustness table run into an output folder, as every caller runs
them: grids read as the command line reads them, the batch function of the continuous-batching
engine, the persistent compilation cache on, the folder's lock held.

The public API (``api.sweep``, ``api.table``), the command line and the studies (compare,
landscape, sensitivity) all call these, so the three run a folder the same way.
"""

from __future__ import annotations

import logging
import math
import numbers
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Union

from ..model.params import Config, ParameterError
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
    """Forces or durations as ``sweep`` reads a grid: sorted, each value once. ``values``: a
    grid string (``"0:150:10"``, ``"20,50,80"``), a number or a sequence of numbers (NumPy's
    too); a bool, a string inside a list or anything else is refused (ParameterError, a
    ValueError naming ``name``)."""
    if isinstance(values, str):
        return parse_grid(values, name)
    expected = ("a number, a sequence of numbers or a grid string such as '0:150:10' or "
                "'20,50,80'")
    if _is_bool(values):
        raise ParameterError(f"{name}: expected {expected}; got a bool ({values!r})")
    if isinstance(values, numbers.Real):
        values = [values]
    try:
        items = list(values)
    except TypeError:
        raise ParameterError(f"{name}: expected {expected}; got {type(values).__name__} "
                             f"({values!r})") from None
    for item in items:
        if _is_bool(item) or not isinstance(item, numbers.Real):
            raise ParameterError(f"{name}: expected {expected}; got {item!r} "
                                 f"({type(item).__name__}) in the list")
    return parse_grid([float(v) for v in items], name)


def _is_bool(value: Any) -> bool:
    return isinstance(value, bool) or type(value).__name__ == "bool_"


def size_value(value: Any, name: str) -> int | None:
    """An optional size (``chunk``, ``slots``, ``batch``): None, or a whole number >= 1 (Python
    or NumPy integer, or a float with no fraction); anything else is refused with a
    ParameterError (a ValueError) naming ``name``."""
    if value is None:
        return None
    if _is_bool(value) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} = {value!r}: must be a whole number >= 1 (or None for "
                             f"the default); got {type(value).__name__}")
    if not (math.isfinite(value) and float(value) == int(value) and value >= 1):
        raise ParameterError(f"{name} = {value!r}: must be a whole number >= 1 (or None for "
                             "the default)")
    return int(value)


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
    chunk, slots = size_value(chunk, "chunk"), size_value(slots, "slots")
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
    batch, slots = size_value(batch, "batch"), size_value(slots, "slots")
    if run_batch is None:
        run_batch = batch_function(config, slots=slots, full_length=full_length,
                                   physics=physics)
    if batch is None:
        batch = table_batch_size(config, forces.size)
    cache.enable()
    with folder_lock(out, wait=wait):
        return run_table(out, config, forces, run_batch=run_batch, batch=batch,
                         progress=progress, log=log.info, cluster=cluster)
