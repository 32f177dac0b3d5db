"""Cohorts (``mjx-balance cohort``, :func:`run_cohort`): one region map per subject of a
population, and the population's numbers.

Each subject is a person (``model.subject.Subject``: height, mass, sex, ankle and hip strength)
whose body goes on the base configuration (``Subject.config(base)``). Each subject's region
map is a plain sweep folder ``OUT/subjects/<id>/`` run by ``runs.folders.run_region`` (its own
manifest, chunks and resume: a cohort run again skips finished subjects and resumes a partial
one), with the subject's table in the same folder when table forces are given. Then:

cohort.csv
    one row per subject: its id and body values, then the numbers a comparison gives a
    configuration (``studies.compare.numbers``: recoverable area [N s], fraction, cells,
    f_max_ref, mean recovery energy [J]; sustained-push limit [N] and max acting time per
    table force [s] when table forces are given, else the limit is NaN)
cohort_summary.csv
    the population's spread: mean, SD (n - 1), 5th, 50th and 95th percentile of every numeric
    column of cohort.csv (NaNs left out), one row per statistic
cohort_probability.csv
    per cell (F, T): the subjects, those that recover, P(recover | F, T) and its 95 % Wilson
    interval (``studies.probability``)
cohort_probability_boundaries.csv
    per force: the longest duration up to which P(recover) >= 0.95, 0.5 and 0.05 at every
    grid duration, and the base body's own recovery boundary
base/
    the base configuration's region map (a plain sweep folder, run after the subjects): the
    reference boundary of cohort_probability.png
manifest.json
    the base configuration, the grids, the subjects with their ids, and the runs' provenance
cohort_area.png, cohort_boundaries.png, cohort_probability.png, cohort_regions.png
    figures (``figures.cohort``); the small multiples only for cohorts of at most
    :data:`SMALL_COHORT` subjects

Subjects share one compiled program: the body, the QP, the certificate and the torque bounds
are traced arguments of the batched closed loop (``rollout.kernel.split_limits``,
``rollout.physics.canonical_hfield_bounds``), so only the first subject compiles (or none, with
the persistent cache warm; docs/cohorts.md, "Cohorts", has the measured cost).

Who the subjects are (a grid, a sampled population, a CSV file): ``members.py``.

Everything is checked before the folder is made or locked (:func:`plan_cohort`: the ids, the
grids, the engine's options and, up to :data:`CHECKED_FIRST` subjects, every subject's
configuration as the batched closed loop will run it; beyond, the :func:`representatives`,
and every subject again when its queue starts), so a refused cohort writes nothing, and a
large one's first scenario waits for a few subjects' set-up only (``runs.population``: queues
of 16 bodies, then twice as many each, up to 1,024). A cohort folder none of whose subjects holds a
result (a run refused or stopped before its first result) is taken over by a run with another
configuration or other subjects, as a sweep folder is (``store.folder``).
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..figures import cohort as cohort_figures
from ..figures.region import log_durations
from ..model.params import Config, ParameterError
from ..rollout.cpath import PATHS
from ..runs.folders import (
    check_batched,
    check_float32_grid,
    run_region,
    run_table_folder,
    size_value,
)
from ..runs.grid import Grid, duration_values, grid_values
from ..runs.population import check_queue, run_maps
from ..runs.progress import progress_bar
from ..store.files import MANIFEST, REGION, TABLE, write_csv, write_text
from ..store.folder import OutputFolder, config_dict
from ..store.provenance import with_run
from . import probability
from .compare import boundary_segments, numbers
from .members import Member, check_ids

COHORT_CSV = "cohort.csv"
SUMMARY_CSV = "cohort_summary.csv"
PROBABILITY_CSV = "cohort_probability.csv"
BOUNDARIES_CSV = "cohort_probability_boundaries.csv"
SUBJECTS = "subjects"
BASE = "base"  # the base configuration's own map: the probability figure's reference boundary
SMALL_COHORT = 16  # cohort_regions.png: one panel per subject up to this many
# Cohorts of up to this many subjects have every configuration checked before the folder is
# made (about 0.1 s each); larger ones their representatives (plan_cohort)
CHECKED_FIRST = 64
CHOSEN = 8  # cohort_boundaries.png: at most this many subjects' boundaries
SUBJECT_COLUMNS = ["id", "height", "mass", "sex", "ankle_strength", "hip_strength"]
STATISTICS = ("mean", "sd", "p5", "p50", "p95")


def _record(
    members: Sequence[Member],
    base: Config,
    forces: np.ndarray,
    durations: np.ndarray,
    table_forces: np.ndarray | None,
) -> dict[str, Any]:
    return {
        "kind": "cohort",
        "config": config_dict(base),
        "cohort": {
            "forces": forces.tolist(),
            "durations": durations.tolist(),
            "table_forces": None if table_forces is None else table_forces.tolist(),
            "subjects": [m.record() for m in members],
        },
    }


def holds_results(out: Path, base: Config) -> bool:
    """Whether a cohort folder holds anything computed: cohort.csv, or a subject's folder or
    the base map's folder with a result (``OutputFolder.holds_results``: a map, a chunk, a
    table's kept scenario)."""
    if (out / COHORT_CSV).exists():
        return True
    folders = list((out / SUBJECTS).glob("*/")) if (out / SUBJECTS).is_dir() else []
    folders += [out / BASE] if (out / BASE).is_dir() else []
    return any(OutputFolder(folder, base).holds_results() for folder in folders)


