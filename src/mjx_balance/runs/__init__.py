"""Floor 7, runs: sweeps over pushes, the recoverable region (``region.parquet``) and the
max-acting-time table (``table.csv``) written into one output folder, and the machinery they
share (grids, chunk sizes, batch functions, sweep definitions, Dask); docs/architecture.md,
"The modules", maps its modules. The output folder itself is the store floor below.
"""

from .acting_time import (
    COARSE_DURATIONS,
    TABLE_COLUMNS,
    Brackets,
    TableResult,
    coarse_brackets,
    coarse_steps,
    evaluate_cells,
    max_acting_time,
    refine_round,
    run_table,
    table_batch_size,
    table_row,
)
from .batch import LazyBatch, RunBatch, default_batch, evaluate, evaluate_batches
from .chunks import (
    ACCELERATOR_CHUNK_CAP,
    CPU_CHUNK_CAP,
    batch_limit,
    chunk_slices,
    default_chunk_size,
    memory_budget,
    power_of_two_chunk,
    scenario_bytes,
)
from .definitions import DEFAULT_SWEEP, STUDY_TABLE_FORCES, SweepDefinition, load_sweep
from .grid import check_durations, describe, grid_cells, parse_grid
from .region import SweepResult, check_region, run_sweep

__all__ = [
    "ACCELERATOR_CHUNK_CAP",
    "Brackets",
    "COARSE_DURATIONS",
    "CPU_CHUNK_CAP",
    "DEFAULT_SWEEP",
    "LazyBatch",
    "RunBatch",
    "STUDY_TABLE_FORCES",
    "SweepDefinition",
    "SweepResult",
    "TABLE_COLUMNS",
    "TableResult",
    "batch_limit",
    "check_durations",
    "check_region",
    "chunk_slices",
    "coarse_brackets",
    "coarse_steps",
    "default_batch",
    "default_chunk_size",
    "describe",
    "evaluate",
    "evaluate_batches",
    "evaluate_cells",
    "grid_cells",
    "load_sweep",
    "max_acting_time",
    "memory_budget",
    "parse_grid",
    "power_of_two_chunk",
    "refine_round",
    "run_sweep",
    "run_table",
    "scenario_bytes",
    "table_batch_size",
    "table_row",
]
