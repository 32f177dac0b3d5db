"""The Python API: what the command line does, as functions that return DataFrames.

    import mjx_balance as mb

    config = mb.load_config("my_body.toml")          # or mb.Config(), or None for the defaults
    summary, series = mb.simulate([20, 80], [0.1], config)   # scalar reference runs
    region = mb.sweep("0:150:10", [0.1, 0.2], config)          # batched MJX + ADMM, in memory
    region = mb.sweep("0:150:10", [0.1, 0.2], config, out="out/region")   # resumable on disk
    table = mb.table([20, 50, 80], config)                     # max acting time per force

``config`` is a :class:`~mjx_balance.model.params.Config`, the path of a TOML configuration file,
a dict with ``body`` / ``controller`` / ``scenario`` tables, or None (the defaults); it is
validated as a TOML file is (:class:`~mjx_balance.model.params.ParameterError` naming the field and
the rule). Forces and durations are a sequence of numbers or a grid string (``"0:150:10"`` or
``"20,50,80"``), as on the command line.

``sweep`` and ``table`` write into the output folder ``out`` exactly what ``mjx-balance sweep``
and ``mjx-balance table`` write there (the same store: manifest, chunks, resume); with
``out=None`` they work in a temporary folder that is removed before they return, so nothing
is kept. They compile the batched closed loop on first use; JAX's persistent compilation cache
(``mjx_balance.runtime.cache``) keeps the executable for the next process. Messages go to the
``mjx_balance`` logger (INFO). Progress bars (stderr, with the time left) are on by default
where someone watches: ``progress=None`` draws them in a terminal and in a Jupyter notebook,
not where stderr is redirected (a file, a pipe, pytest) or closed; ``progress=True`` draws them
wherever stderr is open, ``progress=False`` never (``runs.progress.wanted``).

The command line (``mjx_balance.cli``) is a thin layer over these functions: it resolves its
options into their arguments, then writes figures and prints.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import logging
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, TypeVar, Union, cast

from .control import law
from .measures.strategy import with_strategy
from .model.params import Config, ParameterError
from .model.config_files import config_from_dict, load_config
from .model.subject import Subject
from .runs.folders import batch_function, check_pushes, run_region, run_table_folder, size_value
from .runs.chunks import PlanHook
from .runs.grid import Grid, Values, grid_values
from .runs.progress import wanted
from .store.folder import folder_lock
from .runtime import signals
from .store.provenance import run_context
from .reference import loop as reference
from .store.files import TABLE, check_format, export_tables_said
from .studies.compare import load_configs, run_compare, with_controllers
from .studies.defaults import DEFAULT_DELAYS, DEFAULT_SCALES, DEFAULT_TABLE_FORCES, READINGS
from .studies.defaults import DEFAULT_FORCES as STUDY_TABLE_FORCES
from .studies.landscape import run_landscape
from .studies.lean import lean_limits, run_lean, scored
from .studies.people import run_people
from .studies.pull import pull_limits, run_pull
from .studies.sensitivity import run_sensitivity
from .figures.style import figure_style
from .runs import DEFAULT_SWEEP
from .studies.basin import DEFAULT_V, DEFAULT_X, run_basin
from .studies.cohort import plan_cohort, run_plan
from .studies.members import as_members
from .studies.reference_files import (
    Reference,
    read_references,
    reference_forces,
    unused_points,
)
from .studies.scorecard import folder_results, write_scorecard
from .studies.scorecard import scorecard as score_results
from .report import REPORT_JSON, build_report
from .report.explore import Explorer
from .report.reproduction import store_references
from .runtime import cache
from .studies.experiments import PLANS, Plan, read_record, run_report, selected_studies
from .model.params import CONVENTIONS

if TYPE_CHECKING:
    import pandas as pd


__all__ = [
    "Config",
    "ParameterError",
    "basin",
    "batch_function",
    "cohort",
    "compare",
    "explore",
    "landscape",
    "lean_release",
    "load_config",
    "report",
    "sensitivity",
    "run_region",
    "run_table_folder",
    "scorecard",
    "simulate",
    "sweep",
    "table",
]

log = logging.getLogger("mjx_balance")

ConfigLike = Union[Config, Subject, str, "os.PathLike[str]", Mapping[str, Any], None]
References = Union[str, "os.PathLike[str]", Sequence[Union[str, "os.PathLike[str]"]], None]

# The arguments several API functions share, checked by name before any work, by one checker
# for every function (a wrong type: TypeError naming the argument; a wrong value: ParameterError)
FLAGS = ("full_length", "wait", "html_only", "browser")  # True or False (NumPy's bool too)
SIZES = ("slots", "chunk")  # None or a whole number >= 1 (runs.folders.size_value)
Function = TypeVar("Function", bound=Callable[..., Any])


def check_arguments(values: Mapping[str, Any], required: Sequence[str] = ()) -> None:
    """Check the shared arguments among ``values`` (name -> value): the flags, ``progress``
    (True, False or None), ``out`` (a folder's path, not a file's; None only where it is not in
    ``required``) and the sizes."""
    for name in FLAGS:
        value = values.get(name, False)
        if not isinstance(value, bool) and type(value).__name__ != "bool_":
            raise TypeError(f"{name} = {value!r}: must be True or False")
    progress = values.get("progress")
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"progress = {progress!r}: must be True, False or None")
    if "out" in values and (values["out"] is not None or "out" in required):
        out = values["out"]
        if not isinstance(out, (str, os.PathLike)):
            raise TypeError(f"out = {out!r}: must be a folder's path (str or os.PathLike)")
        if Path(out).exists() and not Path(out).is_dir():
            raise ParameterError(f"out = {os.fspath(out)!r} is a file, not a folder")
    for name in SIZES:
        if name in values:
            size_value(values[name], name)


def checked(function: Function) -> Function:
    """``function`` with its shared arguments checked (:func:`check_arguments`) before it
    runs; an argument without a default is required (``out`` = None refused there)."""
    signature = inspect.signature(function)
    required = [n for n, p in signature.parameters.items() if p.default is p.empty]

    @functools.wraps(function)
    def run(*args: Any, **kwargs: Any) -> Any:
        bound = signature.bind(*args, **kwargs)  # a missing or unknown argument: TypeError
        check_arguments(bound.arguments, required)
        return function(*args, **kwargs)

    return cast(Function, run)


def as_config(config: ConfigLike = None, controller: Any = None) -> Config:
    """A :class:`Config` from a Config, a :class:`Subject` (its ``config()``), a TOML file's
    path, a dict of tables or None; with ``controller`` (a kind or a module-level factory
    function: control/law.py), that controller in the MPC's place."""
    if controller is not None:
        kind = law.kind_of(controller)
        return as_config(config).replace(controller={"kind": kind})
    if config is None:
        return Config()
    if isinstance(config, Config):
        return config
    if isinstance(config, Subject):  # that person's body on the defaults
        return config.config()
    if isinstance(config, (str, os.PathLike)):
        return load_config(config)
    if isinstance(config, Mapping):
        return config_from_dict(dict(config))
    raise ParameterError(
        f"config must be a Config, a Subject, a TOML file's path, a dict or "
        f"None; got {type(config).__name__}"
    )


