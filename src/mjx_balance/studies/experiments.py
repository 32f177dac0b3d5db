"""Planning and running a report: the study's experiments and the studies, saved as tables.

:func:`run_report` runs, for each convention, the time series (experiment 1), the weight study
(2), the region map (4) and the robustness table (3), then, in the base configuration's
convention, every variant of every study and the study's numbers, and last the robustness
table under every reading of the study (convention x plain/offset-free MPC, sensitivity.py) in
sensitivity/, whose section report/extra.py draws. Each of these is one function
below, given the :class:`ReportRun` that holds what they share. A finished step is not rerun:
the time series and the weight study are recorded in report.json with their parameters
(:func:`run_stage`), and the region maps and tables run into their folders as every caller
runs them (``runs.folders.run_region``, ``run_table_folder``: resumable, under each folder's
lock).
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from ..runtime.version import __version__
from . import catalog
from ..measures.outcomes import SUMMARY_COLUMNS
from ..model.params import CONVENTIONS, Config, ParameterError
from ..model.config_files import dumps_config, with_convention
from ..runs import (
    DEFAULT_SWEEP,
    STUDY_TABLE_FORCES,
    SweepDefinition,
    default_chunk_size,
    parse_grid,
)
from ..runs.folders import batch_function, run_region, run_table_folder
from ..runs.grid import Grid
from ..runs.progress import wanted
from ..store.files import REGION, TABLE, copy_folder, write_csv, write_parquet, write_text
from ..reference.loop import simulate_scenario
from ..reference.loop import simulate_many
from . import sensitivity
from ..runs import cluster as cluster_mod

REPORT_JSON = "report.json"
CONFIG_TOML = "config.toml"
WEIGHTS_RECOVERING = "weights_recovering.csv"  # the weight study on a push that recovers
# Q = s I4: the study's Fig. 14 (docs/study.md, "The study's figures and tables, one by one")
Q_SCALES = (1e3, 1e4, 1e5, 1e6, 1e7)
R_SCALES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)  # R = s diag(1000, 1)
REFERENCE_CHUNK = 8  # scenarios per sweep chunk with the reference batch function


@dataclass(frozen=True)
class Plan:
    """Sizes of one report run. Grids are runs.grid.parse_grid strings; None: the study TOMLs'."""

    name: str
    backend: str = "mjx"
    t_end: float | None = None  # override scenario.t_end
    osqp_max_iter: int | None = None  # override controller.osqp_max_iter (reference solver)
    osqp_eps: float | None = None  # override controller.osqp_eps
    timeseries_forces: tuple[float, ...] = (0, 20, 50, 80, 100, 120)
    push_duration: float = 0.1
    weight_force: float = 100.0  # the study's weight experiment (Figs 14-15)
    # The same comparison on a push that recovers under every weight setting: the largest of the
    # study's time-series forces that does (scalar reference, paper convention: 80 N falls
    # under Q = 1e4..1e7 and R = 1e-5..1e-8), so that its energies are recovery costs.
    weight_recovering_force: float = 50.0
    q_scales: tuple[float, ...] = Q_SCALES
    r_scales: tuple[float, ...] = R_SCALES
    table_forces: tuple[float, ...] = STUDY_TABLE_FORCES
    region_forces: str = DEFAULT_SWEEP["forces"]
    region_durations: str = DEFAULT_SWEEP["durations"]
    study_forces: str | None = None
    study_durations: str | None = None
    backward_forces: str | None = None
    sustained: bool = True  # the tables' sustained-push limit (tiny: not measured)


