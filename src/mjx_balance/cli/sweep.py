"""``mjx-balance sweep`` and ``mjx-balance table``: the region map and the robustness table.

Both are thin layers over the Python API (``api.run_region``, ``api.run_table_folder``, which
``mjx_balance.sweep`` and ``mjx_balance.table`` call): they resolve the options (a sweep
definition, the built-in default sweep, the work guard) into its arguments and draw the
figures. Each command checks its arguments, then works in the output folder under its lock (a
second run into the same folder is refused at once, or waits for it with --wait). A write that
fails there (a full disk, a file-size limit) ends in one line and exit code 1; finished chunks
stay and the same command resumes. Derived figures missing or damaged (a PNG cut short) are
drawn again on a rerun.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..model.params import Config
from ..model.config_files import apply_overrides, with_convention
from ..studies.defaults import (
    DEFAULT_SWEEP_DURATIONS,
    DEFAULT_SWEEP_FORCES,  # light
    DEFAULT_SWEEP_TABLE_FORCES,
)
from .common import (
    base_config,
    chosen_physics,
    guard_work,
    in_folder,
    progress_enabled,
    table_scenarios,
)
from .options import (
    cluster_option,
    common_options,
    engine_options,
    figure_options,
    format_option,
    positive_int,
    reference_file,
    sweep_file,
    wait_option,
    write_exports,
    yes_option,
)

if TYPE_CHECKING:
    import pandas as pd

    from ..runs import SweepDefinition, SweepResult
    from ..runs.grid import Grid

log = logging.getLogger("mjx_balance")


def add_parser(sub: Any) -> None:
    """The ``sweep`` and ``table`` sub-commands (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "sweep",
        help="recoverable region over a force x duration grid; "
        "without --forces, --durations or --sweep the default "
        f"sweep: forces {DEFAULT_SWEEP_FORCES} N x durations "
        f"{DEFAULT_SWEEP_DURATIONS} s, and the table at "
        f"{DEFAULT_SWEEP_TABLE_FORCES} N in the same folder",
    )
    p.add_argument(
        "--forces",
        default=None,
        help="start:stop:step or a comma list [N] (default: the --sweep file's, "
        f"else the default sweep's {DEFAULT_SWEEP_FORCES})",
    )
    p.add_argument(
        "--durations",
        default=None,
        help="start:stop:step or a comma list [s] (default: the --sweep file's, "
        f"else the default sweep's {DEFAULT_SWEEP_DURATIONS})",
    )
    p.add_argument(
        "--sweep",
        type=sweep_file,
        default=None,
        help="sweep definition: a TOML file or the name of a shipped one "
        "(default, region_dense_paper, study_...; see mjx_balance/sweeps/)",
    )
    p.add_argument(
        "--chunk",
        type=positive_int,
        default=None,
        help="scenarios per chunk (default: from memory budget)",
    )
    reference_option(p)
    engine_options(p)
    cluster_option(p)
    yes_option(p)
    wait_option(p)
    format_option(p)
    figure_options(p)
    common_options(p)
    p.set_defaults(target="mjx_balance.cli.sweep:sweep_command")

    p = sub.add_parser(
        "table", help="max acting time per force (robustness table) and the sustained-push limit"
    )
    p.add_argument(
        "--forces",
        default=None,
        help="comma list or start:stop:step [N] (default: the --sweep file's "
        "table_forces, "
        "else the study's 5,10,15,20,30,40,50,60,80,100,120)",
    )
    p.add_argument(
        "--sweep",
        type=sweep_file,
        default=None,
        help="sweep definition: a TOML file or the name of a shipped one "
        "(study_table_paper, ...; see mjx_balance/sweeps/)",
    )
    reference_option(p)
    engine_options(p)
    cluster_option(p)
    yes_option(p)
    wait_option(p)
    format_option(p)
    figure_options(p)
    common_options(p)
    p.set_defaults(target="mjx_balance.cli.sweep:table_command")