@contextmanager
def _session(call: str, physics: str = "mjx") -> Iterator[None]:
    """What the output folder's provenance records: this call (unless a command line made it)
    and the physics path; SIGINT and SIGTERM honoured wherever they land (runtime/signals.py:
    they raise KeyboardInterrupt subclasses, after the folder's clean-up)."""
    with signals.honoured(), run_context(command=f"python: mjx_balance.{call}", physics=physics):
        yield


# ---------------------------------------------------------------------------------------------
# simulate: the scalar reference


@checked
def simulate(
    forces: Values | None = None,
    durations: Values | None = None,
    config: ConfigLike = None,
    *,
    controller: Any = None,
    pairs: Any = None,
    progress: bool | None = None,
) -> "tuple[pd.DataFrame, pd.DataFrame]":
    """Pushes through the scalar reference closed loop, one scenario at a time.

    MuJoCo C physics with the MPC solved by OSQP: the cross product of ``forces`` and
    ``durations`` (every force for the first duration, then the next), or the given ``pairs`` in
    their order (``mjx-balance simulate``).

    Args:
        forces: Push forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers.
        durations: Push durations [s]: start:stop:step or a comma list (a string), or a sequence
            of numbers.
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        controller: The controller in the configuration's place: ``"mpc"``, ``"lqr"``,
            ``"pd"``, ``"package.module:factory"`` or a module-level factory function
            (docs/model.md, "Bring your own controller"); None: the configuration's.
        pairs: Instead of the cross product, these (force, duration) pushes in order:
            ``20:0.7,30:0.45``, a CSV file with columns force and duration, or a sequence of
            pairs.
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.

    Returns:
        The pair ``(summary, series)``, one summary row per push (``outcomes.SUMMARY_COLUMNS``, as
        summary.csv, plus ``hip_share`` and ``strategy``) and the time series of every push (one
        row per physics step, ``reference.TIMESERIES_COLUMNS``, as timeseries.parquet).

    Raises:
        ParameterError: a bad value, before any work.

    Example:
        >>> summary, series = mb.simulate([40, 120], [0.1])
    """
    config = as_config(config, controller)
    todo = check_pushes(config, forces, durations, pairs).todo  # before any work
    with signals.honoured():
        summary, series = reference.simulate_pairs(config, todo, progress=wanted(progress))
    return with_strategy(summary), series


# ---------------------------------------------------------------------------------------------
# sweep and table: the batched closed loop (MJX + ADMM) on the continuous-batching engine


@contextmanager
def _folder(out: str | os.PathLike[str] | None, what: str) -> Iterator[Path]:
    """``out``, or a temporary folder removed afterwards."""
    if out is not None:
        yield Path(out)
        return
    with tempfile.TemporaryDirectory(prefix=f"mjx_balance-{what}-") as tmp:
        yield Path(tmp)