PLANS = {
    # For tests and a first look: 2 s scenarios, few forces, scalar reference loop.
    "tiny": Plan(
        "tiny",
        backend="reference",
        t_end=2.0,
        osqp_max_iter=200,
        osqp_eps=1e-6,
        timeseries_forces=(0, 50, 120),
        q_scales=(1e3, 1e5, 1e7),
        r_scales=(1e-4, 1e-6, 1e-8),
        table_forces=(20, 100),
        region_forces="0:120:60",
        region_durations="0.05,0.2",
        study_forces="0:120:60",
        study_durations="0.05,0.2",
        backward_forces="-120:120:60",
        sustained=False,
    ),
    # The study's experiments (table forces, six time series), coarse region maps.
    "default": Plan("default"),
    # The dense region maps of sweeps/region_dense_*.toml (meant for a GPU).
    "dense": Plan("dense", region_forces="0:150:2", region_durations="0.05:10:0.05"),
}


def plan_config(config: Config, plan: Plan) -> Config:
    """The base configuration with the plan's overrides."""
    scenario = {"t_end": plan.t_end} if plan.t_end is not None else {}
    controller = {
        key: getattr(plan, key)
        for key in ("osqp_max_iter", "osqp_eps")
        if getattr(plan, key) is not None
    }
    return config.replace(scenario=scenario, controller=controller)


def weight_settings(plan: Plan) -> list[tuple[str, float, dict[str, tuple[float, ...]]]]:
    """(which, scale, controller overrides) of the weight study."""
    out: list[tuple[str, float, dict[str, tuple[float, ...]]]]
    out = [("Q", s, {"q_diag": (s,) * 4}) for s in plan.q_scales]
    out += [("R", s, {"r_diag": (1000.0 * s, s)}) for s in plan.r_scales]
    return out


def selected_studies(names: str | None) -> list[catalog.Study]:
    """The studies named in a comma list; None or 'all': every study, 'none': none."""
    if names is None or names.strip().lower() == "all":
        return list(catalog.STUDIES)
    if names.strip().lower() == "none":
        return []
    return [catalog.study(n.strip()) for n in names.split(",") if n.strip()]


# ---------------------------------------------------------------------------------------------
# Batch functions


def sweep_chunk_size(config: Config, backend: str, n_cells: int) -> int:
    """Scenarios per sweep chunk: REFERENCE_CHUNK for the reference loop, else from the
    memory budget (runs.chunks.default_chunk_size)."""
    return REFERENCE_CHUNK if backend == "reference" else default_chunk_size(config, n_cells)


class Batches:
    """One batch function per configuration (an MJX runner compiles once per configuration and
    batch size), and the region maps already computed, by (configuration, grid)."""

    def __init__(self, backend: str, cluster: Any = None, physics: str = "auto"):
        self.backend = backend
        self.physics = physics
        self.cluster = cluster  # the region maps' chunks on a Dask cluster (a Client), or None
        self._runs: dict[Config, Any] = {}
        self._regions: dict[tuple, Path] = {}

    def __call__(self, config: Config):
        if config not in self._runs:
            self._runs[config] = batch_function(config, backend=self.backend, physics=self.physics)
        return self._runs[config]

    def sweep(
        self,
        folder: Path,
        config: Config,
        forces: np.ndarray,
        durations: np.ndarray,
        chunk: int,
        progress: bool | None,
    ) -> None:
        """``runs.folders.run_region``, or a copy of an identical sweep made earlier in this
        report (``progress``: as :func:`run_report`'s)."""
        key = (config, tuple(forces), tuple(durations))
        done = self._regions.get(key)
        if done is not None and not (folder / REGION).exists():
            copy_folder(done, folder, REGION)
        run_region(
            folder,
            config,
            Grid.of(forces, durations, config),
            run_batch=self(config),
            chunk=chunk,
            progress=progress,
            say=None if progress is False else print,
            cluster=self.cluster,
        )
        self._regions.setdefault(key, folder)


# ---------------------------------------------------------------------------------------------
# The record (report.json) and the stages


def write_json(path: Path, data: dict) -> None:
    """Write ``data`` as JSON atomically (a reader never sees half a file)."""
    write_text(json.dumps(data, indent=2, default=float) + "\n", path)