def open_manifest(
    out: Path,
    record: dict[str, Any],
    base: Config | None = None,
    say: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """The cohort's manifest: a new one, or the folder's if it holds this same cohort (base,
    grids, subjects); another cohort's folder is refused, unless it holds no result yet (a
    run refused or stopped before its first result): then this cohort takes it over, keeping
    its runs' records (``say`` tells). Reads only: the caller writes what it returns."""
    path = out / MANIFEST
    if not path.exists():
        return dict(record)
    try:
        old = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ParameterError(f"{path}: cannot be read ({exc}); use another --out") from None
    if not isinstance(old, dict) or old.get("kind") != "cohort":
        raise ParameterError(
            f"{out} holds another kind of output (its {MANIFEST} is not a "
            "cohort's); use another --out folder"
        )
    differ = [
        key
        for key in ("config", "cohort")
        if json.dumps(old.get(key), sort_keys=True) != json.dumps(record[key], sort_keys=True)
    ]
    if not differ:
        return {**old, **record}
    if not holds_results(out, base if base is not None else Config()):
        if say is not None:
            say(
                f"note: {out} holds no results of the cohort it was made for; starting it "
                "anew with this run's configuration and subjects"
            )
        runs = old.get("runs")
        return {**record, **({"runs": runs} if isinstance(runs, list) else {})}
    what = "configuration" if differ[0] == "config" else "subjects or grids"
    raise ParameterError(
        f"{out} holds a cohort with other {what}; use another --out folder or the same cohort"
    )


@dataclass(frozen=True)
class CohortPlan:
    """A cohort checked before anything is written (:func:`plan_cohort`): its folder, its
    subjects and each one's configuration, the grids, and the engine's options."""

    out: Path
    members: tuple[Member, ...]
    base: Config
    forces: np.ndarray
    durations: np.ndarray
    tables: np.ndarray | None
    engine: dict[str, Any]
    recorded: dict[str, Any]  # what the manifest records (built once: 3 s for 100,000 subjects)

    def record(self) -> dict[str, Any]:
        return self.recorded

    def config(self, member: Member) -> Config:
        """``member``'s configuration (``Subject.config(base)``: a formula, built when its map
        runs, so a cohort holds one queue's configurations at a time)."""
        return member.subject.config(self.base)


def check_engine(
    slots: Any = None,
    full_length: Any = False,
    physics: Any = "auto",
    cluster: Any = None,
    queue: Any = "each",
) -> dict[str, Any]:
    """The engine's options as ``run_region`` takes them, and ``queue``, each checked
    (ParameterError, a ValueError, naming the argument and what it accepts). ``queue``:
    "each", every subject's map its own engine run (the bytes of ``sweep --subject``); "one",
    every subject's map through one engine queue (``runs.population``; MJX path, no
    cluster); "auto" is resolved before (:func:`resolved_queue`)."""
    if not isinstance(physics, str) or physics not in PATHS:
        raise ParameterError(
            f"physics = {physics!r}: must be one of {', '.join(repr(p) for p in PATHS)}"
        )
    check_queue(queue, physics, cluster)
    if not isinstance(full_length, bool) and type(full_length).__name__ != "bool_":
        raise ParameterError(f"full_length = {full_length!r}: must be True or False")
    engine = {
        "slots": size_value(slots, "slots"),
        "full_length": bool(full_length),
        "physics": physics,
        "queue": queue,
    }
    if cluster is not None:
        engine["cluster"] = cluster
    return engine


def run_options(engine: dict[str, Any]) -> dict[str, Any]:
    """The engine options ``run_region`` and ``run_table_folder`` take (all but ``queue``)."""
    return {k: v for k, v in engine.items() if k != "queue"}


def plan_cohort(
    out: str | os.PathLike[str],
    members: Sequence[Member],
    base: Config,
    forces: Any,
    durations: Any,
    *,
    table_forces: Any = None,
    batched: bool = True,
    say: Callable[[str], None] | None = None,
    **engine: Any,
) -> CohortPlan:
    """Check a cohort before anything is written or locked: the ids, the grids, the engine's
    options (:func:`check_engine`), the subjects' configurations (``Subject.config(base)``,
    the durations on its physics steps, and with ``batched`` everything the batched closed
    loop refuses: ``runs.folders.check_batched``; the base configuration too, whose map the
    cohort also runs) and a folder ``out`` that holds another cohort's results.
    ParameterError (exit code 2) for the first problem, naming it.

    A cohort of at most :data:`CHECKED_FIRST` subjects has every subject checked here; a
    larger one its :func:`representatives` (each sex's extremes of every body value), and
    every subject again when its map's queue starts (``runs.population.run_maps``), so its
    first scenario does not wait for the last subject's check (0.05-0.1 s each)."""
    members = tuple(members)
    check_ids(members)
    out = Path(out)
    engine["queue"] = resolved_queue(
        out, engine.get("queue", "auto"), engine.get("physics", "auto"), engine.get("cluster")
    )
    engine = check_engine(**engine)
    forces = grid_values(forces, "forces")
    tables = None if table_forces is None else grid_values(table_forces, "table forces")
    grids = [(forces, "forces")] + ([] if tables is None else [(tables, "table forces")])
    for values, name in grids:
        check_float32_grid(values, name)
    durations = duration_values(durations, base)  # a subject changes no scenario value
    checked = members if len(members) <= CHECKED_FIRST else representatives(members)
    if batched and len(checked) > SMALL_COHORT and say is not None:
        say(f"cohort: checking {len(checked)} of the {len(members)} subjects' configurations")
    for member in checked:
        try:
            config = member.subject.config(base)
            if batched:
                check_batched(config, *grids, (durations, "durations"))
        except ParameterError as exc:
            raise ParameterError(f"subject {member.id!r}: {exc}") from None
    if batched:  # the base map (the reference boundary) runs on the same engine
        try:
            check_batched(base, (forces, "forces"), (durations, "durations"))
        except ParameterError as exc:
            raise ParameterError(
                f"the base configuration (its map is the probability figure's reference): {exc}"
            ) from None
    if out.exists() and not out.is_dir():
        raise ParameterError(f"--out {out}: is a file, not a folder")
    recorded = _record(members, base, forces, durations, tables)
    open_manifest(out, recorded, base)
    return CohortPlan(out, members, base, forces, durations, tables, engine, recorded)


def representatives(members: Sequence[Member]) -> list[Member]:
    """The subjects whose configurations bound the others': per sex, the first one with the
    least and the greatest height, mass, body mass index, ankle and hip strength and age
    (the configuration is a formula of these: ``Subject.config``), in the members' order."""
    picked: set[int] = set()
    for sex in sorted({m.subject.sex for m in members}):
        same = [i for i, m in enumerate(members) if m.subject.sex == sex]
        for value in _BOUNDING:
            known = [i for i in same if value(members[i].subject) is not None]
            if known:
                picked.add(min(known, key=lambda i: value(members[i].subject)))
                picked.add(max(known, key=lambda i: value(members[i].subject)))
    return [members[i] for i in sorted(picked)]


def checked_first(count: int) -> int:
    """How many of ``count`` subjects :func:`plan_cohort` checks before the folder is made: all
    up to :data:`CHECKED_FIRST`, else at most :func:`representatives`' number."""
    return count if count <= CHECKED_FIRST else min(count, 2 * 2 * len(_BOUNDING))


_BOUNDING: tuple[Callable[[Any], Any], ...] = (
    lambda s: s.height,
    lambda s: s.mass,
    lambda s: s.mass / s.height**2,
    lambda s: s.ankle_strength,
    lambda s: s.hip_strength,
    lambda s: s.age,
)


def resolved_queue(out: Path, queue: Any, physics: Any, cluster: Any) -> Any:
    """``queue`` "auto" (the default) resolved: the queue the maps in ``out`` were started
    with (a folder refuses to be resumed under the other: its results differ by float rounding),
    else "one" on the MJX path without a cluster (one engine queue: docs/cohorts.md,
    "Cohorts", has its speed), else "each". Anything else is returned as given (checked by
    :func:`check_engine`)."""
    if not isinstance(queue, str) or queue != "auto":
        return queue
    if out.is_dir():
        for manifest in [*sorted((out / SUBJECTS).glob(f"*/{MANIFEST}")), out / BASE / MANIFEST]:
            try:
                engine = json.loads(manifest.read_text())["region"]["engine"]
                return str(engine.get("queue", "each"))
            except (OSError, ValueError, KeyError, TypeError, AttributeError):
                continue  # no map started there: nothing to resume
    return "one" if physics in ("auto", "mjx") and cluster is None else "each"


def subject_numbers(
    member: Member, folder: Path, region: pd.DataFrame | None = None
) -> dict[str, Any]:
    """The cohort.csv row of a finished subject's folder (``region``: its map, when read)."""
    region = pd.read_parquet(folder / REGION) if region is None else region
    table = pd.read_csv(folder / TABLE) if (folder / TABLE).exists() else None
    return {**member.record(), **numbers(region, table)}


def summary(frame: pd.DataFrame) -> pd.DataFrame:
    """Mean, SD (n - 1; NaN for one subject), 5/50/95th percentiles of every numeric column."""
    numeric = frame.drop(columns=["id", "sex"]).select_dtypes("number")
    rows = {
        "mean": numeric.mean(),
        "sd": numeric.std(ddof=1),
        "p5": numeric.quantile(0.05),
        "p50": numeric.quantile(0.5),
        "p95": numeric.quantile(0.95),
    }
    out = pd.DataFrame(rows).T
    out.insert(0, "statistic", list(rows))
    return out.reset_index(drop=True)


def run_cohort(
    out: str | Path,
    members: Sequence[Member],
    base: Config,
    forces: Any,
    durations: Any,
    *,
    table_forces: Any = None,
    run_batches: Callable[[Config], Any] | None = None,
    progress: bool = False,
    say: Callable[[str], None] | None = print,
    **engine: Any,
) -> pd.DataFrame:
    """Every subject's region map (and table, with ``table_forces``) in
    ``out/subjects/<id>/`` and the base configuration's map in ``out/base/``, then
    cohort.csv, cohort_summary.csv, the probability map's tables and the figures in ``out``;
    returns cohort.csv's frame, the probability map's tables in its ``attrs``
    (:func:`write_outputs`). ``run_batches``: a batch function per configuration (tests);
    ``engine``: ``slots``, ``full_length``, ``physics``, ``cluster`` for ``run_region``.
    Everything is checked before anything is written (:func:`plan_cohort`)."""
    plan = plan_cohort(
        out,
        members,
        base,
        forces,
        durations,
        table_forces=table_forces,
        batched=run_batches is None,
        say=say,
        **engine,
    )
    return run_plan(plan, run_batches=run_batches, progress=progress, say=say)


def run_plan(
    plan: CohortPlan,
    *,
    run_batches: Callable[[Config], Any] | None = None,
    progress: bool = False,
    say: Callable[[str], None] | None = print,
) -> pd.DataFrame:
    """Run a checked cohort (:func:`plan_cohort`; :func:`run_cohort` says what it writes)."""
    say = say or (lambda _msg: None)
    out, members, forces, durations = plan.out, plan.members, plan.forces, plan.durations
    out.mkdir(parents=True, exist_ok=True)
    manifest = open_manifest(out, plan.record(), plan.base, say)
    write_text(json.dumps(with_run(manifest), indent=2) + "\n", out / MANIFEST)
    cells = forces.size * durations.size
    folders = {m.id: out / SUBJECTS / m.id for m in members}
    done = sum((folders[m.id] / REGION).exists() for m in members)
    base_done = (out / BASE / REGION).exists()
    say(
        f"cohort: {len(members)} subjects x {cells} cells and the base body's map ({done} "
        f"subjects already done); output {out}"
    )
    say(f"cohort: {probability.interval_text(len(members))}")
    bar = progress_bar(
        (len(members) + 1) * cells, (done + base_done) * cells, progress, desc="cohort"
    )
    try:
        if run_batches is None and one_queue(plan):
            _run_queued(plan, folders, say, bar)  # the base body's map too
        else:
            for member in members:
                finished = (folders[member.id] / REGION).exists()
                try:  # a large cohort's subject is checked here (plan_cohort)
                    _run_subject(
                        member,
                        folders[member.id],
                        plan.config(member),
                        forces,
                        durations,
                        plan.tables,
                        run_batches=run_batches,
                        say=say,
                        engine=run_options(plan.engine),
                    )
                except ParameterError as exc:
                    raise ParameterError(f"subject {member.id!r}: {exc}") from None
                if not finished:
                    bar.update(cells)
            say(f"cohort: the base configuration's body (the reference boundary) -> {out / BASE}")
            run_region(
                out / BASE,
                plan.base,
                Grid.of(forces, durations, plan.base),
                progress=False,
                run_batch=run_batches(plan.base) if run_batches is not None else None,
                **run_options(plan.engine),
            )
            if not base_done:
                bar.update(cells)
    finally:
        bar.close()
    return write_outputs(out, members, folders, say, base_label(plan.base))


def one_queue(plan: CohortPlan) -> bool:
    """Whether the subjects' maps run through one engine queue (``runs.population``; asked with
    queue 'one', which :func:`check_engine` allows on the MJX path without a cluster only: the
    C path steps one MuJoCo model per run, a cluster spreads one map's chunks)."""
    return plan.engine["queue"] == "one" and bool(plan.members)


def _run_queued(
    plan: CohortPlan, folders: dict[str, Path], say: Callable[[str], None], bar: Any
) -> None:
    """The unfinished subjects' maps and the base body's through one engine queue
    (``runs.population.run_maps``), each then written to its folder as a sweep of that body
    writes it; the tables (``table_forces``) subject by subject after."""
    members = list(plan.members)
    say(
        f"cohort: the base configuration's body (the reference boundary) -> "
        f"{plan.out / BASE}, in the same queue"
    )
    run_maps(
        [(folders[m.id], functools.partial(plan.config, m)) for m in members]
        + [(plan.out / BASE, plan.base)],
        plan.forces,
        plan.durations,
        slots=plan.engine["slots"],
        full_length=plan.engine["full_length"],
        update=bar.update,
        say=lambda text: say(f"cohort: {text}"),
        label=lambda folder: (
            "the base configuration" if folder == plan.out / BASE else f"subject {folder.name!r}"
        ),
    )
    if plan.tables is not None:
        for member in members:
            run_table_folder(
                folders[member.id],
                plan.config(member),
                plan.tables,
                progress=False,
                **run_options(plan.engine),
            )


def _run_subject(
    member: Member,
    folder: Path,
    config: Config,
    forces: np.ndarray,
    durations: np.ndarray,
    tables: np.ndarray | None,
    *,
    run_batches: Callable[[Config], Any] | None,
    say: Callable[[str], None],
    engine: dict[str, Any],
) -> None:
    say(f"cohort: subject {member.id} ({member.subject.describe()}) -> {folder}")
    batch = run_batches(config) if run_batches is not None else None
    run_region(
        folder,
        config,
        Grid.of(forces, durations, config),
        run_batch=batch,
        progress=False,
        **engine,
    )
    if tables is not None:
        run_table_folder(folder, config, tables, run_batch=batch, progress=False, **engine)


def base_label(base: Config) -> str:
    """How the probability figure names the base configuration's body."""
    return "the study's body" if base.body == Config().body else "the base configuration's body"


def write_outputs(
    out: Path,
    members: Sequence[Member],
    folders: dict[str, Path],
    say: Callable[[str], None],
    label: str = "the base body",
) -> pd.DataFrame:
    """cohort.csv, cohort_summary.csv, the probability map's tables and the figures from the
    subjects' folders and the base map's (``out/base``). Returns cohort.csv's frame with, in
    its ``attrs``: ``probability`` (cohort_probability.csv's frame), ``probability_boundaries``
    (cohort_probability_boundaries.csv's) and ``half_width`` (the interval's worst-case
    half-width over these subjects, ``studies.probability.half_width``). ``label``: the base
    body's name in the probability figure (:func:`base_label`)."""
    rows, tally = [], probability.Tally()
    for m in members:  # one map at a time: the host keeps the rows and the counts
        region = pd.read_parquet(folders[m.id] / REGION)
        rows.append(subject_numbers(m, folders[m.id], region))
        tally.add(region)
    frame = pd.DataFrame(rows)
    write_csv(frame, out / COHORT_CSV)
    write_csv(summary(frame), out / SUMMARY_CSV)
    base = pd.read_parquet(out / BASE / REGION)
    cells = tally.cells()
    lines = probability.boundaries(cells, base)
    write_csv(cells, out / PROBABILITY_CSV)
    write_csv(lines, out / BOUNDARIES_CSV)
    drawn = frame["id"] if len(frame) <= SMALL_COHORT else chosen(frame)
    figures = draw(out, frame, {i: pd.read_parquet(folders[i] / REGION) for i in drawn})
    levels = {p / 100: probability.thresholded(cells, p) for p in probability.LEVELS}
    figures.append(
        cohort_figures.plot_probability(
            cells,
            levels,
            (label, base),
            probability.half_width(len(members)),
            out / "cohort_probability.png",
        )
    )
    say(
        f"wrote {out / COHORT_CSV}, {out / SUMMARY_CSV}, {out / PROBABILITY_CSV}, "
        f"{out / BOUNDARIES_CSV} and " + ", ".join(p.name for p in figures)
    )
    frame.attrs = {
        "probability": cells,
        "probability_boundaries": lines,
        "half_width": probability.half_width(len(members)),
    }
    return frame


def chosen(frame: pd.DataFrame, count: int = CHOSEN) -> list[str]:
    """Up to ``count`` subjects spread over the area's range: the smallest, the largest and
    those at evenly spaced ranks between (the median among them for an odd count)."""
    order = frame.sort_values(["area", "id"], kind="stable")["id"].tolist()
    if len(order) <= count:
        return order
    ranks = np.unique(np.round(np.linspace(0, len(order) - 1, count)).astype(int))
    return [order[r] for r in ranks]


def draw(out: Path, frame: pd.DataFrame, regions: dict[str, pd.DataFrame]) -> list[Path]:
    """The cohort's figures (module docstring). ``regions``: the maps of the subjects drawn
    (:func:`chosen`, or every subject of a cohort of at most :data:`SMALL_COHORT`), in
    cohort.csv's order; every map holds the cohort's whole grid, so theirs give the axes."""
    paths = [cohort_figures.plot_area(frame, out / "cohort_area.png")]
    picks = chosen(frame)
    every = pd.concat(regions.values())
    log = log_durations(np.sort(every["duration"].unique()))
    segments = {i: boundary_segments(regions[i], log) for i in picks}
    paths.append(
        cohort_figures.plot_boundaries(
            segments, frame.set_index("id").loc[picks], every, out / "cohort_boundaries.png"
        )
    )
    if len(frame) <= SMALL_COHORT:
        paths.append(cohort_figures.plot_regions(regions, frame, out / "cohort_regions.png"))
    return paths