def reference_option(p: Any) -> None:
    """``--reference FILE`` (repeatable): a published or a lab's table, or points to draw."""
    p.add_argument(
        "--reference",
        type=reference_file,
        action="append",
        default=None,
        metavar="FILE",
        help="reference CSV (repeatable), or 'study' (the study's Table 2, "
        "shipped): points (force, duration) drawn over the map, or a table "
        "(force and max_acting_time, energies or recovered) scored beside "
        "ours in scorecard.csv / scorecard.png; its forces join the table "
        "(docs/outputs.md, 'Reference files')",
    )


def with_reference_forces(forces: Any, refs: list, what: str) -> Any:
    """``forces`` (an array, or None) with the reference tables' forces added (sorted)."""
    import numpy as np

    from ..studies.reference_files import reference_forces  # lazy: pandas, JAX

    extra = reference_forces(refs, forces)  # not already there (the scorecard's tolerance)
    if not extra:
        return forces
    log.info(f"{what}: adding the reference's forces {', '.join(f'{f:g}' for f in extra)} N")
    merged = np.concatenate([np.asarray([] if forces is None else forces, float), extra])
    return np.unique(merged)


def report_scorecard(out: Path, refs: list) -> None:
    """scorecard.csv and scorecard.png in ``out`` from its results; its summary in the log."""
    from ..studies.scorecard import scorecard_files, summary_text  # lazy: pandas, matplotlib

    card, written = scorecard_files(out, refs)
    if card is not None:  # what was written: no figure when no measure has a panel
        log.info(f"wrote {' and '.join(str(p) for p in written)}\n" + summary_text(card))


def sweep_command(args: Any) -> int:
    """``mjx-balance sweep``: region.parquet, region.png, energy.png, strategy.png and
    strategy_threshold.png in --out.

    Without --forces, --durations or --sweep it runs the built-in default sweep and also writes
    the table (table.csv, table.png) into the same folder.
    """
    # lazy: the library (JAX, MuJoCo, pandas) loads when the command runs, not for --help
    from .. import api
    from ..runs import DEFAULT_SWEEP  # lazy: the runs floor: JAX
    from ..store.files import MANIFEST  # lazy: as above
    from ..studies.reference_files import reference_points  # lazy: as above
    from ..runs.grid import Grid  # lazy: as above

    use_default, definition, config, forces, durations, chunk = _sweep_request(args)
    # Check everything before any work: the grid once, here, carried down.
    grid = Grid.of(forces, durations, config)
    table_forces, refs = _checked_table(args, config, definition, grid, chunk)
    reference = reference_points(refs)
    if use_default:
        log.info(
            "no grid given: running the built-in default sweep "
            f"(forces {DEFAULT_SWEEP['forces']} N, durations {DEFAULT_SWEEP['durations']} "
            f"s, table forces {DEFAULT_SWEEP['table_forces']} N)"
        )

    out = Path(args.out)
    progress = progress_enabled(args)

    def work() -> None:
        # built (and compiled) only if a scenario must run
        run_batch = api.batch_function(
            config,
            slots=args.slots,
            full_length=args.full_length,
            physics=chosen_physics(args, definition),
        )
        result = api.run_region(
            out,
            config,
            grid,
            run_batch=run_batch,
            chunk=chunk,
            progress=progress,
            cluster=args.cluster,
            lock=False,
        )
        _make_region_figures(out, result, config, reference)
        if table_forces is not None:
            # The table in calls of the sweep's chunk size: the rollout compiled for it already.
            chunk_used = json.loads((out / MANIFEST).read_text())["region"]["chunk_size"]
            table = api.run_table_folder(
                out,
                config,
                table_forces,
                run_batch=run_batch,
                batch=int(chunk_used),
                progress=progress,
                cluster=args.cluster,
                lock=False,
            )
            _make_table_figure(out, config, force=table is not None)
            # region.png overlays the table's max-acting-time curve: drawn again with it
            _make_region_figures(
                out, result, config, reference, only="region", force=table is not None
            )
        report_scorecard(out, refs)
        write_exports(out, args)

    return in_folder(out, work, wait=getattr(args, "wait", False))