def read_record(path: Path, *, required: bool = True) -> dict:
    """A report's report.json as a dict: ParameterError (one line naming the file and what to
    do) when it is missing (if ``required``), unreadable, not a JSON object, or lacks the keys
    a finished stage writes (config, conventions)."""
    path = Path(path)
    if not path.exists():
        if required:
            raise ParameterError(f"{path} not found (run the report first)")
        return {}
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ParameterError(
            f"{path} is damaged ({type(exc).__name__}); delete it to rerun the "
            "report in that folder, or use another --out folder"
        ) from None
    problem = None
    if not isinstance(record, dict):
        problem = f"holds a {type(record).__name__}, not an object"
    elif required and not isinstance(record.get("config"), dict):
        problem = "has no configuration"
    elif required and not isinstance(record.get("conventions"), list):
        problem = "has no list of conventions"
    if problem:
        raise ParameterError(
            f"{path} {problem}; delete it to rerun the report in that folder, "
            "or use another --out folder"
        )
    return record


def open_record(
    out: Path, config: Config, plan: Plan, backend: str, conventions: tuple[str, ...]
) -> dict:
    """report.json of ``out`` for this run (the stages already done kept), written with the
    base configuration (config.toml). Raises ParameterError if ``out`` holds a report made with
    another configuration."""
    path = out / REPORT_JSON
    record = read_record(path, required=False)
    if record.get("config") not in (None, config.to_dict()):
        raise ParameterError(
            f"{out} holds a report made with another configuration; use another --out folder"
        )
    record.update(
        {
            "package": "mjx_balance",
            "version": __version__,
            "plan": dataclasses.asdict(plan),
            "backend": backend,
            "config": config.to_dict(),
            "conventions": list(conventions),
            "studies": [],
        }
    )
    write_text(dumps_config(config), out / CONFIG_TOML)
    write_json(path, record)
    return record


class StageLog:
    """Numbered progress lines, ``[report i/total, elapsed] text`` (nothing when quiet)."""

    def __init__(self, total: int, quiet: bool = False):
        self.total, self.done, self.quiet = total, 0, quiet
        self.start = time.perf_counter()

    def stage(self, text: str) -> None:
        self.done += 1
        if not self.quiet:
            elapsed = time.perf_counter() - self.start
            print(f"[report {self.done}/{self.total}, {elapsed:.0f} s] {text}", flush=True)


@dataclass
class ReportRun:
    """What the steps of one report run share."""

    out: Path
    config: Config  # the base configuration with the plan's overrides
    plan: Plan
    backend: str
    record: dict  # report.json, rewritten after every stage
    log: StageLog
    batches: Batches
    region_forces: np.ndarray  # the grid of the experiments' region maps
    region_durations: np.ndarray
    chunk: int  # one batch size for every sweep and table: the MJX runner compiles once
    sweeps: Path | None  # folder of the study sweep definitions (None: the repository's)
    progress: bool | None  # bars: None where someone watches, True always, False never

    @property
    def sweep_log(self) -> Callable[[str], None] | None:
        return None if self.progress is False else print  # -q: no maps' lines

    def save_record(self) -> None:
        write_json(self.out / REPORT_JSON, self.record)


def run_stage(
    run: ReportRun, key: str, params: dict, files: list[Path], work: Callable[[], None]
) -> None:
    """Run ``work`` unless report.json records stage ``key`` done with the same parameters
    and its ``files`` exist; then record it with its time."""
    stages = run.record.setdefault("stages", {})
    done = stages.get(key)
    if done and done.get("params") == params and all(f.exists() for f in files):
        return
    start = time.perf_counter()
    work()
    stages[key] = {"params": params, "seconds": round(time.perf_counter() - start, 2)}
    run.save_record()


# ---------------------------------------------------------------------------------------------
# The study's experiments (docs/study.md, "The study's figures and tables, one by one"), one
# convention at a time


