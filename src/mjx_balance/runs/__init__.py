"""Sweeps over pushes: the recoverable region and the max-acting-time table (SPEC §4, §6.3–6.4).

Two products, both written into one output folder ``DIR``:

region   every cell of a force x duration grid, one summary row per cell
         (``outcomes.SUMMARY_COLUMNS``) -> ``DIR/region.parquet``  (region.py)
table    for each force, the max acting time: the largest duration T (to 0.01 s) such that
         every duration up to T recovers -> ``DIR/table.csv``  (acting_time.py)

The modules, bottom up:

    grid.py         parse force / duration grids, the cells of a grid
    chunks.py       scenarios per batch call: memory budget, power-of-two chunk sizes
    batch.py        batch functions (the MJX rollout by default) and evaluating a batch
    progress.py     progress bars
    region.py       the region sweep, resumable chunk by chunk
    acting_time.py  the batched bisection for the max acting time, the table
    definitions.py  the default sweep and sweep definition files (the repository's sweeps/*.toml,
                    shipped in the package as mjx_balance/sweeps)

The output folder itself (atomic writes, manifest, chunk files, locks, the merge) is the store
floor below this one (``mjx_balance.store``); the public function is :func:`mjx_balance.sweep`
(``api.py``).
"""

from .acting_time import (COARSE_DURATIONS, TABLE_COLUMNS, Brackets, TableResult, coarse_brackets,
                          coarse_steps, evaluate_cells, max_acting_time, refine_round, run_table,
                          table_batch_size, table_row)
from .batch import LazyBatch, RunBatch, default_batch, evaluate, evaluate_batches
from .chunks import (ACCELERATOR_CHUNK_CAP, CPU_CHUNK_CAP, batch_limit, chunk_slices,
                     default_chunk_size, memory_budget, power_of_two_chunk, scenario_bytes)
from .definitions import DEFAULT_SWEEP, STUDY_TABLE_FORCES, SweepDefinition, load_sweep
from .grid import GRID_TOL, check_durations, describe, grid_cells, parse_grid, same_values
from .region import SweepResult, check_region, run_sweep
from ..store.files import (MANIFEST, REGION, TABLE, TABLE_CELLS, TABLE_RUNS, write_atomic,
                           write_parquet, write_text)
from ..store.folder import (OutputFolder, TableCells, chunk_path, manifest_problem, merge_chunks,
                            read_chunk)

__all__ = [
    "ACCELERATOR_CHUNK_CAP", "Brackets", "COARSE_DURATIONS", "CPU_CHUNK_CAP", "DEFAULT_SWEEP",
    "GRID_TOL", "LazyBatch", "MANIFEST", "OutputFolder", "REGION", "RunBatch",
    "STUDY_TABLE_FORCES", "SweepDefinition", "SweepResult", "TABLE", "TABLE_CELLS",
    "TABLE_COLUMNS", "TABLE_RUNS", "TableCells", "TableResult", "batch_limit",
    "check_durations", "check_region", "chunk_path", "chunk_slices", "coarse_brackets",
    "coarse_steps", "default_batch", "default_chunk_size", "describe", "evaluate",
    "evaluate_batches", "evaluate_cells", "grid_cells", "load_sweep", "manifest_problem",
    "max_acting_time", "memory_budget", "merge_chunks", "parse_grid", "power_of_two_chunk",
    "read_chunk", "refine_round", "run_sweep", "run_table", "same_values", "scenario_bytes",
    "table_batch_size", "table_row", "write_atomic", "write_parquet", "write_text",
]