def _sweep_request(args: Any) -> tuple:
    """What the options ask for: (default sweep?, definition, config, forces, durations, chunk)."""
    from ..runs import DEFAULT_SWEEP, load_sweep  # lazy: the runs floor: JAX

    use_default = args.sweep is None and args.forces is None and args.durations is None
    definition = load_sweep(args.sweep, base_config(args, overrides=False))
    if args.sweep is None and not use_default:
        # A grid from the command line: the region only, chunk size from the memory budget.
        definition.table_forces = definition.chunk = None
    # the command line wins: --set over the sweep definition, --convention over both
    config = with_convention(
        apply_overrides(definition.config, getattr(args, "set", None)), args.convention
    )
    forces = (
        args.forces
        if args.forces is not None
        else (definition.forces if definition.forces is not None else DEFAULT_SWEEP["forces"])
    )
    durations = (
        args.durations
        if args.durations is not None
        else (
            definition.durations if definition.durations is not None else DEFAULT_SWEEP["durations"]
        )
    )
    chunk = args.chunk if args.chunk is not None else definition.chunk
    return use_default, definition, config, forces, durations, chunk


def _checked_table(
    args: Any, config: Config, definition: SweepDefinition, grid: Grid, chunk: int | None
) -> tuple:
    """The table's forces (None: none) and the references, once the work guard and checks pass."""
    from ..runs import parse_grid  # lazy: the runs floor: JAX
    from ..runs.chunks import default_chunk_size  # lazy: as above
    from ..runs.folders import check_batched  # lazy: as above
    from ..studies.reference_files import read_references  # lazy: as above

    table_forces = (
        parse_grid(definition.table_forces, "table_forces")
        if definition.table_forces is not None
        else None
    )
    refs = read_references(args.reference)
    table_forces = with_reference_forces(table_forces, refs, "table")
    guard_work(
        args,
        config,
        grid.n_cells,
        "cells",
        chunk_size=chunk or default_chunk_size(config, grid.n_cells),
        extra=(table_scenarios(config, table_forces.size) if table_forces is not None else 0),
    )
    check_batched(
        config,
        (grid.forces, "forces"),
        (grid.durations, "durations"),  # derived rules
        *([(table_forces, "table_forces")] if table_forces is not None else []),
    )
    return table_forces, refs


def table_command(args: Any) -> int:
    """``mjx-balance table``: table.csv and table.png in --out (and, with --reference,
    scorecard.csv and scorecard.png)."""
    import pandas as pd

    # lazy: the library (JAX, MuJoCo, pandas) loads when the command runs, not for --help
    from .. import api
    from ..figures import region as region_plots  # lazy: matplotlib
    from ..figures.style import figure_name  # lazy: as above
    from ..runs import (
        STUDY_TABLE_FORCES,
        load_sweep,  # lazy: the runs floor: JAX
        parse_grid,
        table_batch_size,
    )
    from ..runs.folders import check_batched  # lazy: the runs floor: JAX
    from ..store.files import REGION, TABLE  # lazy: pandas
    from ..studies.reference_files import (  # lazy: as above
        read_references,
        reference_points,
        unused_points,
    )

    definition = load_sweep(args.sweep, base_config(args, overrides=False)) if args.sweep else None
    config = with_convention(
        apply_overrides(definition.config, getattr(args, "set", None))
        if definition
        else base_config(args),
        args.convention,
    )
    if args.forces is not None:
        forces = args.forces
    elif definition is not None and definition.table_forces is not None:
        forces = definition.table_forces
    else:
        forces = list(STUDY_TABLE_FORCES)
    refs = read_references(args.reference)
    forces = with_reference_forces(parse_grid(forces, "forces"), refs, "table")
    batch = table_batch_size(config, forces.size)
    guard_work(
        args,
        config,
        table_scenarios(config, forces.size),
        "scenarios (estimated)",
        chunk_size=batch,
    )
    check_batched(config, (forces, "forces"))  # derived rules, before the folder is made
    out = Path(args.out)

    def work() -> None:
        table = api.run_table_folder(
            out,
            config,
            forces,
            batch=batch,
            slots=args.slots,
            full_length=args.full_length,
            physics=chosen_physics(args, definition),
            progress=progress_enabled(args),
            cluster=getattr(args, "cluster", None),
            lock=False,
        )
        _make_table_figure(out, config, force=table is not None)
        if (out / REGION).exists():  # a sweep's folder: its map overlays the table's curve
            path = out / figure_name("region.png")  # in --figure-format
            if table is not None or _stale(path, out / TABLE):
                path = region_plots.plot_region(
                    pd.read_parquet(out / REGION),
                    path,
                    config=config,
                    reference=reference_points(refs),
                )
                log.info(f"wrote {path}")
        report_scorecard(out, refs)
        for line in unused_points(refs, (out / REGION).exists()):
            log.warning(line)
        write_exports(out, args)

    return in_folder(out, work, wait=getattr(args, "wait", False))