def timeseries_stage(run: ReportRun, convention: str) -> None:
    """Experiment 1: summary.csv and timeseries.parquet of the time-series pushes."""
    plan, folder = run.plan, run.out / convention
    cfg = with_convention(run.config, convention)

    def work() -> None:
        summary, series = simulate_many(
            cfg,
            list(plan.timeseries_forces),
            [plan.push_duration],
            progress=wanted(run.progress),
        )
        write_csv(summary, folder / "summary.csv", units=False)
        write_parquet(series, folder / "timeseries.parquet")

    run.log.stage(
        f"{convention}: time series, F = {plan.timeseries_forces} N, "
        f"T = {plan.push_duration} s (reference loop)"
    )
    run_stage(
        run,
        f"{convention}/timeseries",
        {"forces": list(plan.timeseries_forces), "duration": plan.push_duration},
        [folder / "summary.csv", folder / "timeseries.parquet"],
        work,
    )


def run_weights(config: Config, plan: Plan, force: float | None = None) -> pd.DataFrame:
    """The weight study's summary rows: one per setting of :func:`weight_settings`, the push
    of ``force`` (default ``plan.weight_force``) for ``plan.push_duration`` through the
    reference loop."""
    rows = []
    force = plan.weight_force if force is None else force
    for which, scale, overrides in weight_settings(plan):
        summary, _ = simulate_scenario(
            config.replace(controller=overrides), force, plan.push_duration, record=False
        )
        rows.append({"weight": which, "scale": scale, **summary})
    return pd.DataFrame(rows, columns=["weight", "scale", *SUMMARY_COLUMNS])


def weights_stage(run: ReportRun, convention: str) -> None:
    """Experiment 2: weights.csv (the study's push) and weights_recovering.csv (a push that
    recovers under every setting, so that its energies compare recovery costs)."""
    plan, folder = run.plan, run.out / convention
    cfg = with_convention(run.config, convention)
    run.log.stage(f"{convention}: weight study at F = {plan.weight_force} N (reference loop)")
    run_stage(
        run,
        f"{convention}/weights",
        {"force": plan.weight_force, "q": list(plan.q_scales), "r": list(plan.r_scales)},
        [folder / "weights.csv"],
        lambda: write_csv(run_weights(cfg, plan), folder / "weights.csv", units=False),
    )
    force = plan.weight_recovering_force
    run.log.stage(
        f"{convention}: weight study at F = {force} N, a push every setting should "
        "recover (reference loop)"
    )
    run_stage(
        run,
        f"{convention}/weights_recovering",
        {"force": force, "q": list(plan.q_scales), "r": list(plan.r_scales)},
        [folder / WEIGHTS_RECOVERING],
        lambda: write_csv(run_weights(cfg, plan, force), folder / WEIGHTS_RECOVERING, units=False),
    )


def region_stage(run: ReportRun, convention: str) -> None:
    """Experiment 4: the region map, region/region.parquet (a sweep folder)."""
    forces, durations = run.region_forces, run.region_durations
    run.log.stage(
        f"{convention}: region map, {forces.size} x {durations.size} cells ({run.backend})"
    )
    run.batches.sweep(
        run.out / convention / "region",
        with_convention(run.config, convention),
        forces,
        durations,
        run.chunk,
        run.progress,
    )


def table_stage(run: ReportRun, convention: str) -> None:
    """Experiment 3: the max acting time per force, table/table.csv (a sweep folder)."""
    cfg = with_convention(run.config, convention)
    run.log.stage(
        f"{convention}: robustness table, {len(run.plan.table_forces)} forces ({run.backend})"
    )
    table_folder(run, run.out / convention / "table", cfg)


def table_folder(run: ReportRun, folder: Path, cfg: Config) -> None:
    """The plan's table of ``cfg`` into ``folder`` (``runs.folders.run_table_folder``; the
    reference loop bisects, the engine takes the report's chunk per call)."""
    run_table_folder(
        folder,
        cfg,
        list(run.plan.table_forces),
        run_batch=run.batches(cfg),
        batch=None if run.backend == "reference" else run.chunk,
        progress=run.progress,
        say=run.sweep_log,
        sustained=run.plan.sustained,
    )