@checked
def sweep(
    forces: Values,
    durations: Values,
    config: ConfigLike = None,
    *,
    out: str | os.PathLike[str] | None = None,
    controller: Any = None,
    chunk: int | None = None,
    slots: int | None = None,
    full_length: bool = False,
    progress: bool | None = None,
    wait: bool = False,
    cluster: Any = None,
    physics: str = "auto",
    reference: References = None,
    format: str | None = None,
) -> "pd.DataFrame":
    """The recoverable region: one summary row per (force, duration) cell, on the batched engine.

    Rows are force-major (all durations of the first force, then the next), as region.parquet
    holds them. Besides the summary columns each row has ``hip_share`` (the hip's share of the
    motors' work) and ``strategy`` (``ankle`` / ``hip_ankle`` for recovered cells).

    Args:
        forces: Push forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers.
        durations: Push durations [s]: start:stop:step or a comma list (a string), or a sequence
            of numbers.
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        out: The output folder, written and resumed as ``mjx-balance sweep`` writes it
            (manifest, chunks, region.parquet), without the figures; None: a temporary folder,
            nothing kept.
        controller: The controller in the configuration's place: ``"mpc"``, ``"lqr"``,
            ``"pd"``, ``"package.module:factory"`` or a module-level factory function
            (docs/model.md, "Bring your own controller"); None: the configuration's.
        chunk: Scenarios per chunk file (None: from the memory budget).
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        cluster: Run the work on a Dask cluster: ``"local:N"``, a scheduler address or file, or
            a ``distributed.Client`` (``pip install "mjx_balance[cluster]"``; docs/cluster.md).
            None: in this process.
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        reference: Reference CSV file(s) or a shipped reference's name (:func:`scorecard`):
            their ``recovered`` rows are scored against the map's cells, into ``out``'s
            scorecard.csv and the returned frame's ``.attrs["scorecard"]``.
        format: ``"csv"``, ``"parquet"`` or ``"both"``: every table of ``out`` also in that
            format (a CSV with its units in ``NAME.units.csv``; docs/outputs.md, "Units and
            exports"); None: as written.

    Returns:
        The region (``pandas.DataFrame``), one row per cell.

    Raises:
        ParameterError: a bad value or grid, before any folder is made.

    Example:
        >>> region = mb.sweep("0:150:50", [0.1, 0.3])
    """
    import pandas as pd

    config = as_config(config, controller)
    grid = Grid.of(forces, durations, config)  # checked once, before any folder
    check_format(format)
    refs = read_references(reference)
    with _session("sweep"), _folder(out, "sweep") as folder:
        result = run_region(
            folder,
            config,
            grid,
            chunk=chunk,
            slots=slots,
            full_length=full_length,
            progress=wanted(progress),
            wait=wait,
            cluster=cluster,
            physics=physics,
        )
        region = with_strategy(pd.read_parquet(result.region_path))
        card = write_scorecard(folder, refs, figure=False)
        if card is not None:
            region.attrs["scorecard"] = card
        export_tables_said(folder, format, log.info)
        return region


@checked
def table(
    forces: Values,
    config: ConfigLike = None,
    *,
    out: str | os.PathLike[str] | None = None,
    controller: Any = None,
    slots: int | None = None,
    full_length: bool = False,
    progress: bool | None = None,
    wait: bool = False,
    cluster: Any = None,
    physics: str = "auto",
    reference: References = None,
    format: str | None = None,
    figure_format: str | None = None,
    figure_size: str | None = None,
) -> "pd.DataFrame":
    """The robustness table: per force, the max acting time and the energies.

    The max acting time is the largest duration, to 0.01 s, such that every push up to it
    recovers (``TABLE_COLUMNS``, as ``mjx-balance table`` writes table.csv, read back from it).

    Args:
        forces: Table forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers.
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        out: The output folder (table.csv, table_runs.parquet: the scenarios run, kept for a
            resume), without the figure; None: a temporary folder, nothing kept.
        controller: The controller in the configuration's place: ``"mpc"``, ``"lqr"``,
            ``"pd"``, ``"package.module:factory"`` or a module-level factory function
            (docs/model.md, "Bring your own controller"); None: the configuration's.
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        cluster: Run the bisection's batch calls on a Dask cluster (as :func:`sweep`); the table
            is the same.
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        reference: Reference CSV file(s) or a shipped reference's name (:func:`scorecard`):
            their table forces join ``forces``, ``out`` gets scorecard.csv and scorecard.png,
            and the table carries the scorecard in ``.attrs["scorecard"]``.
        format: ``"csv"``, ``"parquet"`` or ``"both"``: every table of ``out`` also in that
            format (a CSV with its units in ``NAME.units.csv``; docs/outputs.md, "Units and
            exports"); None: as written.
        figure_format: ``"png"``, ``"svg"`` or ``"pdf"``; None: the style in effect
            (:func:`figure_style`; png unless set).
        figure_size: ``"screen"``, ``"one-column"`` or ``"two-column"`` (docs/outputs.md,
            "Figures"); None: the style in effect.

    Returns:
        The table (``pandas.DataFrame``), one row per force.

    Raises:
        ParameterError: a bad value, before any folder is made.
    """
    config = as_config(config, controller)
    check_format(format)
    refs = read_references(reference)
    forces = _with_forces(grid_values(forces, "forces"), refs)
    with (
        _session("table"),
        figure_style(figure_format, figure_size),
        _folder(out, "table") as folder,
    ):
        run_table_folder(
            folder,
            config,
            forces,
            slots=slots,
            full_length=full_length,
            progress=wanted(progress),
            wait=wait,
            cluster=cluster,
            physics=physics,
        )
        result = read_table(folder / TABLE)
        for line in unused_points(refs, has_map=False):  # the API's table draws no map
            log.warning(line)
        card = write_scorecard(folder, refs)
        if card is not None:
            result.attrs["scorecard"] = card
        export_tables_said(folder, format, log.info)
        return result


def _with_forces(forces: "Any", refs: "list[Reference]") -> "Any":
    """``forces`` with the reference tables' forces added (sorted, each once)."""
    import numpy as np

    extra = reference_forces(refs, forces)  # those not in forces (the scorecard's tolerance)
    if not extra:
        return forces
    merged = np.unique(np.concatenate([np.asarray(forces, float), extra]))
    return merged[np.concatenate([[True], np.diff(merged) > 1e-9])]


