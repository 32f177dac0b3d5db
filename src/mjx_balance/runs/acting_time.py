"""The robustness table: the max acting time of each force, by a batched bisection.

For each force, the max acting time is the largest duration T (to ``resolution``, 0.01 s)
such that every duration up to T recovers. One coarse scan of durations for all forces in one
batch brackets it and checks that recovery is monotone in duration (:func:`coarse_brackets`);
then rounds that each evaluate one midpoint per force, all forces in one batch, shrink every
bracket to one ``resolution`` step (:func:`refine_round`). Given a fixed batch size (the
commands use one), each round evaluates several points per bracket instead (k-section), so
every call has that size. :func:`run_table` writes the table into a sweep folder, keeping
every scenario as its batch call returns (``store.folder.TableCells``), so that a rerun, or a
table over other forces, runs only the cells it has not seen.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np
import pandas as pd

from ..measures.capture import saved
from ..measures.outcomes import NOT_SETTLED, OUTCOMES, RECOVERED, check_results
from ..model.params import Config, ParameterError
from .batch import LazyBatch, RunBatch, evaluate, evaluate_batches, resume_engine
from .chunks import batch_limit, chunk_slices
from .cluster import ClusterBatch
from .grid import describe, parse_grid
from .progress import NoBar, progress_bar
from ..store.files import TABLE, TABLE_RUNS, write_csv, write_parquet
from ..store.folder import GRID_TOL, OutputFolder, TableCells, require_lock, same_values

# Coarse scan of the table: durations [s] tried for every force before bisecting. 0.1 s is
# always included (the table reports the energies there); t_end is added.
COARSE_DURATIONS = (0.01, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)

# Energies at T = 0.1 s (_01) and at the max acting time (_max): the study's (eq. 20,
# |sum u_i Δx_i| of the convention's pairs, docs/model.md) and the motors' absolute work.
STUDY_ENERGY_COLUMNS = [
    "study_energy_u1_01",
    "study_energy_u2_01",
    "study_energy_total_01",
    "study_energy_u1_max",
    "study_energy_u2_max",
    "study_energy_total_max",
]
MOTOR_ENERGY_COLUMNS = [
    "energy_ankle_01",
    "energy_hip_01",
    "energy_total_01",
    "energy_ankle_max",
    "energy_hip_max",
    "energy_total_max",
]
# table.csv of the paper convention: the study's energies come first (its headline); the joint
# convention's puts the motors' first (table_columns).
TABLE_COLUMNS = [
    "force",
    "max_acting_time",
    *STUDY_ENERGY_COLUMNS,
    *MOTOR_ENERGY_COLUMNS,
    "ending_outcome",
    "monotone",
    "recovered_beyond_failure",
    "outcome_01",
    "settle_time_01",
    "settle_time_max",
    "energy_u1_01",
    "energy_u2_01",
    "energy_u1_max",
    "energy_u2_max",
    "convention",
    "evaluations",
    "note",
    "sustained_push_limit",
    "max_acting_time_one_step",
]


def table_columns(convention: str) -> list[str]:
    """The columns of table.csv in their order: TABLE_COLUMNS in the paper convention (the
    study's energy first); in the joint convention the motors' energies first."""
    if convention == "paper":
        return list(TABLE_COLUMNS)
    rest = TABLE_COLUMNS[2 + len(STUDY_ENERGY_COLUMNS) + len(MOTOR_ENERGY_COLUMNS) :]
    return [*TABLE_COLUMNS[:2], *MOTOR_ENERGY_COLUMNS, *STUDY_ENERGY_COLUMNS, *rest]


# Forces [N] of the sustained-push limit's coarse scan (each pushed for the whole window).
SUSTAINED_COARSE = (0.0, 2.5, 5.0, 7.5, 10.0, 12.5, 15.0, 20.0, 30.0, 50.0, 80.0, 120.0, 200.0)
HELD = ("recovered", "not_settled")  # outcomes of a push that did not knock the body over


@dataclass
class TableResult:
    table: pd.DataFrame  # TABLE_COLUMNS, one row per force
    runs: pd.DataFrame  # every scenario evaluated (summary rows), in evaluation order
    seconds: float


def coarse_steps(
    t_end: float, resolution: float, durations: Iterable[float] = COARSE_DURATIONS
) -> np.ndarray:
    """Coarse scan durations in units of ``resolution``: the given ones that fit in t_end, 0.1 s,
    and t_end itself (at least one step)."""
    n_max = int(math.floor(t_end / resolution + 1e-9))
    if n_max < 1:
        raise ParameterError(
            f"scenario.t_end = {t_end:g} s is shorter than the resolution {resolution:g} s"
        )
    steps = {int(round(d / resolution)) for d in (*durations, 0.1) if d <= t_end + GRID_TOL}
    steps.add(n_max)
    return np.array(sorted(s for s in steps if 1 <= s <= n_max), dtype=np.int64)


def table_batch_size(config: Config, n_forces: int, resolution: float = 0.01) -> int:
    """Default batch of the table: the coarse scan in one call (rounded up to a power of two,
    as the rollout compiles), within ``batch_limit``."""
    n = n_forces * coarse_steps(config.scenario.t_end, resolution).size
    limit = batch_limit(config)
    return min(1 << max(3, math.ceil(math.log2(max(n, 1)))), max(limit, n_forces))


def max_acting_time(
    forces: np.ndarray | str | Sequence[float],
    config: Config,
    *,
    run_batch: RunBatch | None = None,
    resolution: float = 0.01,
    coarse: Iterable[float] = COARSE_DURATIONS,
    batch: int | None = None,
    points_per_round: int | None = None,
    progress: bool | None = True,
    say: Callable[[str], None] | None = print,
    cells: TableCells | None = None,
) -> TableResult:
    """Max acting time of every force (docs/outputs.md, "mjx-balance table"): the largest T, a
    multiple of ``resolution`` in [0, t_end], such that the push (F, T) recovers and so does
    every duration tried below it.

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

    cells: scenarios already evaluated (a folder's ``table_runs/``): a cell found there is read
    back, not run; the batch function runs only the others (in calls of the same sizes), and
    each call's rows are added to it as the call returns. The result is the same.

    A force whose shortest push (one resolution step) fails gets max_acting_time 0; one that
    recovers up to t_end gets t_end and no ending outcome. The energies "_01" are those of the
    run at T = 0.1 s, "_max" those at the max acting time, each only if that run recovered
    (NaN otherwise: a fallen or unsettled run's energy is never reported as a recovery's; its
    outcome is outcome_01).
    """
    say = say or (lambda _msg: None)
    start = time.perf_counter()
    forces = parse_grid(forces, "table forces")
    t_end = config.scenario.t_end
    points_per_round = _points_per_round(resolution, batch, points_per_round, forces.size)
    steps = coarse_steps(t_end, resolution, coarse)
    n_max = int(math.floor(t_end / resolution + 1e-9))
    run_batch = run_batch or LazyBatch(config)
    n_f, n_c = forces.size, steps.size
    if hasattr(run_batch, "prepare"):
        run_batch.prepare(batch or n_f * n_c, say=say)
    widest = int(np.diff(np.concatenate([[0], steps])).max())
    say(_plan_text(n_f, n_c, points_per_round, resolution, batch, config.controller.convention))
    bar = _table_bar(n_f, n_c, widest, points_per_round, progress)
    options: dict[str, Any] = dict(batch=batch, resolution=resolution, cells=cells)
    options["points_per_round"] = points_per_round
    reserve = n_f * bracket_cost(widest, points_per_round)  # the one-step rounds' most
    try:
        brackets, runs = _bracket_rounds(
            run_batch, forces, steps, n_max, config, bar=bar, reserve=reserve, **options
        )
        one_step = _one_step_rounds(run_batch, forces, steps, n_max, config, bar, runs, options)
    finally:
        bar.close()

    table = _table_of(forces, brackets, steps, resolution, t_end, config)
    table["max_acting_time_one_step"] = (
        np.round(one_step.lo * resolution, 12) if one_step is not None else np.nan
    )
    # every scenario once (the one-step rounds read back cells the in-place rounds ran)
    runs_frame = pd.concat(runs, ignore_index=True).drop_duplicates(
        ["force", "duration"], ignore_index=True
    )
    seconds = time.perf_counter() - start
    say(f"table: {len(runs_frame)} scenarios in {seconds:.1f} s")
    return TableResult(table, runs_frame, seconds)


def _one_step_rounds(
    run_batch: Any,
    forces: np.ndarray,
    steps: np.ndarray,
    n_max: int,
    config: Config,
    bar: Any,
    runs: list[pd.DataFrame],
    options: dict[str, Any],
) -> Brackets | None:
    """The brackets with one step (capturability, ``steps_needed`` <= 1; None where the rows
    lack it): the in-place rounds' coarse scan ``runs[0]``, then rounds where the one-step
    bracket is still open; a cell the in-place rounds ran is read back, not run again (from
    ``options["cells"]``, or kept in memory here). Appends the new rounds' rows to ``runs``."""
    if "steps_needed" not in runs[0]:
        return None
    if options["cells"] is None:
        options = {**options, "cells": TableCells(None, config.controller.convention)}
        for frame in runs:
            options["cells"].add(frame)
    one_step, more = _bracket_rounds(
        run_batch, forces, steps, n_max, config, bar=bar, within=1, coarse_frame=runs[0], **options
    )
    runs += more
    return one_step


def _plan_text(
    n_f: int, n_c: int, points_per_round: int, resolution: float, batch: int | None, convention: str
) -> str:
    """The line that says the table's planned work: forces, coarse scan, rounds, batches."""
    return (
        f"table: {n_f} forces; coarse scan of {n_c} durations, then "
        + ("bisection" if points_per_round == 1 else f"{points_per_round + 1}-section")
        + f" to {resolution:g} s"
        + (f" in batches of {batch}" if batch else "")
        + f"; convention {convention}"
    )


def _table_bar(n_f: int, n_c: int, widest: int, points_per_round: int, progress: bool | None):
    """The table's progress bar, over the most scenarios its coarse scan and rounds can take."""
    # a fixed total: the most scenarios the coarse scan and the rounds, in place and with one
    # step, can take (the bar counts those run and those a force no longer needs once its
    # bracket has closed)
    return progress_bar(
        n_f * (n_c + 2 * bracket_cost(widest, points_per_round)), 0, progress, desc="table"
    )


def _table_of(
    forces: np.ndarray,
    brackets: Brackets,
    steps: np.ndarray,
    resolution: float,
    t_end: float,
    config: Config,
) -> pd.DataFrame:
    """The table: one row per force from its closed bracket (:func:`table_row`)."""
    rows = [
        table_row(i, force, brackets, steps, resolution, t_end, config)
        for i, force in enumerate(forces)
    ]
    return pd.DataFrame(rows, columns=table_columns(config.controller.convention))


def _points_per_round(
    resolution: float, batch: int | None, points_per_round: int | None, n_forces: int
) -> int:
    """Check the table's resolution and batch; the points per bracket and round (default
    max(1, batch // n_forces) with a batch, else 1: bisection)."""
    if not resolution > 0:
        raise ParameterError(f"resolution must be > 0, got {resolution}")
    if batch is not None and not (isinstance(batch, int) and batch >= 1):
        raise ParameterError(f"batch must be an integer >= 1, got {batch!r}")
    if points_per_round is None:
        points_per_round = max(1, batch // n_forces) if batch else 1
    if not (isinstance(points_per_round, int) and points_per_round >= 1):
        raise ParameterError(f"points_per_round must be an integer >= 1, got {points_per_round!r}")
    return points_per_round


def _bracket_rounds(
    run_batch: RunBatch,
    forces: np.ndarray,
    steps: np.ndarray,
    n_max: int,
    config: Config,
    *,
    batch: int | None,
    resolution: float,
    points_per_round: int,
    cells: TableCells | None,
    bar: Any,
    within: int | None = None,
    coarse_frame: pd.DataFrame | None = None,
    reserve: int = 0,
) -> tuple[Brackets, list[pd.DataFrame]]:
    """The coarse scan of the durations ``steps`` (in resolution units) for every force [n_f]
    (or its rows ``coarse_frame``, already run), then refine rounds until every bracket is one
    resolution step wide (``within``: :func:`recovers`); returns the brackets and each call's
    summary rows (the coarse scan first, when run here). ``bar`` counts the scenarios (its
    total, an upper estimate, is set to the count at the end; ``reserve`` of it is left for
    rounds that follow)."""
    n_f, n_c = forces.size, steps.size
    runs: list[pd.DataFrame] = []
    if coarse_frame is None:
        coarse_frame = evaluate_cells(
            run_batch,
            np.repeat(forces, n_c),
            np.round(np.tile(steps * resolution, n_f), 12),
            config,
            batch,
            None,
            cells,
        )
        runs.append(coarse_frame)
    brackets = coarse_brackets(coarse_frame, steps, n_max, within)

    def work_left() -> int:
        return reserve + sum(
            bracket_cost(int(brackets.hi[i] - brackets.lo[i]), points_per_round)
            for i in brackets.active()
        )

    advance(bar, work_left())
    for _round in range(64):
        if not brackets.active().size:
            break
        frame = refine_round(
            brackets,
            forces,
            run_batch,
            config,
            batch,
            resolution,
            points_per_round,
            cells=cells,
            within=within,
        )
        runs.append(frame)
        advance(bar, work_left())
    else:  # pragma: no cover - the bracket halves every round
        raise RuntimeError("bisection did not converge")
    return brackets, runs


def bracket_cost(width: int, points_per_round: int) -> int:
    """The most scenarios the k-section of a bracket ``width`` resolution steps wide runs
    (``points_per_round`` = k points a round; each round leaves a gap of at most
    ceil(width / (k + 1)))."""
    n = 0
    while width > 1:
        n += min(points_per_round, width - 1)
        width = -(-width // (points_per_round + 1))
    return n


def advance(bar: Any, left: int) -> None:
    """Move ``bar`` (its total an upper bound of the scenarios, fixed) to total - ``left``:
    the scenarios run and those no longer needed; never backwards."""
    if bar is None or isinstance(bar, NoBar):
        return
    target = max(bar.n, bar.total - left)
    if target > bar.n:
        bar.update(target - bar.n)


@dataclass
class Brackets:
    """Per force, in units of the resolution: the largest recovered duration ``lo`` (0:
    nothing recovered yet) and the smallest failed one ``hi`` above it (n_max + 1: nothing
    failed), with their summary rows; what the coarse scan found beyond the first failure;
    the number of scenarios evaluated."""

    lo: np.ndarray
    hi: np.ndarray
    lo_row: list[dict | None]
    hi_row: list[dict | None]
    monotone: np.ndarray  # bool: no recovered coarse duration beyond the first failure
    beyond: np.ndarray  # largest recovered coarse duration beyond the first failure [s]
    evaluations: np.ndarray
    coarse_rows: list[list[dict]]  # the coarse scan's rows, per force
    n_max: int

    def active(self) -> np.ndarray:
        """Forces whose bracket is wider than one step and below t_end."""
        return np.flatnonzero((self.hi - self.lo > 1) & (self.hi <= self.n_max))


def recovers(frame: pd.DataFrame, within: int | None = None) -> np.ndarray:
    """Which runs recover: in place (outcome recovered), or with ``within`` steps at most
    (``steps_needed``, capturability: a run that did not fall needs none)."""
    in_place = frame["outcome"].to_numpy() == OUTCOMES[RECOVERED]
    return saved(in_place, frame.get("steps_needed"), within)


def coarse_brackets(
    coarse_frame: pd.DataFrame, steps: np.ndarray, n_max: int, within: int | None = None
) -> Brackets:
    """Brackets from the coarse scan (rows force-major, ``steps`` durations per force): the
    first failure brackets T between the last recovered coarse duration and it; a recovered
    coarse duration beyond it marks the force not monotone. ``within``: recovered with at
    most that many steps (:func:`recovers`)."""
    n_c = steps.size
    n_f = len(coarse_frame) // n_c
    recovered = recovers(coarse_frame, within).reshape(n_f, n_c)
    rows = coarse_frame.to_dict("records")
    coarse_rows = [rows[i * n_c : (i + 1) * n_c] for i in range(n_f)]
    first_fail = np.where(recovered.all(axis=1), n_c, np.argmin(recovered, axis=1))
    b = Brackets(
        lo=np.zeros(n_f, dtype=np.int64),
        hi=np.full(n_f, n_max + 1, dtype=np.int64),
        lo_row=[None] * n_f,
        hi_row=[None] * n_f,
        monotone=np.ones(n_f, dtype=bool),
        beyond=np.full(n_f, np.nan),
        evaluations=np.full(n_f, n_c, dtype=np.int64),
        coarse_rows=coarse_rows,
        n_max=n_max,
    )
    for i in range(n_f):
        j = first_fail[i]
        if j > 0:
            b.lo[i], b.lo_row[i] = steps[j - 1], coarse_rows[i][j - 1]
        if j < n_c:
            b.hi[i], b.hi_row[i] = steps[j], coarse_rows[i][j]
            later = np.flatnonzero(recovered[i, j + 1 :])
            if later.size:
                b.monotone[i] = False
                b.beyond[i] = steps[j + 1 + later[-1]]
    return b


def evaluate_cells(
    run_batch: RunBatch,
    forces: np.ndarray,
    durations: np.ndarray,
    config: Config,
    batch: int | None,
    pad_to: int | None,
    cells: TableCells | None,
) -> pd.DataFrame:
    """Summary rows of the scenarios, in order: in calls of exactly ``batch`` (padded) if
    given, else one call padded to ``pad_to``. With ``cells``, only the scenarios it lacks are
    run (in calls of those sizes), each call's rows are kept there as it returns, and every row
    is read back from it (so a resumed table is built from the same values as a whole one).
    On a cluster (a batch function with ``evaluate_calls``, ``cluster.ClusterBatch``) the same
    calls run as tasks on its workers, all of a round's at once, and come back in order: the
    rows, and so the kept part files, are those of a local run."""
    on_cluster = getattr(run_batch, "evaluate_calls", None)  # cluster.ClusterBatch
    if cells is None:
        if on_cluster is not None:
            parts = chunk_slices(forces.size, batch) if batch else [slice(0, forces.size)]
            frames = list(on_cluster([(forces[p], durations[p]) for p in parts], batch or pad_to))
            return pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
        return (
            evaluate_batches(run_batch, forces, durations, config, batch)
            if batch
            else evaluate(run_batch, forces, durations, config, pad_to=pad_to)
        )
    todo = cells.missing(forces, durations)
    calls = [
        todo[part]
        for part in (chunk_slices(todo.size, batch) if batch else [slice(0, todo.size)])
        if todo[part].size
    ]
    if on_cluster is not None:
        # the same calls, each split into tasks over the workers and kept as it comes back
        for frame in on_cluster([(forces[c], durations[c]) for c in calls], batch or pad_to):
            cells.add(frame)
    else:
        for call in calls:
            cells.add(
                evaluate(run_batch, forces[call], durations[call], config, pad_to=batch or pad_to)
            )
    return cells.frame(forces, durations)


def refine_round(
    b: Brackets,
    forces: np.ndarray,
    run_batch: RunBatch,
    config: Config,
    batch: int | None,
    resolution: float,
    points_per_round: int,
    *,
    cells: TableCells | None = None,
    within: int | None = None,
) -> pd.DataFrame:
    """One round of bisection (k-section for points_per_round = k > 1): evaluate k points
    inside each active bracket, all forces in one batch of the fixed size n_f * k (or calls of
    ``batch``); each bracket shrinks to the gap around its first failing point (``within``:
    :func:`recovers`). Updates ``b`` and returns the round's summary rows."""
    k_points = int(points_per_round)
    owner: list[int] | np.ndarray  # (lists while gathered, then arrays)
    points: list[int] | np.ndarray
    owner, points = [], []
    for i in b.active():
        split = b.lo[i] + (b.hi[i] - b.lo[i]) * np.arange(1, k_points + 1) // (k_points + 1)
        split = np.unique(split[(split > b.lo[i]) & (split < b.hi[i])])
        owner += [i] * split.size
        points += split.tolist()
    owner, points = np.asarray(owner), np.asarray(points, dtype=np.int64)
    durations = np.round(points * resolution, 12)
    frame = evaluate_cells(
        run_batch, forces[owner], durations, config, batch, forces.size * k_points, cells
    )
    ok = recovers(frame, within)
    rows = frame.to_dict("records")
    for i in np.unique(owner):
        mine = np.flatnonzero(owner == i)  # ascending durations
        b.evaluations[i] += mine.size
        failing = mine[~ok[mine]]
        if failing.size:
            first = failing[0]
            b.hi[i], b.hi_row[i] = points[first], rows[first]
            below = mine[mine < first]
        else:
            below = mine
        if below.size:
            b.lo[i], b.lo_row[i] = points[below[-1]], rows[below[-1]]
    return frame


def table_row(
    i: int,
    force: float,
    b: Brackets,
    steps: np.ndarray,
    resolution: float,
    t_end: float,
    config: Config,
) -> dict[str, Any]:
    """The table row (TABLE_COLUMNS) of force ``i`` from its final bracket."""
    index_01 = int(round(0.1 / resolution))
    at_01 = next((r for s, r in zip(steps, b.coarse_rows[i]) if s == index_01), None)
    at_max = b.lo_row[i]
    # energies (and settle times) of recovered runs only: a run that fell or did not settle
    # leaves them NaN (its outcome is in outcome_01 / ending_outcome)
    energy_01 = at_01 if _recovered(at_01) else None
    energy_max = at_max if _recovered(at_max) else None
    hi_row = b.hi_row[i]
    note = ""
    if b.lo[i] == 0:
        note = f"fails at the shortest push tried ({steps[0] * resolution:g} s)"
    elif b.hi[i] > b.n_max:
        note = f"recovers for every duration up to t_end = {t_end:g} s"
    elif hi_row is not None and hi_row["outcome"] == OUTCOMES[NOT_SETTLED]:
        note = (
            f"a longer push does not fall but is not settled by t_end = {t_end:g} s "
            "(limited by the time window)"
        )
    beyond = b.beyond[i] * resolution
    if not b.monotone[i]:
        note = (note + "; " if note else "") + (
            f"not monotone: fails at {b.hi[i] * resolution:g} s but recovers again at "
            f"{beyond:g} s (coarse scan)"
        )
    return {
        "force": float(force),
        "max_acting_time": round(float(b.lo[i] * resolution), 12),
        "energy_ankle_01": _get(energy_01, "energy_ankle"),
        "energy_hip_01": _get(energy_01, "energy_hip"),
        "energy_total_01": _get(energy_01, "energy_total"),
        "energy_ankle_max": _get(energy_max, "energy_ankle"),
        "energy_hip_max": _get(energy_max, "energy_hip"),
        "energy_total_max": _get(energy_max, "energy_total"),
        **{
            f"{c}_{suffix}": _get(row, c)
            for suffix, row in (("01", energy_01), ("max", energy_max))
            for c in ("study_energy_u1", "study_energy_u2", "study_energy_total")
        },
        "ending_outcome": hi_row["outcome"] if hi_row is not None else "",
        "monotone": bool(b.monotone[i]),
        "recovered_beyond_failure": beyond,
        "outcome_01": at_01["outcome"] if at_01 is not None else "",
        "settle_time_01": _get(at_01, "settle_time"),
        "settle_time_max": _get(at_max, "settle_time"),
        "energy_u1_01": _get(energy_01, "energy_u1"),
        "energy_u2_01": _get(energy_01, "energy_u2"),
        "energy_u1_max": _get(energy_max, "energy_u1"),
        "energy_u2_max": _get(energy_max, "energy_u2"),
        "convention": config.controller.convention,
        "sustained_push_limit": float("nan"),  # a configuration's, set by run_table
        "max_acting_time_one_step": float("nan"),  # the one-step rounds', set by the caller
        "evaluations": int(b.evaluations[i]),
        "note": note,
    }


def sustained_push_limit(
    config: Config,
    run_batch: RunBatch,
    *,
    batch: int | None = None,
    cells: TableCells | None = None,
    resolution: float = 0.1,
    points_per_round: int = 7,
    coarse: Sequence[float] = SUSTAINED_COARSE,
    bar: Any = None,
) -> tuple[float, str, pd.DataFrame]:
    """The largest force (a multiple of ``resolution``, N) that the body holds for the whole
    window: pushed from t = 0 to t_end, it does not fall (the outcome is recovered or
    not_settled: a body leaning against a push that is still on at t_end is outside the settle
    band), and no force of the coarse scan below it falls either.

    A coarse scan of ``coarse`` forces in one call brackets the limit between the last force
    held and the first that falls; rounds of ``points_per_round`` evenly spaced forces then
    shrink the bracket to one resolution step (k-section, as the table's rounds). Returns
    (limit, note, every scenario run); the limit is 0 if the unpushed body falls, the largest
    coarse force if every one is held (the note says so, and when a force above the first
    failure is held again). ``bar``: a progress bar updated with the scenarios run."""
    t_end = config.scenario.t_end
    units = np.unique(np.round(np.asarray(coarse, float) / resolution).astype(np.int64))

    def held(points: np.ndarray) -> tuple[np.ndarray, pd.DataFrame]:
        frame = evaluate_cells(
            run_batch,
            np.round(points * resolution, 12),
            np.full(points.size, t_end),
            config,
            batch,
            None,
            cells,
        )
        if bar is not None:  # never past a fixed total
            room = getattr(bar, "total", None)
            bar.update(points.size if room is None else min(points.size, max(0, room - bar.n)))
        return frame["outcome"].isin(HELD).to_numpy(), frame

    ok, frame = held(units)
    runs = [frame]
    if not ok[0]:
        return 0.0, f"the body falls at {units[0] * resolution:g} N held for {t_end:g} s", frame
    if ok.all():
        top = units[-1] * resolution
        return float(top), f"holds every force tried, up to {top:g} N", frame
    first = int(np.argmin(ok))
    note = ""
    if ok[first:].any():
        note = (
            f"not monotone: falls at {units[first] * resolution:g} N but holds "
            f"{units[first:][ok[first:]].max() * resolution:g} N (coarse scan)"
        )
    lo, hi = int(units[first - 1]), int(units[first])
    while hi - lo > 1:
        split = lo + (hi - lo) * np.arange(1, points_per_round + 1) // (points_per_round + 1)
        split = np.unique(split[(split > lo) & (split < hi)])
        ok, frame = held(split)
        runs.append(frame)
        if ok.all():
            lo = int(split[-1])
        else:
            fail = int(np.argmin(ok))
            hi = int(split[fail])
            lo = int(split[fail - 1]) if fail > 0 else lo
    return round(lo * resolution, 12), note, pd.concat(runs, ignore_index=True)


def _add_sustained_limit(
    result: TableResult,
    config: Config,
    run_batch: RunBatch,
    cells: TableCells,
    batch: int | None,
    progress: bool | None,
    say: Callable[[str], None],
) -> None:
    """The sustained-push limit into ``result``'s table (a column) and runs, with a progress
    bar and a line on how it came out."""
    start = time.perf_counter()
    units = np.unique(np.round(np.asarray(SUSTAINED_COARSE) / 0.1).astype(np.int64))
    # a fixed total: the coarse scan and the most its bracket's rounds can take (7 points a
    # round, as sustained_push_limit's defaults); what was not needed is counted at the end
    bar = progress_bar(
        units.size + bracket_cost(int(np.diff(units).max()), 7), 0, progress, desc="sustained limit"
    )
    try:
        limit, note, held_runs = sustained_push_limit(
            config, run_batch, batch=batch, cells=cells, bar=bar
        )
        advance(bar, 0)
    finally:
        bar.close()
    say(
        f"table: sustained-push limit {limit:g} N (the largest force held for the whole "
        f"{config.scenario.t_end:g}-s window{'; ' + note if note else ''}; "
        f"{len(held_runs)} scenarios in {time.perf_counter() - start:.1f} s)"
    )
    result.table["sustained_push_limit"] = limit
    result.runs = pd.concat([result.runs, held_runs], ignore_index=True)


def _recovered(row: dict | None) -> bool:
    return row is not None and row["outcome"] == OUTCOMES[RECOVERED]


def _get(row: dict | None, key: str) -> float:
    return float(row[key]) if row is not None else float("nan")


def run_table(
    out: str | os.PathLike[str],
    config: Config,
    forces: np.ndarray | str | Sequence[float],
    *,
    run_batch: RunBatch | None = None,
    progress: bool | None = True,
    say: Callable[[str], None] | None = print,
    cluster: Any = None,
    sustained: bool = True,
    **options: Any,
) -> TableResult | None:
    """``max_acting_time`` into ``out/table.csv`` (+ table_runs.parquet, every scenario run),
    under the folder's lock, which the run's entry holds (``store.folder.folder_lock``).

    Every scenario is kept in ``out/table_runs/`` as its batch call returns: an interrupted
    table resumes from them, and a table over other forces reuses the cells they share.
    Returns None (and does nothing) when the folder already holds the table for these forces.

    cluster: run each round's batch calls on a Dask cluster (``cluster.ClusterBatch``, as
    ``run_sweep``'s chunks: ``"local:N"``, a scheduler address or file, or a
    ``distributed.Client``); the bisection, the kept scenarios and the table stay here and
    are the same as without it. None: here. sustained: also the sustained-push limit
    (:func:`sustained_push_limit`; False: the column is NaN, as in a report's tiny plan).
    """
    forces = parse_grid(forces, "table forces")
    # the run's entry holds the folder's lock: a failure below marks the run failed
    require_lock(out)
    if cluster is None:
        result = _run_table(out, config, forces, run_batch, progress, say, options, sustained)
    else:
        with ClusterBatch(cluster, run_batch or LazyBatch(config), config, say) as on_cluster:
            result = _run_table(out, config, forces, on_cluster, progress, say, options, sustained)
    runs = (
        result.runs
        if result is not None
        else pd.read_parquet(Path(out) / TABLE_RUNS, columns=["outcome"])
    )
    check_results(runs["outcome"], "scenarios the table ran")
    return result


def _run_table(
    out: str | os.PathLike[str],
    config: Config,
    forces: np.ndarray,
    run_batch: Any,
    progress: bool | None,
    say: Callable[[str], None] | None,
    options: dict[str, Any],
    sustained: bool = True,
) -> TableResult | None:
    # (run_batch: a batch function, None, or a cluster.ClusterBatch, found by its methods)
    say = say or (lambda _msg: None)
    folder = OutputFolder(out, config)
    manifest = folder.open()
    recorded = manifest.get("table")
    table_path = folder.path / TABLE
    if folder.rebuilt:
        say(
            f"note: {folder.path} had lost its manifest; rebuilt it: config.toml matches this run"
            + (f" and table.csv holds forces {describe(recorded['forces'])}" if recorded else "")
        )
        folder.write_manifest(manifest)
    if recorded is not None and same_values(recorded["forces"], forces) and table_path.exists():
        try:
            done = pd.read_csv(table_path)
            # a table from before a column (e.g. the study's energies) is made again
            if same_values(done["force"], forces) and set(TABLE_COLUMNS) <= set(done):
                say(f"table already complete: {table_path} ({forces.size} forces); nothing to do")
                return None
        except Exception:
            pass
    if recorded is not None and not same_values(recorded["forces"], forces):
        say(
            f"replacing the table for forces {describe(recorded['forces'])} in {folder.path} "
            "(reusing the scenarios they share)"
        )
    folder.check_numerics(manifest)  # new scenarios: computed as the folder's were
    # the engine settings the table's scenarios were (or will be) run with
    run_batch = run_batch or LazyBatch(config)
    if manifest.get("table_engine") is not None:
        resume_engine(run_batch, manifest["table_engine"], folder.path, say)
    elif hasattr(run_batch, "engine_record") and run_batch.engine_record() is not None:
        manifest["table_engine"] = run_batch.engine_record()
        folder.write_manifest(manifest)
    cells = TableCells(folder.path, config.controller.convention)
    if cells.rows:
        say(
            f"table: {len(cells.rows)} scenarios already evaluated in {cells.path}; "
            "running only the others"
        )
    result = max_acting_time(
        forces, config, run_batch=run_batch, progress=progress, say=say, cells=cells, **options
    )
    if sustained:
        _add_sustained_limit(result, config, run_batch, cells, options.get("batch"), progress, say)
    write_parquet(result.runs, folder.path / TABLE_RUNS)
    write_csv(result.table, table_path)
    manifest = folder.read_manifest() or manifest
    manifest["table"] = {"forces": forces.tolist(), "resolution": options.get("resolution", 0.01)}
    folder.write_manifest(manifest)
    say(f"wrote {table_path}")
    return result


def table_scenarios(config: Config, n_forces: int) -> int:
    """Scenarios a table evaluates, at most: every force's (:func:`table_scenarios_per_force`)
    and the sustained-push limit's (its coarse scan and rounds to 0.1 N from its widest
    bracket); a planning estimate."""
    coarse = np.asarray(SUSTAINED_COARSE)
    rounds = math.ceil(math.log(np.diff(coarse).max() / 0.1) / math.log(8))
    return n_forces * table_scenarios_per_force(config) + coarse.size + 7 * rounds


def table_scenarios_per_force(config: Config, resolution: float = 0.01) -> int:
    """Scenarios the table evaluates per force, at most: its coarse scan, then one bisection of
    the widest bracket (a planning estimate; resumed or monotone forces need fewer)."""
    steps = coarse_steps(config.scenario.t_end, resolution)
    widest = int(max(np.diff(np.concatenate([[0], steps])).max(), 1))
    return int(steps.size + math.ceil(math.log2(widest)) + 1)