def run_experiments(run: ReportRun, convention: str) -> None:
    """The four experiments in one convention, into ``out/<convention>/``."""
    (run.out / convention).mkdir(exist_ok=True)
    timeseries_stage(run, convention)
    weights_stage(run, convention)
    region_stage(run, convention)
    table_stage(run, convention)


# ---------------------------------------------------------------------------------------------
# The studies


def study_grid(
    plan: Plan, study: catalog.Study, definition: SweepDefinition
) -> tuple[np.ndarray, np.ndarray]:
    """The (forces, durations) of a study variant: the plan's grid, else the definition's."""
    forces = (plan.backward_forces if study.signed else plan.study_forces) or definition.forces
    durations = plan.study_durations or definition.durations
    return parse_grid(forces, "study forces"), parse_grid(durations, "study durations")


def run_variant(run: ReportRun, study: catalog.Study, variant: catalog.Variant) -> dict:
    """One study variant's region map, studies/<study>/<variant>/region.parquet; returns its
    entry in report.json."""
    definition = catalog.variant_definition(study, variant, run.config, run.sweeps)
    forces, durations = study_grid(run.plan, study, definition)
    run.log.stage(f"study {study.key}: {variant.label}, {forces.size} x {durations.size} cells")
    run.batches.sweep(
        run.out / "studies" / study.key / variant.key,
        definition.config,
        forces,
        durations,
        run.chunk,
        run.progress,
    )
    return {
        "key": variant.key,
        "label": variant.label,
        "file": variant.file,
        "config": definition.config.to_dict(),
    }


def study_numbers(study: catalog.Study, folder: Path, variants: list[dict]) -> pd.DataFrame:
    """The study's numbers from its saved maps: the halves of the signed map, or every
    variant against the first (catalog.signed_halves, catalog.compare)."""
    regions = {v["key"]: pd.read_parquet(folder / v["key"] / "region.parquet") for v in variants}
    if study.signed:
        return catalog.signed_halves(next(iter(regions.values())))
    return catalog.compare(regions, {v["key"]: v["label"] for v in variants})


def run_study(run: ReportRun, study: catalog.Study) -> None:
    """Every variant's map, then studies/<study>/numbers.csv; recorded in report.json."""
    entry: dict[str, Any]
    entry = {"key": study.key, "variants": [run_variant(run, study, v) for v in study.variants]}
    folder = run.out / "studies" / study.key
    write_csv(study_numbers(study, folder, entry["variants"]), folder / "numbers.csv", units=False)
    run.record["studies"].append(entry)
    run.save_record()


# ---------------------------------------------------------------------------------------------
# The sensitivity of the robustness table to the reading of the study (sensitivity.py)


def sensitivity_readings(config: Config, conventions: tuple[str, ...]) -> dict[str, Config]:
    """The readings the report runs: those of its conventions (plain and offset-free MPC) that
    the base configuration admits (the offset-free MPC refuses a controller delay)."""
    configs = {}
    for key in sensitivity.READINGS:
        if sensitivity.reading_convention(key) in conventions:
            try:
                configs.update(sensitivity.reading_configs(config, [key]))
            except ParameterError:
                pass
    return configs


