"""``mjx-balance sweep`` and ``mjx-balance table``: the region map and the robustness table."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd

from .. import region_plots
from ..params import Config, with_convention
from ..sweep import (DEFAULT_SWEEP, MANIFEST, STUDY_TABLE_FORCES, TABLE, LazyBatch,
                     check_durations, load_sweep, parse_grid, run_sweep, run_table,
                     table_batch_size)
from . import base_config


def sweep_command(args: Any) -> int:
    """``mjx-balance sweep``: region.parquet, region.png, energy.png in --out.

    Without --forces, --durations or --sweep it runs the built-in default sweep and also writes
    the table (table.csv, table.png) into the same folder.
    """
    use_default = args.sweep is None and args.forces is None and args.durations is None
    definition = load_sweep(args.sweep, base_config(args))
    if args.sweep is None and not use_default:
        # A grid from the command line: the region only, chunk size from the memory budget.
        definition.table_forces = definition.chunk = None
    config = with_convention(definition.config, args.convention)
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
    config = with_convention(definition.config if definition else base_config(args),
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
    targets = {"region.png": region_plots.plot_region, "energy.png": region_plots.plot_energy}
    for name, plot in targets.items():
        path = out / name
        if force or not path.exists() or reference is not None:
            kwargs = {"reference": reference} if name == "region.png" else {}
            plot(region, path, config=config, **kwargs)
            print(f"wrote {path}")


def _make_table_figure(out: Path, config: Config, force: bool) -> None:
    path = out / "table.png"
    if force or not path.exists():
        region_plots.plot_table(pd.read_csv(out / TABLE, keep_default_na=True), path, config=config)
        print(f"wrote {path}")