def scorecard(
    ours: "str | os.PathLike[str] | pd.DataFrame", reference: References
) -> "pd.DataFrame":
    """Our table beside reference tables, row by row and measure by measure.

    Each row and measure of the reference file(s) beside ours, with our uncertainty, the
    difference, the tolerance (the reference's stated or printed resolution plus our bisection
    step, never fitted) and whether the difference is within it (``studies.scorecard``). A row's
    ``reason`` is carried from the reference, never inferred.

    Args:
        ours: A sweep or table folder (its table.csv, table_runs.parquet and region.parquet are
            read; nothing is written), or a table as :func:`table` returns it.
        reference: A CSV path, the name of a shipped reference (``study``: :func:`references`),
            or a list of them (docs/outputs.md, ``Reference files``).

    Returns:
        The scorecard (``pandas.DataFrame``).

    Raises:
        TypeError: ``ours`` or ``reference`` of another type.
        ValueError: a table without a numeric ``force`` column.
    """
    import pandas as pd

    from .studies.scorecard import check_ours  # lazy: a name of the scorecard's, for one check

    if isinstance(ours, pd.DataFrame):
        check_ours(ours, "ours")
    elif not isinstance(ours, (str, os.PathLike)):
        raise TypeError(
            f"ours: expected a sweep or table folder (a path) or a table DataFrame "
            f"(as mjx_balance.table returns it); got {type(ours).__name__}"
        )
    refs = [r for r in read_references(reference) if r.kind == "table"]
    if isinstance(ours, pd.DataFrame):
        return score_results(ours, refs)
    found = folder_results(ours)
    if found["table"] is None and found["region"] is None:
        raise ParameterError(f"{ours}: holds neither table.csv nor region.parquet")
    check_ours(found["table"], str(Path(ours) / TABLE))
    return score_results(found["table"], refs, runs=found["runs"], region=found["region"])