def _stale(figure: Path, source: Path) -> bool:
    """A figure to draw again: missing, damaged (cut short by a failed write), or older than
    the table it is drawn from (a run that failed after rewriting the table)."""
    from ..store.files import readable_figure  # lazy: the store floor loads pandas

    return not readable_figure(figure) or figure.stat().st_mtime_ns < source.stat().st_mtime_ns


def _make_region_figures(
    out: Path,
    result: SweepResult,
    config: Config,
    reference: pd.DataFrame | None,
    *,
    only: str | None = None,
    force: bool = False,
) -> None:
    """region.png and energy.png (or ``only`` one of them, by stem): drawn after a sweep that
    computed or merged anything, with reference points, when ``force``d, or when stale (older
    than region.parquet, or region.png older than the table.csv whose curve it overlays); read
    from region.parquet only then. Each in --figure-format (region.svg, ...: figures.style)."""
    from ..figures import region as region_plots  # lazy: matplotlib
    from ..figures import strategy as strategy_plots  # lazy: matplotlib
    from ..figures.style import figure_name  # lazy: as above
    from ..store.files import TABLE  # lazy: pandas
    from ..store.files import readable_figure  # lazy: the store floor loads pandas

    targets = {
        "region": region_plots.plot_region,
        "energy": region_plots.plot_energy,
        "strategy": strategy_plots.plot_strategy,
        "strategy_threshold": strategy_plots.plot_threshold,
    }
    region = None
    for stem, plot in targets.items():
        if only is not None and stem != only:
            continue
        path = out / figure_name(f"{stem}.png")
        overlay_stale = (
            stem == "region"
            and (out / TABLE).exists()
            and readable_figure(path)
            and _stale(path, out / TABLE)
        )
        if (
            force
            or not result.already_complete
            or _stale(path, result.region_path)
            or overlay_stale
            or (reference is not None and stem == "region")
        ):
            region = result.region if region is None else region
            kwargs = {"reference": reference} if stem == "region" else {}
            path = plot(region, path, config=config, **kwargs)
            log.info(f"wrote {path}")


def _make_table_figure(out: Path, config: Config, force: bool) -> None:
    import pandas as pd

    from ..figures import region as region_plots  # lazy: matplotlib
    from ..store.files import TABLE  # lazy: pandas

    from ..figures.style import figure_name  # lazy: as above

    path = out / figure_name("table.png")  # in --figure-format
    if force or _stale(path, out / TABLE):
        path = region_plots.plot_table(
            pd.read_csv(out / TABLE, keep_default_na=True), path, config=config
        )
        log.info(f"wrote {path}")
