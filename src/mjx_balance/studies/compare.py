"""Several configurations on one grid (``mjx-balance compare``, :func:`run_compare`).

Each configuration gets a sweep folder ``OUT/<name>/`` with its region map and its table (the
sweep's and the table's own resumable store, so a rerun computes only what is missing), then
``OUT/compare.csv`` holds one row per configuration (:func:`numbers`) and ``OUT/compare.png``
draws every configuration's recovery boundary on one force x duration plane
(:func:`plot_compare`).

Numbers of a configuration:

area, fraction, recovered_cells, cells, t_ref, f_max_ref, rest_recovered
    of its region map (``catalog.region_numbers``: area in N s over the grid's cells)
mean_recovery_energy
    the mean total joint energy [J] of its recovered cells
sustained_push_limit
    the largest force held for the whole window (table.csv, ``acting_time.sustained_push_limit``)
max_acting_time_<F>N
    the max acting time [s] at each table force

and, in compare.csv only (cohort.csv shares the numbers above), ``controller`` (the
configuration's controller.kind) and ``mean_settle_time`` [s] of the recovered cells.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..figures import style as figure_style
from ..figures.region import cell_bounds, duration_axis, log_durations
from ..model.params import Config, ParameterError
from ..model.config_files import config_from_dict, load_config, read_toml, run_config
from ..model.subject import Subject, with_sections
from ..runs import cluster as cluster_mod
from ..runs.definitions import load_sweep
from ..runs.acting_time import table_scenarios
from ..runs.chunks import PlanHook, PlannedWork
from ..runs.folders import check_batched, run_region, run_table_folder
from ..runs.population import check_queue, run_maps
from ..runs.grid import Grid, check_durations, describe, parse_grid
from ..store.files import REGION, TABLE, write_csv
from ..store.folder import OutputFolder, config_dict, config_differences, folder_lock, same_values
from . import catalog

COMPARE_CSV = "compare.csv"
COMPARE_PNG = "compare.png"
RESERVED = (COMPARE_CSV, COMPARE_PNG)  # names a configuration's folder cannot take


def names_for(paths: Sequence[str | Path]) -> list[str]:
    """A folder name per configuration file: its stem (characters other than letters, digits,
    '.', '_' and '-' replaced), made unique with -2, -3, ... (also against compare.csv and
    compare.png, the comparison's own files)."""
    names: list[str] = []
    for path in paths:
        stem = re.sub(r"[^A-Za-z0-9._-]", "_", Path(path).stem).strip(".") or "config"
        name, n = stem, 1
        while name in names or name in RESERVED:
            n += 1
            name = f"{stem}-{n}"
        names.append(name)
    return names


def check_names(names: Sequence[str]) -> None:
    """Names given to configurations (``mb.compare`` with a dict) must be usable folder names
    in OUT, distinct from each other and from the comparison's own files."""
    seen: set[str] = set()
    for name in names:
        if not name or name in (".", "..") or "/" in name or "\\" in name or name != name.strip():
            raise ParameterError(
                f"configuration name {name!r} is not a folder name (letters, "
                "digits, '.', '_', '-'; no path separators)"
            )
        if name in RESERVED:
            raise ParameterError(
                f"configuration name {name!r} is taken by the comparison's own output file"
            )
        if name.lower() in seen:  # a case-insensitive filesystem would merge them
            raise ParameterError(f"configuration name {name!r} is given twice")
        seen.add(name.lower())


def controller_name(kind: str, whole: bool = False) -> str:
    """A controller kind's folder name: the kind itself for a built-in one, the factory's name
    for ``package.module:factory`` (``whole``: the whole kind), characters other than letters,
    digits, '.', '_' and '-' as '_'."""
    name = kind if whole else kind.rpartition(":")[2]
    return re.sub(r"[^A-Za-z0-9._-]", "_", name)


def with_controllers(configs: dict[str, Config], kinds: Sequence[str]) -> dict[str, Config]:
    """Every configuration under every controller kind (``compare --controllers``): named by
    the kind (:func:`controller_name`) for one configuration, ``NAME-kind`` for several, each
    checked as the configuration's own values are."""
    if not kinds:
        return configs
    names = [controller_name(kind) for kind in kinds]
    if len(set(names)) != len(names):  # two factories of one name: their whole kinds
        names = [controller_name(kind, whole=True) for kind in kinds]
    out = {}
    for label, config in configs.items():
        for kind, name in zip(kinds, names):
            key = name if len(configs) == 1 else f"{label}-{name}"
            out[key] = config.replace(controller={"kind": kind})
    check_names(list(out))
    return out


def load_configs(
    paths: Sequence[str | Path],
    base: Config | None = None,
    names: Sequence[str | None] | None = None,
) -> dict[str, Config]:
    """name -> configuration of every file (ParameterError naming the file that is wrong, or
    a file given twice: its map would be computed twice). ``base``: the configuration each
    file's values go on top of (default: the defaults); ``names``: a name per file, None for
    the file's stem (:func:`names_for`)."""
    if not paths:
        raise ParameterError(
            "compare needs at least one configuration (compare FILE ... or --variant NAME=FILE)"
        )
    seen: dict[Path, str | Path] = {}
    for path in paths:
        key = Path(path).resolve()
        if key in seen:
            also = f" (also as {seen[key]})" if str(seen[key]) != str(path) else ""
            raise ParameterError(
                f"{path}: this configuration file is given twice{also}; give "
                "each configuration once"
            )
        seen[key] = path
    given = list(names) if names is not None else [None] * len(paths)
    chosen = [name or stem for name, stem in zip(given, names_for(paths))]
    check_names(chosen)
    configs = {}
    for name, path in zip(chosen, paths):
        try:
            configs[name] = load_one(path, base)
        except ParameterError as exc:
            raise ParameterError(f"{path}: {exc}") from None
    return configs


def load_one(path: str | Path, base: Config | None = None) -> Config:
    """A configuration file's configuration, or a sweep definition's (a file with a [sweep]
    table: its grid is not used, the comparison has its own); the file's values go on top of
    ``base`` (default: the defaults)."""
    data = read_toml(Path(path))
    if "sweep" in data:
        return load_sweep(path, base or Config()).config
    if base is None:
        return load_config(path)
    if "subject" in data:  # the subject's body on the base; its conflicts are the file's own
        return with_sections(base, data)
    merged: dict[str, Any] = base.to_dict()
    for section, values in data.items():  # the file's values over the base's, section by section
        known = merged.get(section)
        merged[section] = (
            {**known, **values} if isinstance(known, dict) and isinstance(values, dict) else values
        )
    return config_from_dict(merged)


def load_base(path: str | Path | None, subject: Subject | None = None) -> Config | None:
    """The base configuration of a comparison (``compare --config FILE --subject ...``): the
    file read as each compared FILE is (:func:`load_one`: a configuration file, or a sweep
    definition whose grid is left out), with ``subject``'s body. On a configuration file the
    subject takes the place of its [subject] table (``config_files.run_config``, whose checks
    refuse a value both set); on a sweep definition the file's values go over the subject's body, as
    ``sweep --sweep FILE --subject ...`` layers them. None: no file and no subject."""
    if subject is None:
        return load_one(path) if path else None
    if path and "sweep" in read_toml(Path(path)):
        return load_one(path, run_config(None, subject=subject))
    return run_config(path, subject=subject)


def check_folder(
    folder: Path, name: str, config: Config, forces: np.ndarray, durations: np.ndarray
) -> None:
    """Refuse, before any configuration runs, a folder OUT/<name> left by another
    configuration or holding a region map over another grid (the sweep itself would refuse
    it, but only once the configurations before it had run)."""
    folder_ = OutputFolder(folder, config)
    try:
        manifest = folder_.read_manifest()
    except ParameterError as exc:
        raise ParameterError(f"configuration {name!r}: {exc}") from None
    if manifest is None:
        return
    differences = config_differences(manifest.get("config", {}), config_dict(config))
    if differences:
        raise ParameterError(
            f"configuration {name!r}: {folder} was made with a different configuration; use "
            "another --out folder or the same configuration. Differences: "
            + "; ".join(differences[:6])
            + (" ..." if len(differences) > 6 else "")
        )
    recorded = manifest.get("region")
    if recorded is not None and not (
        same_values(recorded["forces"], forces) and same_values(recorded["durations"], durations)
    ):
        raise ParameterError(
            f"configuration {name!r}: {folder} holds a sweep over another grid (forces "
            f"{describe(recorded['forces'])}, durations {describe(recorded['durations'])}); "
            "use another --out folder or the same grid"
        )


def numbers(region: pd.DataFrame, table: pd.DataFrame | None) -> dict[str, float]:
    """The comparison's numbers of one configuration (module docstring)."""
    row: dict[str, float] = dict(catalog.region_numbers(region))
    recovered = region[catalog.is_recovered(region)]
    row["mean_recovery_energy"] = (
        float(recovered["energy_total"].mean()) if len(recovered) else float("nan")
    )
    row["sustained_push_limit"] = float("nan")
    if table is not None and len(table):
        if "sustained_push_limit" in table:
            row["sustained_push_limit"] = float(table["sustained_push_limit"].iloc[0])
        for force, t in zip(table["force"], table["max_acting_time"]):
            row[f"max_acting_time_{force:g}N"] = float(t)
    return row


def mean_settle_time(region: pd.DataFrame) -> float:
    """The mean settle time [s] of a map's recovered cells (NaN without one): how fast a
    controller brings the body back, beside what it costs (``mean_recovery_energy``). The
    mean, not the median: most small pushes never leave the settle band (settle time 0)."""
    recovered = region[catalog.is_recovered(region)]
    return float(recovered["settle_time"].mean()) if len(recovered) else float("nan")


def check_compare(
    out: str | Path, configs: dict[str, Config], forces: Any, durations: Any, table_forces: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every input of :func:`run_compare` checked, nothing written: the names, the grids
    (within float32; every duration on every configuration's window and physics step), each
    configuration as the batched path runs it (``runs.folders.check_batched``) and each
    configuration's folder in ``out``. Returns the parsed grids; ParameterError naming the
    configuration otherwise."""
    out = Path(out)
    forces = parse_grid(forces, "forces")
    durations = parse_grid(durations, "durations")
    table_forces = parse_grid(table_forces, "table forces")
    check_names(list(configs))
    for name, config in configs.items():  # every grid check before any work
        try:
            check_durations(durations, config.scenario.t_end, physics_dt=config.scenario.physics_dt)
            check_batched(config, (forces, "forces"), (table_forces, "table forces"))
        except ParameterError as exc:
            raise ParameterError(f"configuration {name!r}: {exc}") from None
        check_folder(out / name, name, config, forces, durations)
    return forces, durations, table_forces


def run_compare(
    out: str | os.PathLike[str],
    configs: dict[str, Config],
    forces: Any,
    durations: Any,
    table_forces: Any,
    *,
    run_batches: dict[str, Any] | None = None,
    progress: bool = False,
    say: Callable[[str], None] | None = print,
    plan: PlanHook | None = None,
    wait: bool = False,
    **engine: Any,
) -> pd.DataFrame:
    """Every configuration's region map and table in ``out/<name>/``, then compare.csv and
    compare.png in ``out``; returns the comparison (one row per configuration, in order).

    forces, durations, table_forces: grids (``parse_grid``); every duration must fit every
    configuration's window. Everything is checked once (:func:`check_compare`), then ``plan``
    (if given) hears the planned work (``runs.chunks.PlannedWork``), then the work runs under
    ``out``'s lock (``wait``: for another run that holds it). run_batches: a batch function
    per name (tests); engine: ``slots``, ``full_length``, ``physics``, ``cluster`` for
    ``runs.folders.run_region`` / ``run_table_folder``, and ``queue`` ("each": every
    configuration's map its own engine run; "one": through one engine queue per compiled
    shape, ``runs.population.run_maps``, MJX only, no cluster)."""
    say = say or (lambda _msg: None)
    out = Path(out)
    engine = dict(engine)
    queue = check_queue(
        engine.pop("queue", "each"), engine.get("physics", "auto"), engine.get("cluster")
    )
    grids = check_compare(out, configs, forces, durations, table_forces)
    if plan is not None:
        first = next(iter(configs.values()))
        plan(
            PlannedWork(
                first,
                len(configs) * grids[0].size * grids[1].size,
                "cells",
                extra=len(configs) * table_scenarios(first, grids[2].size),
            )
        )
    with folder_lock(out, wait=wait):
        cluster = engine.get("cluster")
        if not isinstance(cluster, str):
            return _compare(
                out,
                configs,
                grids,
                run_batches=run_batches,
                progress=progress,
                say=say,
                queue=queue,
                engine=engine,
            )
        client, local = cluster_mod.connect(cluster, say)  # one connection for every map
        try:
            return _compare(
                out,
                configs,
                grids,
                run_batches=run_batches,
                progress=progress,
                say=say,
                queue=queue,
                engine={**engine, "cluster": client},
            )
        finally:
            cluster_mod.close(client, local, owned=True)


def _compare(
    out: Path,
    configs: dict[str, Config],
    grids: tuple[np.ndarray, np.ndarray, np.ndarray],
    *,
    run_batches: dict[str, Any] | None,
    progress: bool,
    say: Callable[[str], None],
    queue: str,
    engine: dict[str, Any],
) -> pd.DataFrame:
    """:func:`run_compare`'s work, its inputs checked (``grids``: forces, durations, table
    forces) and the folder locked."""
    forces, durations, table_forces = grids
    windows = {name: config.scenario.t_end for name, config in configs.items()}
    if len(set(windows.values())) > 1:
        say(
            "note: the configurations' windows differ ("
            + ", ".join(f"{n}: {t:g} s" for n, t in windows.items())
            + "); 'recovered' and "
            "the sustained-push limit are judged over each one's own window"
        )
    regions, tables, rows = {}, {}, []
    if queue == "one":  # every configuration's map through one engine queue per shape
        run_maps(
            [(out / name, config) for name, config in configs.items()],
            forces,
            durations,
            slots=engine.get("slots"),
            full_length=engine.get("full_length", False),
            say=lambda text: say(f"compare: {text}"),
        )
    for name, config in configs.items():
        folder = out / name
        say(f"compare: {name} ({config.controller.convention} convention) -> {folder}")
        batch = (run_batches or {}).get(name)
        if queue != "one":
            run_region(
                folder,
                config,
                Grid.of(forces, durations, config),
                run_batch=batch,
                progress=progress,
                **engine,
            )
        run_table_folder(folder, config, table_forces, run_batch=batch, progress=progress, **engine)
        regions[name] = pd.read_parquet(folder / REGION)
        tables[name] = pd.read_csv(folder / TABLE)
        rows.append(
            {
                "name": name,
                "convention": config.controller.convention,
                "controller": config.controller.kind,
                "t_end": config.scenario.t_end,
                **numbers(regions[name], tables[name]),
                "mean_settle_time": mean_settle_time(regions[name]),
            }
        )
    frame = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(frame, out / COMPARE_CSV)
    figure = plot_compare(regions, out / COMPARE_PNG, frame)  # compare.png in the figure style
    say(f"wrote {out / COMPARE_CSV} and {figure}")
    return frame


def boundary_segments(
    region: pd.DataFrame, log: bool
) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The edges between recovered and other cells of a region map, as ((F0, T0), (F1, T1))
    segments on the cells' bounds (``figures.region.cell_bounds``: where each cell is drawn)."""
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    fb, db = cell_bounds(forces), cell_bounds(durations, log=log)
    ok = np.zeros((forces.size + 2, durations.size + 2), bool)  # padded with "not recovered"
    rec = region[catalog.is_recovered(region)]
    fi = np.searchsorted(forces, rec["force"].to_numpy())
    di = np.searchsorted(durations, rec["duration"].to_numpy())
    ok[fi + 1, di + 1] = True
    segments = []
    for i in range(forces.size + 1):  # vertical edges at force bound i (between i-1 and i)
        for j in range(durations.size):
            if ok[i, j + 1] != ok[i + 1, j + 1]:
                segments.append(((fb[i], db[j]), (fb[i], db[j + 1])))
    for i in range(forces.size):  # horizontal edges at duration bound j
        for j in range(durations.size + 1):
            if ok[i + 1, j] != ok[i + 1, j + 1]:
                segments.append(((fb[i], db[j]), (fb[i + 1], db[j])))
    return segments


def _shade_recovered(ax, first: tuple[str, pd.DataFrame], log: bool) -> Any:
    """The first configuration's recovered cells, filled lightly in the outcome palette's
    recovered colour, so that the map says which side of the outlines recovers; returns the
    legend's patch for it."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    name, region = first
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    grid = np.full((durations.size, forces.size), np.nan)
    rec = region[catalog.is_recovered(region)]
    grid[
        np.searchsorted(durations, rec["duration"].to_numpy()),
        np.searchsorted(forces, rec["force"].to_numpy()),
    ] = 1.0
    colour = figure_style.OUTCOME_COLOURS["recovered"]
    ax.pcolormesh(
        cell_bounds(forces),
        cell_bounds(durations, log=log),
        np.ma.masked_invalid(grid),
        cmap=ListedColormap([colour]),
        alpha=0.22,
        zorder=0,
    )
    return Patch(facecolor=colour, alpha=0.22, label=f"{name}: recovered cells")


def plot_compare(regions: dict[str, pd.DataFrame], path: Path, frame: pd.DataFrame) -> Path:
    """One figure: every configuration's recovery boundary (the outline of its recovered
    cells) in its own colour and line style, the legend naming it with its area and
    sustained-push limit."""
    from matplotlib.collections import LineCollection

    every = pd.concat(regions.values())
    durations = np.sort(every["duration"].unique())
    log = log_durations(durations)
    fig, ax = figure_style.subplots(figsize=(8, 5.5))
    shaded = _shade_recovered(ax, next(iter(regions.items())), log)
    styles = ["-", "--", "-.", ":"]
    numbers_of = frame.set_index("name")
    several_windows = frame["t_end"].nunique() > 1
    for k, (name, region) in enumerate(regions.items()):
        segments = boundary_segments(region, log)
        row = numbers_of.loc[name]
        limit = row["sustained_push_limit"]
        label = (
            f"{name}: {row['area']:.3g} N·s"
            + (f", holds {limit:g} N" if np.isfinite(limit) else "")
            + (f" ({row['t_end']:g}-s window)" if several_windows else "")
        )
        colour = figure_style.SERIES[k % len(figure_style.SERIES)]
        ax.add_collection(
            LineCollection(
                segments,
                colors=colour,
                linewidths=2.2,
                linestyles=styles[k % len(styles)],
                label=label,
            )
        )
    forces = np.sort(every["force"].unique())
    fb = cell_bounds(forces)
    ax.set_xlim(fb[0], fb[-1])
    duration_axis(ax, durations, cell_bounds(durations, log=log), log)
    ax.set_xlabel("push force F [N]")
    ax.set_title("Recovery boundaries: recovered cells lie inside each outline")
    handles = ax.get_legend_handles_labels()[0] + [shaded]
    ax.legend(
        handles=handles, loc="upper right", fontsize=9, title="configuration: recoverable area"
    )
    ax.grid(alpha=0.3)
    return figure_style.save(fig, path, dpi=120)