@checked
def compare(
    configs: "Mapping[str, ConfigLike] | Sequence[str | os.PathLike[str]] | None" = None,
    *,
    out: str | os.PathLike[str],
    controllers: "Sequence[Any] | None" = None,
    forces: Values | None = None,
    durations: Values | None = None,
    table_forces: Values | None = None,
    slots: int | None = None,
    full_length: bool = False,
    physics: str = "auto",
    cluster: Any = None,
    queue: str = "each",
    progress: bool | None = None,
    format: str | None = None,
    figure_format: str | None = None,
    figure_size: str | None = None,
    wait: bool = False,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """Several configurations on one grid (``mjx-balance compare``).

    Each configuration's region map and table in ``out/<name>/``, then ``out/compare.csv`` and
    ``out/compare.png`` (every recovery boundary on one plane).

    Args:
        configs: Name -> configuration (a Config, a dict or a TOML path), or a list of TOML
            paths (named by their stems); None: the defaults (with ``controllers``).
        out: The output folder (resumable).
        controllers: Every configuration under each of these controllers (``"mpc"``,
            ``"lqr"``, ``"pd"``, ``"package.module:factory"`` or a module-level factory
            function; docs/model.md, "Bring your own controller"), each named by its kind.
        forces: Push forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers (None: the default sweep's).
        durations: Push durations [s]: start:stop:step or a comma list (a string), or a sequence
            of numbers (None: the default sweep's).
        table_forces: Also each configuration's table at these forces (None: no table).
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        cluster: Run the work on a Dask cluster: ``"local:N"``, a scheduler address or file, or
            a ``distributed.Client`` (``pip install "mjx_balance[cluster]"``; docs/cluster.md).
            None: in this process.
        queue: ``each`` (every map its own engine run) or ``one`` (every map through one engine
            queue with per-lane QPs; MJX only).
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        format: ``"csv"``, ``"parquet"`` or ``"both"``: every table of ``out`` also in that
            format (a CSV with its units in ``NAME.units.csv``; docs/outputs.md, "Units and
            exports"); None: as written.
        figure_format: ``"png"``, ``"svg"`` or ``"pdf"``; None: the style in effect
            (:func:`figure_style`; png unless set).
        figure_size: ``"screen"``, ``"one-column"`` or ``"two-column"`` (docs/outputs.md,
            "Figures"); None: the style in effect.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        compare.csv's rows (area, mean recovery energy, sustained-push limit and max acting times,
        one row per configuration).

    Raises:
        ParameterError: a bad value, before any folder is made.
    """
    check_format(format)
    named: dict[str, Config]  # (the configurations, each checked)
    if configs is None and controllers:
        named = {"base": Config()}
    elif isinstance(configs, Mapping):
        named = {str(name): as_config(c) for name, c in configs.items()}
    else:
        named = load_configs([str(p) for p in configs or []])
    named = with_controllers(named, [law.kind_of(c) for c in controllers or []])
    with _session("compare"), figure_style(figure_format, figure_size):
        frame = run_compare(
            out,
            named,
            DEFAULT_SWEEP["forces"] if forces is None else forces,
            DEFAULT_SWEEP["durations"] if durations is None else durations,
            DEFAULT_SWEEP["table_forces"] if table_forces is None else table_forces,
            progress=wanted(progress),
            say=log.info,
            slots=slots,
            full_length=full_length,
            physics=physics,
            cluster=cluster,
            queue=queue,
            plan=plan,
            wait=wait,
        )
        export_tables_said(out, format, log.info)
        return frame


@checked
def lean_release(
    config: ConfigLike = None,
    *,
    resolution: float = 0.05,
    slots: int | None = None,
    out: str | os.PathLike[str] | None = None,
    wait: bool = False,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """People's lean-and-release protocol (Robinovitch et al. 2002) on the batched engine.

    The largest lean held still (static), the largest lean released from rest that recovers with
    the feet in place (dynamic) and with one step (capturability), beside the people reference's
    measures of the same protocol (``agrees``: within the published mean +- 2 SD).

    Args:
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        resolution: The dynamic limit's bracket width [deg], in [0.001, 1].
        slots: Scenarios in flight per device (None: from the memory budget).
        out: Also write the results there (lean.csv, lean_limits.csv, a manifest; a folder made
            with another configuration is refused); None: nothing written.
        wait: Wait for another run that holds ``out`` instead of refusing at once. (with
            ``out``)
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        The people rows of the protocol beside ours, every limit in ``.attrs["limits"]``
        (``LeanLimits.row``).

    Raises:
        ParameterError: a bad value, before any work.
    """
    config = as_config(config)
    if out is None and (wait or plan is not None):
        raise ParameterError("wait and plan apply to a run written in a folder: give out=")
    slots = size_value(slots, "slots")
    with _session("lean"):
        if out is None:
            return scored(lean_limits(config, resolution=resolution, slots=slots))
        return run_lean(
            out, config, resolution=resolution, slots=slots, say=log.info, plan=plan, wait=wait
        )


@checked
def waist_pull(
    config: ConfigLike = None,
    *,
    resolution: float = 0.5,
    ramp: float = 5.0,
    slots: int | None = None,
    out: str | os.PathLike[str] | None = None,
    wait: bool = False,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """People's waist pull (DePasquale & Toscano 2009's Spring Scale Test), batched.

    The largest horizontal pull at the hip joint, rising linearly over ``ramp`` seconds and then
    held to the window's end, that the body withstands with its feet in place, forward and
    backward, in newtons and in % of body weight.

    Args:
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        resolution: The limits' bracket width [N].
        ramp: The pull's rise time [s] (0: at once).
        slots: Scenarios in flight per device (None: from the memory budget).
        out: Also write the result there (pull.csv, a manifest; another configuration's folder
            is refused); None: nothing written.
        wait: Wait for another run that holds ``out`` instead of refusing at once. (with
            ``out``)
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        One row (``PullLimits.row``), with both limits, the brackets' width, the weight, the
        peak ankle torque at each limit, the scenarios run.

    Raises:
        ParameterError: a bad value, before any work.
    """
    import pandas as pd  # lazy: as the module's other pandas users

    config = as_config(config)
    if out is None and (wait or plan is not None):
        raise ParameterError("wait and plan apply to a run written in a folder: give out=")
    slots = size_value(slots, "slots")
    with _session("waist pull"):
        if out is not None:
            return run_pull(
                out,
                config,
                resolution=resolution,
                ramp=ramp,
                slots=slots,
                say=log.info,
                plan=plan,
                wait=wait,
            )
        limits = pull_limits(config, resolution=resolution, ramp=ramp, slots=slots, say=log.info)
    return pd.DataFrame([limits.row()])


@checked
def people(
    *,
    out: str | os.PathLike[str],
    slots: int | None = None,
    wait: bool = False,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """The people scorecard (``mjx-balance people``): published measurements of people beside ours.

    Every measure of the people reference beside what the shipped human bodies (``human``,
    ``human_older``) and two women's bodies predict by lean and release, its single-step limit
    and the held waist pull, in ``out`` (people.csv, people_limits.csv, people.png, a manifest).
    Each row's ``kind``: predicted (``agrees`` within the published mean +- 2 SD), an input taken
    from that row, or not modelled; a row that is not a predicted agreement carries its measured
    ``reason``.

    Args:
        out: The output folder.
        slots: Scenarios in flight per device (None: from the memory budget).
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        people.csv's rows.
    """
    slots = size_value(slots, "slots")
    with _session("people"):
        return run_people(out, slots=slots, say=log.info, plan=plan, wait=wait)


@checked
def basin(
    config: ConfigLike = None,
    *,
    out: str | os.PathLike[str],
    x_com: Values | None = None,
    v_com: Values | None = None,
    posture: str = "rigid",
    pushes: Any = None,
    slots: int | None = None,
    full_length: bool = False,
    progress: bool | None = None,
    format: str | None = None,
    figure_format: str | None = None,
    figure_size: str | None = None,
    wait: bool = False,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """The recovery basin (``mjx-balance basin``): which initial CoM states recover with no push.

    One unpushed scenario per (x_com, v_com) cell from the ``posture`` family's initial state, in
    ``out`` (basin.parquet, basin.png; resumable).

    Args:
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        out: The output folder.
        x_com: CoM positions relative to the ankle [m]: start:stop:step or a comma list (a
            string), or a sequence of numbers (None: -0.2:0.2:0.02).
        v_com: CoM velocities [m/s]: start:stop:step or a comma list (a string), or a sequence
            of numbers (None: -0.6:0.6:0.06).
        posture: ``rigid`` (the body straight, leaning at the ankle) or ``trunk`` (upright legs,
            the trunk tilted at the hip).
        pushes: None, or (forces, durations) whose end-of-push states are drawn (pushes.csv).
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        format: ``"csv"``, ``"parquet"`` or ``"both"``: every table of ``out`` also in that
            format (a CSV with its units in ``NAME.units.csv``; docs/outputs.md, "Units and
            exports"); None: as written.
        figure_format: ``"png"``, ``"svg"`` or ``"pdf"``; None: the style in effect
            (:func:`figure_style`; png unless set).
        figure_size: ``"screen"``, ``"one-column"`` or ``"two-column"`` (docs/outputs.md,
            "Figures"); None: the style in effect.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        basin.parquet's rows.

    Raises:
        ParameterError: a bad value, before any folder is made.
    """
    check_format(format)
    with _session("basin"), figure_style(figure_format, figure_size):
        frame = run_basin(
            out,
            as_config(config),
            DEFAULT_X if x_com is None else x_com,
            DEFAULT_V if v_com is None else v_com,
            posture,
            pushes,
            progress=wanted(progress),
            say=log.info,
            slots=size_value(slots, "slots"),
            early_stop=not full_length,
            plan=plan,
            wait=wait,
        )
        export_tables_said(out, format, log.info)
        return frame


@checked
def cohort(
    subjects: "Sequence[Subject] | Mapping[str, Subject] | str | os.PathLike[str]",
    *,
    out: str | os.PathLike[str],
    forces: Values | None = None,
    durations: Values | None = None,
    config: ConfigLike = None,
    table_forces: Values | None = None,
    slots: int | None = None,
    full_length: bool = False,
    physics: str = "auto",
    queue: str = "auto",
    progress: bool | None = None,
    wait: bool = False,
    format: str | None = None,
    figure_format: str | None = None,
    figure_size: str | None = None,
) -> "pd.DataFrame":
    """A population's region maps and its probability map (``mjx-balance cohort``).

    Each subject's region map (its body from :class:`Subject` on ``config``) in
    ``out/subjects/<id>/``, then ``out/cohort.csv``, ``out/cohort_summary.csv`` (mean, SD,
    5/50/95th percentiles), the probability map (``cohort_probability.csv``: P(recover) per cell
    with its 95 % Wilson interval; ``cohort_probability_boundaries.csv``: the 95/50/5 %
    boundaries and the base body's, from its own map in ``out/base/``) and the figures
    (docs/outputs.md, "mjx-balance cohort"). Resumable: a rerun skips finished subjects and
    resumes a partial one. Every argument and every subject's configuration is checked before
    anything is written.

    Args:
        subjects: One Subject (id s01), a sequence of Subjects (ids s01, s02, ...), a dict id ->
            Subject, or a CSV file's path (columns height, mass and optionally id, sex,
            ankle_strength, hip_strength, age, notes).
        out: The output folder.
        forces: Push forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers (None: the default sweep's).
        durations: Push durations [s]: start:stop:step or a comma list (a string), or a sequence
            of numbers (None: the default sweep's).
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's). The
            subjects' bodies go on it.
        table_forces: Also each subject's table at these forces (max acting times and the
            sustained-push limit; None: no table).
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        queue: ``each`` (every subject its own engine run: the bytes of ``sweep --subject``),
            ``one`` (one engine queue with per-lane bodies, MJX only) or ``auto`` (one on the
            MJX path without a cluster, else each; a resumed folder's own).
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        format: ``"csv"``, ``"parquet"`` or ``"both"``: every table of ``out`` also in that
            format (a CSV with its units in ``NAME.units.csv``; docs/outputs.md, "Units and
            exports"); None: as written.
        figure_format: ``"png"``, ``"svg"`` or ``"pdf"``; None: the style in effect
            (:func:`figure_style`; png unless set).
        figure_size: ``"screen"``, ``"one-column"`` or ``"two-column"`` (docs/outputs.md,
            "Figures"); None: the style in effect.

    Returns:
        cohort.csv's rows (one per subject, with its body, recoverable area [N s], mean recovery
        energy, ...), with the probability map's tables in ``.attrs["probability"]`` and
        ``.attrs["probability_boundaries"]`` and the interval's worst half-width in
        ``.attrs["half_width"]``.

    Raises:
        ParameterError: a bad argument or subject, naming it, before anything is written.
        TypeError: an argument of the wrong type, naming it.
    """
    check_format(format)
    members = as_members(
        Path(subjects)
        if isinstance(subjects, os.PathLike)
        else dict(subjects)
        if isinstance(subjects, Mapping)
        else subjects
    )
    base = as_config(config)
    with figure_style(figure_format, figure_size):  # checks both, first
        plan = plan_cohort(
            out,
            members,
            base,
            DEFAULT_SWEEP["forces"] if forces is None else forces,
            DEFAULT_SWEEP["durations"] if durations is None else durations,
            table_forces=table_forces,
            say=log.info,
            slots=slots,
            full_length=full_length,
            physics=physics,
            queue=queue,
        )
        with _session("cohort"), folder_lock(plan.out, wait=wait):
            frame = run_plan(plan, progress=wanted(progress), say=log.info)
            export_tables_said(plan.out, format, log.info)
            return frame


@checked
def landscape(
    config: ConfigLike = None,
    *,
    out: str | os.PathLike[str],
    forces: Values | None = None,
    durations: Values | None = None,
    q_scales: Values = DEFAULT_SCALES,
    r_scales: Values = DEFAULT_SCALES,
    delays: str = DEFAULT_DELAYS,
    table_forces: Values = DEFAULT_TABLE_FORCES,
    slots: int | None = None,
    full_length: bool = False,
    physics: str = "auto",
    queue: str = "each",
    progress: bool | None = None,
    wait: bool = False,
    format: str | None = None,
    figure_format: str | None = None,
    figure_size: str | None = None,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """The weight landscape (``mjx-balance landscape``): the maps over Q and R scales and delays.

    For every delay setting and every Q and R scale, the region map and table of ``config`` with
    those weights in ``out/<delay>/q<q>_r<r>/`` (resumable), then landscape.csv, landscape.png
    and landscape.txt.

    Args:
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        out: The output folder.
        forces: Push forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers (None: the default sweep's).
        durations: Push durations [s]: start:stop:step or a comma list (a string), or a sequence
            of numbers (None: the default sweep's).
        q_scales: Factors on the state weights Q (None: the sweep definition's).
        r_scales: Factors on the input weights R (None: the sweep definition's).
        delays: A comma list of delays in ms, a trailing c for the delay-compensated controller
            (e.g. ``0,100c``).
        table_forces: Each setting's table at these forces (None: the definition's).
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        queue: ``each`` or ``one`` (as :func:`compare`).
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        format: ``"csv"``, ``"parquet"`` or ``"both"``: every table of ``out`` also in that
            format (a CSV with its units in ``NAME.units.csv``; docs/outputs.md, "Units and
            exports"); None: as written.
        figure_format: ``"png"``, ``"svg"`` or ``"pdf"``; None: the style in effect
            (:func:`figure_style`; png unless set).
        figure_size: ``"screen"``, ``"one-column"`` or ``"two-column"`` (docs/outputs.md,
            "Figures"); None: the style in effect.
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        landscape.csv's rows (area, sustained-push limit and mean recovery energy per setting).
    """
    check_format(format)
    with _session("landscape"), figure_style(figure_format, figure_size):
        frame = run_landscape(
            out,
            as_config(config),
            DEFAULT_SWEEP["forces"] if forces is None else forces,
            DEFAULT_SWEEP["durations"] if durations is None else durations,
            q_scales=q_scales,
            r_scales=r_scales,
            delays=delays,
            table_forces=table_forces,
            progress=wanted(progress),
            say=log.info,
            slots=slots,
            full_length=full_length,
            physics=physics,
            queue=queue,
            plan=plan,
            wait=wait,
        )
        export_tables_said(out, format, log.info)
        return frame


@checked
def sensitivity(
    config: ConfigLike = None,
    *,
    out: str | os.PathLike[str],
    forces: Values = STUDY_TABLE_FORCES,
    readings: Sequence[str] | None = None,
    slots: int | None = None,
    full_length: bool = False,
    physics: str = "auto",
    cluster: Any = None,
    progress: bool | None = None,
    wait: bool = False,
    figure_format: str | None = None,
    figure_size: str | None = None,
    plan: PlanHook | None = None,
) -> "pd.DataFrame":
    """The robustness table under every reading of the study (``mjx-balance sensitivity``).

    Each reading's table on ``config`` in ``out/<reading>/`` (resumable), then sensitivity.csv
    (the spread per force), sensitivity.png and sensitivity.txt (what holds under every reading).

    Args:
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        out: The output folder.
        forces: Table forces [N]: start:stop:step or a comma list (a string), or a sequence of
            numbers (None: the study's).
        readings: Keys of ``studies.defaults.READINGS`` (None: all).
        slots: Scenarios in flight per device (None: from the memory budget).
        full_length: Run every scenario that does not fall to t_end (no early stop).
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        cluster: Run the work on a Dask cluster: ``"local:N"``, a scheduler address or file, or
            a ``distributed.Client`` (``pip install "mjx_balance[cluster]"``; docs/cluster.md).
            None: in this process.
        progress: A progress bar on stderr: None where someone watches (a terminal, a notebook),
            True always, False never.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        figure_format: ``"png"``, ``"svg"`` or ``"pdf"``; None: the style in effect
            (:func:`figure_style`; png unless set).
        figure_size: ``"screen"``, ``"one-column"`` or ``"two-column"`` (docs/outputs.md,
            "Figures"); None: the style in effect.
        plan: Called once with the planned work (``runs.chunks.PlannedWork``) after every check,
            before anything is written (the command line says it and refuses too much work
            without --yes).

    Returns:
        sensitivity.csv's rows.
    """
    with _session("sensitivity"), figure_style(figure_format, figure_size):
        return run_sensitivity(
            out,
            as_config(config),
            forces,
            readings=list(READINGS) if readings is None else list(readings),
            progress=wanted(progress),
            say=log.info,
            slots=slots,
            full_length=full_length,
            physics=physics,
            cluster=cluster,
            plan=plan,
            wait=wait,
        )


def _report_plan(scale: str, refs, say: Callable[[str], None]) -> Plan:
    """The report's plan of ``scale``, its table's forces joined by the references' forces."""
    chosen = PLANS.get(scale)
    if chosen is None:
        raise ParameterError(f"scale = {scale!r}: must be one of {', '.join(PLANS)}")
    extra = reference_forces(refs, chosen.table_forces)  # the scorecard's force tolerance
    if extra:
        chosen = dataclasses.replace(
            chosen, table_forces=tuple(sorted({*chosen.table_forces, *extra}))
        )
        say(f"table: adding the reference's forces {', '.join(f'{f:g}' for f in extra)} N")
    return chosen


@checked
def report(
    config: ConfigLike = None,
    *,
    out: str | os.PathLike[str],
    scale: str = "default",
    backend: str | None = None,
    studies: str | None = "all",
    conventions: Sequence[str] | None = None,
    sweeps: str | os.PathLike[str] | None = None,
    reference: References = None,
    cluster: Any = None,
    physics: str = "auto",
    html_only: bool = False,
    wait: bool = False,
    progress: bool | None = None,
    say: Callable[[str], None] | None = None,
) -> Path:
    """The HTML report (``mjx-balance report``): the study's experiments and the studies beyond it.

    The experiments under each of ``conventions`` and the studies on ``config``, their tables
    saved in ``out`` (resumable), then ``out/report.html``. Every input is checked before the
    folder is made; the work runs under the folder's lock.

    Args:
        config: The configuration: a ``Config``, a TOML file's path, a dict of ``body`` /
            ``controller`` / ``scenario`` tables, a ``Subject``, or None (the study's).
        out: The output folder.
        scale: ``tiny`` (2-s runs on tiny grids), ``default`` or ``dense``.
        backend: The tables' and maps' batch function, ``mjx`` or ``reference`` (None: the
            scale's).
        studies: A comma list of study keys, ``all`` or ``none`` (None: the scale's).
        conventions: The conventions to run the experiments in (None: every convention).
        sweeps: A folder of study sweep definitions (None: the shipped ones).
        reference: Reference table(s) scored in the report (kept in ``out/references/``; their
            forces join the table).
        cluster: Run the work on a Dask cluster: ``"local:N"``, a scheduler address or file, or
            a ``distributed.Client`` (``pip install "mjx_balance[cluster]"``; docs/cluster.md).
            None: in this process.
        physics: ``"auto"``, ``"mjx"`` or ``"c"`` (MuJoCo C physics; docs/engine.md).
        html_only: Only redraw the figures and the page from the tables saved in ``out``.
        wait: Wait for another run that holds ``out`` instead of refusing at once.
        progress: The numbered stage lines and the progress bars: None where someone watches
            (bars) and always (lines), True always, False never (the command's ``-q``).
        say: Where the lines about the work go (None: the ``mjx_balance`` logger).

    Returns:
        The path of report.html.

    Raises:
        ParameterError: a bad value, before the folder is made.
    """
    say = say or log.info
    refs = read_references(reference)  # a bad file is refused before any work
    chosen = _report_plan(scale, refs, say)
    out = Path(out)
    if html_only:  # the record checked before build_report creates anything
        read_record(out / REPORT_JSON)
    else:  # every input checked before the folder is made or locked
        kept = tuple(CONVENTIONS if conventions is None else conventions)
        unknown = [c for c in kept if c not in CONVENTIONS]
        if unknown or not kept:
            raise ParameterError(
                f"conventions: unknown {', '.join(unknown) or '(none)'}; "
                f"known: {', '.join(CONVENTIONS)}"
            )
        base, study_list = as_config(config), selected_studies(studies)
        if (backend or chosen.backend) == "mjx":
            cache.enable()  # the batched rollout compiles: keep its executables
    with signals.honoured(), folder_lock(out, wait=wait):
        if not html_only:
            # what the sweep folders' manifests record as the physics path
            with run_context(
                command="python: mjx_balance.report",
                physics="mjx" if (backend or chosen.backend) == "mjx" else "mujoco",
            ):
                record = run_report(
                    out,
                    base,
                    chosen,
                    backend=backend,
                    study_list=study_list,
                    conventions=kept,
                    sweeps=None if sweeps is None else Path(sweeps),
                    cluster=cluster,
                    physics=physics,
                    progress=progress,
                )
            say(f"tables saved in {out} ({record['seconds']:.0f} s)")
        store_references(
            out,
            None
            if reference is None
            else [str(reference)]
            if isinstance(reference, (str, os.PathLike))
            else [str(r) for r in reference],
        )
        return build_report(out)


@checked
def explore(
    folder: str | os.PathLike[str], *, port: int = 0, browser: bool = False, wait: bool = False
) -> Explorer:
    """A page on this machine that draws a folder's maps and opens any cell's run.

    Served at ``http://127.0.0.1:PORT/`` for a sweep, compare or cohort folder; a cell's run is
    computed on demand by the scalar reference in the map's own configuration and kept in the
    folder (``explore/<force>_<duration>.parquet``), so a second click is served from there
    (docs/explore.md, "mjx-balance explore").

    Args:
        folder: A sweep, compare or cohort folder.
        port: The port (0: a free one).
        browser: Open the page in the default web browser.
        wait: Serve in this thread until Ctrl-C, as ``mjx-balance explore`` does, instead of in
            a background thread.

    Returns:
        The running :class:`~mjx_balance.report.explore.Explorer` (its ``url``; a notebook shows
        it as a link; ``.stop()`` ends it).

    Raises:
        ParameterError: a folder without a region map, or a port that cannot be bound.
    """
    explorer = Explorer(folder, port=port)
    log.info(
        f"explore: {explorer.folder.shown} at {explorer.url}"
        + (" (Ctrl-C stops it)" if wait else " (.stop() ends it)")
    )
    import sys

    # on Linux without a display, webbrowser would start a text browser in this terminal
    if browser and (
        not sys.platform.startswith("linux")
        or os.environ.get("DISPLAY")
        or os.environ.get("WAYLAND_DISPLAY")
    ):
        import webbrowser

        webbrowser.open(explorer.url)
    if not wait:
        return explorer.start()
    with signals.honoured():
        explorer.serve_forever()
    return explorer


def read_table(path: str | os.PathLike[str]) -> "pd.DataFrame":
    """A table.csv as :func:`table` returns it (pandas reads the floats it wrote back exactly)."""
    import pandas as pd

    return pd.read_csv(path)