def run_sensitivity_stage(run: ReportRun) -> None:
    """The robustness table (the plan's table forces and sustained setting) under every reading
    of :func:`sensitivity_readings`, each in sensitivity/<reading>/ (a table folder), then
    sensitivity/sensitivity.csv, .png and .txt. A reading whose configuration is an
    experiment's reuses that table (copied, then resumed: nothing is recomputed)."""
    folder = run.out / sensitivity.REPORT_DIR
    configs = sensitivity_readings(run.config, tuple(run.record["conventions"]))
    run.log.stage(
        f"sensitivity: the robustness table under {len(configs)} readings "
        f"({', '.join(configs)}), {len(run.plan.table_forces)} forces"
    )
    if not configs:
        return
    tables = {}
    for key, cfg in configs.items():
        convention = sensitivity.reading_convention(key)
        done = run.out / convention / "table"
        if (
            cfg == with_convention(run.config, convention)
            and (done / TABLE).exists()
            and not (folder / key / TABLE).exists()
        ):
            copy_folder(done, folder / key, TABLE)
        table_folder(run, folder / key, cfg)
        tables[key] = pd.read_csv(folder / key / TABLE)
    sensitivity.write_sensitivity(folder, tables, say=run.sweep_log or (lambda _m: None))


# ---------------------------------------------------------------------------------------------
# The whole run


def start_report(
    out: Path,
    config: Config,
    plan: Plan,
    *,
    backend: str,
    study_list: list[catalog.Study],
    conventions: tuple[str, ...],
    sweeps: Path | None,
    progress: bool | None,
    physics: str = "auto",
) -> ReportRun:
    """Open report.json in ``out`` and set up what the steps share (``config``: the base
    configuration with the plan's overrides)."""
    out.mkdir(parents=True, exist_ok=True)
    record = open_record(out, config, plan, backend, conventions)
    n_variants = sum(len(s.variants) for s in study_list)
    log = StageLog(5 * len(conventions) + n_variants + 1, progress is False)  # + 1: sensitivity
    forces = parse_grid(plan.region_forces, "region forces")
    durations = parse_grid(plan.region_durations, "region durations")
    return ReportRun(
        out=out,
        config=config,
        plan=plan,
        backend=backend,
        record=record,
        log=log,
        batches=Batches(backend, physics=physics),
        region_forces=forces,
        region_durations=durations,
        chunk=sweep_chunk_size(config, backend, forces.size * durations.size),
        sweeps=sweeps,
        progress=progress,
    )


def run_report(
    out: str | Path,
    config: Config = Config(),
    plan: Plan = PLANS["default"],
    *,
    backend: str | None = None,
    study_list: list[catalog.Study] | None = None,
    conventions: tuple[str, ...] = CONVENTIONS,
    sweeps: Path | None = None,
    progress: bool | None = None,
    cluster: Any = None,
    physics: str = "auto",
) -> dict:
    """Run everything and save the tables in ``out``; returns the report record (report.json).

    config: the base configuration (its convention is the studies'; the experiments run every
    convention in ``conventions``). backend: the batch function of the region maps and the
    table (default: the plan's). study_list: default every study. cluster: compute the region
    maps' chunks on a Dask cluster (a spec as ``sweep --cluster`` takes, or a Client; one
    connection serves every map; the tables and time series run here). physics: the
    batched backend's physics path (auto, mjx or c). progress: the bars (as every runner's,
    runs.progress.wanted: None where someone watches, True always, False never); False also
    drops the numbered stage lines and the maps' lines (the command's ``-q``).
    """
    study_list = list(catalog.STUDIES) if study_list is None else study_list
    run = start_report(
        Path(out),
        plan_config(config, plan),
        plan,
        backend=backend or plan.backend,
        study_list=study_list,
        conventions=conventions,
        sweeps=sweeps,
        progress=progress,
        physics=physics,
    )
    client = local = None
    if cluster is not None:
        client, local = cluster_mod.connect(cluster, run.sweep_log or (lambda _m: None))
        run.batches.cluster = client
    try:
        for convention in conventions:
            run_experiments(run, convention)
        for study in study_list:
            run_study(run, study)
        run_sensitivity_stage(run)
    finally:
        if client is not None:
            cluster_mod.close(client, local, owned=client is not cluster)
    run.record["seconds"] = round(time.perf_counter() - run.log.start, 1)
    run.save_record()
    return run.record
