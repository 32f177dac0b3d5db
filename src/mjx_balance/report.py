"""The study's experiments and the studies beyond it, as saved tables and one HTML report.

``mjx-balance report --out DIR`` runs, for both conventions, every experiment of SPEC §6 and then
the studies of ``studies.py``, saving each result table in DIR before any figure is drawn:

    DIR/report.json                    what was run: plan, base configuration, studies, timings
    DIR/config.toml                    the base configuration
    DIR/<convention>/summary.csv       experiment 1: one summary row per force (T = 0.1 s)
    DIR/<convention>/timeseries.parquet            and the long time series (reference loop)
    DIR/<convention>/weights.csv       experiment 2: summary rows of the Q and R settings
    DIR/<convention>/table/table.csv   experiment 3: max acting time (sweep.run_table folder)
    DIR/<convention>/region/region.parquet   experiment 4: region map (sweep.run_sweep folder)
    DIR/studies/<study>/<variant>/region.parquet   one region map per study variant
    DIR/studies/<study>/numbers.csv    areas and changes (studies.compare)
    DIR/figures/*.png, DIR/report.html figures and the report, drawn from the saved tables

``build_report(DIR)`` (``--html-only``) redraws figures and HTML from the saved tables alone. The
time series and the weight study use the scalar reference loop (reference.py); the table and the
region maps use a batch function: the MJX rollout (``--backend mjx``, default) or the reference
loop run scenario by scenario (``--backend reference``, what ``--scale tiny`` uses).
A finished stage is not rerun (sweeps resume chunk by chunk; see sweep.py).
"""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from . import __version__, studies
from .metrics import SUMMARY_COLUMNS
from .params import CONVENTIONS, Config, ParameterError, config_from_dict, save_config
from .sweep import (DEFAULT_SWEEP, STUDY_TABLE_FORCES, LazyBatch, default_chunk_size,
                    parse_grid, run_sweep, run_table)

REPORT_JSON = "report.json"
HTML = "report.html"
Q_SCALES = (1e3, 1e4, 1e5, 1e6, 1e7)  # Q = s I4 (SPEC §6.2)
R_SCALES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)  # R = s diag(1000, 1)


@dataclass(frozen=True)
class Plan:
    """Sizes of one report run. Grids are sweep.parse_grid strings; None: the study TOMLs'."""

    name: str
    backend: str = "mjx"
    t_end: float | None = None  # override scenario.t_end
    osqp_max_iter: int | None = None  # override controller.osqp_max_iter (reference solver)
    osqp_eps: float | None = None  # override controller.osqp_eps
    timeseries_forces: tuple[float, ...] = (0, 20, 50, 80, 100, 120)
    push_duration: float = 0.1
    weight_force: float = 100.0
    q_scales: tuple[float, ...] = Q_SCALES
    r_scales: tuple[float, ...] = R_SCALES
    table_forces: tuple[float, ...] = STUDY_TABLE_FORCES
    region_forces: str = DEFAULT_SWEEP["forces"]
    region_durations: str = DEFAULT_SWEEP["durations"]
    study_forces: str | None = None
    study_durations: str | None = None
    backward_forces: str | None = None


PLANS = {
    # For tests and a first look: 2 s scenarios, few forces, scalar reference loop.
    "tiny": Plan("tiny", backend="reference", t_end=2.0, osqp_max_iter=200, osqp_eps=1e-6,
                 timeseries_forces=(0, 50, 120), q_scales=(1e3, 1e5, 1e7),
                 r_scales=(1e-4, 1e-6, 1e-8), table_forces=(20, 100),
                 region_forces="0:120:60", region_durations="0.05,0.2",
                 study_forces="0:120:60", study_durations="0.05,0.2",
                 backward_forces="-120:120:60"),
    # The study's experiments (table forces, six time series), coarse region maps.
    "default": Plan("default"),
    # The dense region maps of sweeps/region_dense_*.toml (meant for a GPU).
    "dense": Plan("dense", region_forces="0:150:2", region_durations="0.05:10:0.05"),
}


# ---------------------------------------------------------------------------------------------
# Batch functions


class ReferenceBatch:
    """A sweep batch function that runs the scalar reference loop scenario by scenario
    (results memoised, so padding and repeated cells cost nothing)."""

    def __init__(self, config: Config):
        self.config = config
        self._done: dict[tuple[float, float], dict[str, Any]] = {}

    def __call__(self, forces: np.ndarray, durations: np.ndarray) -> pd.DataFrame:
        from .reference import simulate_scenario

        rows = []
        for f, d in zip(np.asarray(forces, float), np.asarray(durations, float)):
            key = (round(float(f), 9), round(float(d), 9))
            if key not in self._done:
                self._done[key] = simulate_scenario(self.config, key[0], key[1], record=False)[0]
            rows.append(self._done[key])
        return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)


def batch_function(config: Config, backend: str):
    if backend == "reference":
        return ReferenceBatch(config)
    if backend == "mjx":
        return LazyBatch(config)
    raise ParameterError(f"backend must be 'mjx' or 'reference', got {backend!r}")


class _Batches:
    """One batch function per configuration (an MJX runner compiles once per configuration and
    batch size), and the region maps already computed, by (configuration, grid)."""

    def __init__(self, backend: str):
        self.backend = backend
        self._runs: dict[Config, Any] = {}
        self._regions: dict[tuple, Path] = {}

    def __call__(self, config: Config):
        if config not in self._runs:
            self._runs[config] = batch_function(config, self.backend)
        return self._runs[config]

    def sweep(self, folder: Path, config: Config, forces: np.ndarray, durations: np.ndarray,
              chunk: int, quiet: bool) -> None:
        """run_sweep, or a copy of an identical sweep made earlier in this report."""
        key = (config, tuple(forces), tuple(durations))
        done = self._regions.get(key)
        if done is not None and not (folder / "region.parquet").exists():
            shutil.copytree(done, folder, dirs_exist_ok=True)
        run_sweep(folder, config, forces, durations, run_batch=self(config), chunk_size=chunk,
                  progress=not quiet, log=None if quiet else print)
        self._regions.setdefault(key, folder)


def _chunk(config: Config, backend: str, n_cells: int) -> int:
    return 8 if backend == "reference" else default_chunk_size(config, n_cells)


# ---------------------------------------------------------------------------------------------
# Running the experiments


def plan_config(config: Config, plan: Plan) -> Config:
    """The base configuration with the plan's overrides."""
    scenario = {"t_end": plan.t_end} if plan.t_end is not None else {}
    controller = {key: getattr(plan, key) for key in ("osqp_max_iter", "osqp_eps")
                  if getattr(plan, key) is not None}
    return config.replace(scenario=scenario, controller=controller)


class _Log:
    def __init__(self, total: int, quiet: bool = False):
        self.total, self.done, self.quiet = total, 0, quiet
        self.start = time.perf_counter()

    def stage(self, text: str) -> None:
        self.done += 1
        if not self.quiet:
            elapsed = time.perf_counter() - self.start
            print(f"[report {self.done}/{self.total}, {elapsed:.0f} s] {text}", flush=True)


def _stage(out: Path, record: dict, key: str, params: dict, files: list[Path],
           run: Callable[[], None]) -> None:
    """Run a stage unless report.json records it done with the same parameters."""
    stages = record.setdefault("stages", {})
    done = stages.get(key)
    if done and done.get("params") == params and all(f.exists() for f in files):
        return
    start = time.perf_counter()
    run()
    stages[key] = {"params": params, "seconds": round(time.perf_counter() - start, 2)}
    _write_json(out / REPORT_JSON, record)


def _write_json(path: Path, data: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2, default=float) + "\n")
    tmp.replace(path)


def weight_settings(plan: Plan) -> list[tuple[str, float, dict[str, tuple[float, ...]]]]:
    """(which, scale, controller overrides) of the weight study."""
    out = [("Q", s, {"q_diag": (s,) * 4}) for s in plan.q_scales]
    out += [("R", s, {"r_diag": (1000.0 * s, s)}) for s in plan.r_scales]
    return out


def run_weights(config: Config, plan: Plan) -> pd.DataFrame:
    from .reference import simulate_scenario

    rows = []
    for which, scale, overrides in weight_settings(plan):
        summary, _ = simulate_scenario(config.replace(controller=overrides), plan.weight_force,
                                       plan.push_duration, record=False)
        rows.append({"weight": which, "scale": scale, **summary})
    return pd.DataFrame(rows, columns=["weight", "scale", *SUMMARY_COLUMNS])


def selected_studies(names: str | None) -> list[studies.Study]:
    if names is None or names.strip().lower() == "all":
        return list(studies.STUDIES)
    if names.strip().lower() == "none":
        return []
    return [studies.study(n.strip()) for n in names.split(",") if n.strip()]


def run_report(out: str | Path, config: Config = Config(), plan: Plan = PLANS["default"], *,
               backend: str | None = None, study_list: list[studies.Study] | None = None,
               conventions: tuple[str, ...] = CONVENTIONS, sweeps: Path | None = None,
               quiet: bool = False) -> dict:
    """Run everything and save the tables in ``out``; returns the report record (report.json).

    config: the base configuration (its convention is the studies'; the experiments run every
    convention in ``conventions``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    backend = backend or plan.backend
    config = plan_config(config, plan)
    study_list = list(studies.STUDIES) if study_list is None else study_list
    record_path = out / REPORT_JSON
    record = json.loads(record_path.read_text()) if record_path.exists() else {}
    if record.get("config") not in (None, config.to_dict()):
        raise ParameterError(f"{out} holds a report made with another configuration; "
                             "use another --out folder")
    record.update({"package": "mjx_balance", "version": __version__,
                   "plan": dataclasses.asdict(plan),
                   "backend": backend, "config": config.to_dict(),
                   "conventions": list(conventions), "studies": []})
    save_config(config, out / "config.toml")
    _write_json(record_path, record)

    n_variants = sum(len(s.variants) for s in study_list)
    log = _Log(4 * len(conventions) + n_variants, quiet)
    sweep_log = None if quiet else print
    batches = _Batches(backend)
    forces = parse_grid(plan.region_forces, "region forces")
    durations = parse_grid(plan.region_durations, "region durations")
    # One batch size for every sweep and table: the MJX runner compiles once per configuration.
    chunk = _chunk(config, backend, forces.size * durations.size)
    from .reference import simulate_many

    for convention in conventions:
        cfg = config.replace(controller={"convention": convention})
        folder = out / convention
        folder.mkdir(exist_ok=True)

        def timeseries(cfg=cfg, folder=folder):
            summary, series = simulate_many(cfg, list(plan.timeseries_forces),
                                            [plan.push_duration], progress=not quiet)
            summary.to_csv(folder / "summary.csv", index=False)
            series.to_parquet(folder / "timeseries.parquet", index=False)

        log.stage(f"{convention}: time series, F = {plan.timeseries_forces} N, "
                  f"T = {plan.push_duration} s (reference loop)")
        _stage(out, record, f"{convention}/timeseries",
               {"forces": list(plan.timeseries_forces), "duration": plan.push_duration},
               [folder / "summary.csv", folder / "timeseries.parquet"], timeseries)

        log.stage(f"{convention}: weight study at F = {plan.weight_force} N (reference loop)")
        _stage(out, record, f"{convention}/weights",
               {"force": plan.weight_force, "q": list(plan.q_scales), "r": list(plan.r_scales)},
               [folder / "weights.csv"],
               lambda cfg=cfg, folder=folder: run_weights(cfg, plan).to_csv(
                   folder / "weights.csv", index=False))

        log.stage(f"{convention}: region map, {forces.size} x {durations.size} cells ({backend})")
        batches.sweep(folder / "region", cfg, forces, durations, chunk, quiet)
        log.stage(f"{convention}: robustness table, {len(plan.table_forces)} forces ({backend})")
        run_table(folder / "table", cfg, list(plan.table_forces), run_batch=batches(cfg),
                  batch=None if backend == "reference" else chunk, progress=not quiet,
                  log=sweep_log)

    for st in study_list:
        entry = {"key": st.key, "variants": []}
        for variant in st.variants:
            definition = studies.variant_definition(st, variant, config, sweeps)
            grid_f = (plan.backward_forces if st.signed else plan.study_forces) or definition.forces
            grid_d = plan.study_durations or definition.durations
            study_f = parse_grid(grid_f, "study forces")
            study_d = parse_grid(grid_d, "study durations")
            vcfg = definition.config
            log.stage(f"study {st.key}: {variant.label}, {study_f.size} x {study_d.size} cells")
            batches.sweep(out / "studies" / st.key / variant.key, vcfg, study_f, study_d, chunk,
                          quiet)
            entry["variants"].append({"key": variant.key, "label": variant.label,
                                      "file": variant.file, "config": vcfg.to_dict()})
        regions = {v["key"]: pd.read_parquet(out / "studies" / st.key / v["key"] / "region.parquet")
                   for v in entry["variants"]}
        numbers = (studies.signed_halves(next(iter(regions.values()))) if st.signed else
                   studies.compare(regions, {v["key"]: v["label"] for v in entry["variants"]}))
        numbers.to_csv(out / "studies" / st.key / "numbers.csv", index=False)
        record["studies"].append(entry)
        _write_json(record_path, record)
    record["seconds"] = round(time.perf_counter() - log.start, 1)
    _write_json(record_path, record)
    return record


# ---------------------------------------------------------------------------------------------
# Figures from saved tables


def weight_figure(weights: pd.DataFrame, convention: str):
    """Bar charts: ankle, hip and total energy for each Q (left) and each R (right) setting."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.4), layout="constrained")
    parts = [("energy_ankle", "ankle", "C0"), ("energy_hip", "hip", "C1"),
             ("energy_total", "total", "0.35")]
    for ax, which, label in ((axes[0], "Q", r"Q = s$\cdot$I$_4$  (R default)"),
                             (axes[1], "R", r"R = s$\cdot$diag(1000, 1)  (Q default)")):
        rows = weights[weights["weight"] == which].reset_index(drop=True)
        x = np.arange(len(rows))
        for j, (column, name, colour) in enumerate(parts):
            values = rows[column].to_numpy(float)
            ax.bar(x + (j - 1) * 0.27, np.where(values > 0, values, np.nan), 0.27, label=name,
                   color=colour)
        for i, row in rows.iterrows():
            if row["outcome"] != "recovered":
                ax.annotate(row["outcome"], (i, 1), xycoords=("data", "axes fraction"),
                            ha="center", va="top", fontsize=8, color="C3",
                            xytext=(0, -4), textcoords="offset points")
        ax.set_xticks(x, [f"{s:.0e}" for s in rows["scale"]])
        values = rows[[c for c, _, _ in parts]].to_numpy(float)
        positive = values[np.isfinite(values) & (values > 0)]
        if positive.size and positive.max() / positive.min() > 100:
            ax.set_yscale("log")  # the energies span decades
        else:
            ax.set_ylim(0, 1.15 * (positive.max() if positive.size else 1.0))
        ax.set_xlabel(f"s, {label}")
        ax.set_ylabel(r"joint energy $\int|\tau\,\dot q|\,dt$ [J]")
        ax.grid(axis="y", which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=3, fontsize=8, frameon=False)
    force = weights["force"].iloc[0]
    duration = weights["duration"].iloc[0]
    fig.suptitle(f"Weight study, {convention} convention: F = {force:g} N, T = {duration:g} s "
                 "(red: outcome if not recovered)", fontsize=11)
    return fig


def conventions_figure(tables: dict[str, pd.DataFrame]):
    """Max acting time against force, one line per convention."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2), layout="constrained")
    for i, (convention, table) in enumerate(tables.items()):
        t = table.sort_values("force")
        ax.plot(t["force"], np.maximum(t["max_acting_time"], 0.005), "o-", color=f"C{i}",
                label=convention)
    ax.set_yscale("log")
    ax.set_xlabel("push force F [N]")
    ax.set_ylabel("max acting time [s] (0: drawn at 0.005)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title("Max acting time, paper vs joint convention", fontsize=10)
    return fig


def save_figure(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def load_results(out: str | Path) -> dict[str, Any]:
    """Every saved table of a report folder (what the figures and the notebook read)."""
    out = Path(out)
    record = json.loads((out / REPORT_JSON).read_text())
    results: dict[str, Any] = {"record": record, "config": config_from_dict(record["config"]),
                               "conventions": {}, "studies": {}}
    for convention in record["conventions"]:
        folder = out / convention
        results["conventions"][convention] = {
            "summary": pd.read_csv(folder / "summary.csv"),
            "timeseries": pd.read_parquet(folder / "timeseries.parquet"),
            "weights": pd.read_csv(folder / "weights.csv"),
            "table": pd.read_csv(folder / "table" / "table.csv"),
            "region": pd.read_parquet(folder / "region" / "region.parquet"),
        }
    for entry in record["studies"]:
        folder = out / "studies" / entry["key"]
        results["studies"][entry["key"]] = {
            "variants": entry["variants"],
            "regions": {v["key"]: pd.read_parquet(folder / v["key"] / "region.parquet")
                        for v in entry["variants"]},
            "numbers": pd.read_csv(folder / "numbers.csv"),
        }
    return results


# ---------------------------------------------------------------------------------------------
# HTML


CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; max-width: 1150px;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; } h2 { border-bottom: 1px solid #bbb; margin-top: 2.2em; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.3em 0; }
.row { display: flex; gap: 0.8em; flex-wrap: wrap; } .row figure { flex: 1 1 45%; margin: 0; }
figcaption { font-size: 0.85em; color: #555; }
table { border-collapse: collapse; font-size: 0.82em; margin: 0.6em 0; }
th, td { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #f2f2f2; } .params { background: #f7f7f7; border-left: 4px solid #888;
padding: 0.4em 0.8em; font-size: 0.9em; } .reading { background: #eef6ee;
border-left: 4px solid #4daf4a; padding: 0.5em 0.9em; }
nav ul { columns: 2; font-size: 0.9em; }
"""


def _img(path: Path, caption: str = "") -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    cap = f"<figcaption>{html.escape(caption)}</figcaption>" if caption else ""
    alt = html.escape(caption or Path(path).stem)
    return f'<figure><img alt="{alt}" src="data:image/png;base64,{data}">{cap}</figure>'


def _row(*figures: str) -> str:
    return '<div class="row">' + "".join(figures) + "</div>"


def _table(frame: pd.DataFrame, columns: list[str] | None = None) -> str:
    frame = frame[columns] if columns else frame
    return frame.to_html(index=False, border=0, na_rep="–", float_format=lambda v: f"{v:.4g}")


def _params(text: str) -> str:
    return f'<p class="params">{text}</p>'


def _config_text(config: Config) -> str:
    c, s = config.controller, config.scenario
    return (f"N = {c.horizon}, Q = diag{c.q_diag}, R = diag{c.r_diag}, input bounds "
            f"{c.input1_bounds}, {c.input2_bounds} N·m, state bounds {c.state1_bounds}, "
            f"{c.state2_bounds} rad, CoP/CoM bounds {c.cop_bounds}/{c.com_bounds} m; "
            f"physics dt {s.physics_dt} s, control dt {s.control_dt} s, recovery within "
            f"t_end = {s.t_end:g} s; body mass {config.body.total_mass:g} kg, height "
            f"{config.body.lower_length + config.body.upper_length:g} m")


SUMMARY_SHOWN = ["force", "duration", "outcome", "settle_time", "fall_time", "peak_ankle",
                 "peak_hip", "cop_min", "cop_max", "com_min", "com_max", "peak_tau_ankle",
                 "peak_tau_hip", "energy_ankle", "energy_hip", "energy_total", "energy_u1",
                 "energy_u2", "nonconverged_solves"]
TABLE_SHOWN = ["force", "max_acting_time", "ending_outcome", "energy_ankle_01", "energy_hip_01",
               "energy_total_01", "outcome_01", "energy_ankle_max", "energy_hip_max",
               "energy_total_max", "energy_u1_max", "energy_u2_max", "note"]


def sections(out: str | Path) -> list[tuple[str, str]]:
    """(id, heading) of every section of the report in ``out`` (what build_report writes)."""
    record = json.loads((Path(out) / REPORT_JSON).read_text())
    ids = [("overview", "Overview")]
    for convention in record["conventions"]:
        ids += [(f"timeseries-{convention}", f"1. Time series — {convention} convention"),
                (f"weights-{convention}", f"2. Weight study — {convention} convention"),
                (f"table-{convention}", f"3. Robustness table — {convention} convention"),
                (f"region-{convention}", f"4. Recoverable region — {convention} convention")]
    if len(record["conventions"]) > 1:
        ids.append(("conventions", "Side by side: paper vs joint convention"))
    for entry in record["studies"]:
        ids.append((f"study-{entry['key']}", "Study: " + studies.study(entry["key"]).title))
    return ids


def key_numbers(results: dict[str, Any]) -> list[str]:
    """Headline numbers of a report, one line each, from the saved tables."""
    lines = []
    tables = {c: res["table"] for c, res in results["conventions"].items()}
    if tables:
        parts = []
        for convention, table in tables.items():
            t = table.sort_values("force")
            pairs = ", ".join(f"{f:g} N: {m:g} s" for f, m in zip(t["force"], t["max_acting_time"]))
            parts.append(f"{convention}: {pairs}")
        lines.append("Max acting time — " + "; ".join(parts) + ".")
        for convention, res in results["conventions"].items():
            n = studies.region_numbers(res["region"])
            lines.append(f"Recoverable region ({convention}): {n['area']:.3g} N·s, "
                         f"{n['fraction']:.0%} of the grid.")
    st = results["studies"]
    if "ankle_only" in st:
        rows = st["ankle_only"]["numbers"]
        added = rows["area"].iloc[0] - rows["area"].iloc[1]
        rel = added / rows["area"].iloc[1] if rows["area"].iloc[1] > 0 else float("nan")
        lines.append(f"The hip adds {added:+.3g} N·s to the ankle-only region"
                     + (f" ({rel:+.0%})" if np.isfinite(rel) else "")
                     + ("; with the hip held by its servo and the hip motor off even upright "
                        "rest is lost."
                        if rows.get("rest_recovered", pd.Series([1, 1])).iloc[1] == 0 else "."))
    if "delay" in st:
        rows = st["delay"]["numbers"]
        lines.append("Delay changes the area by " + ", ".join(
            f"{c:+.3g} N·s ({r:+.0%}) at {label}" for c, r, label in
            zip(rows["area_change"].iloc[1:], rows["relative_change"].iloc[1:],
                rows["label"].iloc[1:])) + ".")
        if "rest_recovered" in rows:
            lost = rows["label"][rows["rest_recovered"] == 0].tolist()
            if lost:
                lines.append(f"Upright rest (F = 0) is not held with a delay of {', '.join(lost)}.")
    for key in ("older_adult", "push_height"):
        if key in st:
            rows = st[key]["numbers"]
            lines.append(f"{studies.study(key).title}: " + ", ".join(
                f"{label} {a:.3g} N·s" for label, a in zip(rows["label"], rows["area"])) + ".")
    if "backward" in st:
        rows = st["backward"]["numbers"]
        lines.append(f"Backward vs forward pushes: {rows['area'].iloc[0]:.3g} vs "
                     f"{rows['area'].iloc[1]:.3g} N·s.")
    return lines


def build_report(out: str | Path) -> Path:
    """Draw the figures (DIR/figures) and write DIR/report.html from the saved tables."""
    from . import plots, region_plots

    out = Path(out)
    results = load_results(out)
    record, config = results["record"], results["config"]
    plan = record["plan"]
    figures = out / "figures"
    figures.mkdir(exist_ok=True)
    headings = dict(sections(out))
    body: list[str] = []

    def section(key: str, *content: str) -> None:
        body.append(f'<section id="{key}"><h2>{html.escape(headings[key])}</h2>'
                    + "".join(content) + "</section>")

    section("overview", _params(
        f"mjx_balance {html.escape(str(record['version']))}, plan <b>{plan['name']}</b>, "
        f"batch backend <b>{record['backend']}</b> (table and region maps; the time series and "
        f"the weight study use the scalar reference loop, MuJoCo C + OSQP)"
        + (f", last run {record['seconds']:.0f} s (stages already saved are not rerun)"
           if "seconds" in record else "")
        + ". Base configuration: " + html.escape(_config_text(config)) + "."),
        "<p>Pushes start at upright rest: a horizontal force F (+ forward) on the upper body's "
        "centre of mass for T seconds. Outcomes: recovered (every angle within 0.01 rad and rate "
        "within 0.05 rad/s of upright at t_end), not settled, fell (foot pitch, foot lift, a "
        "state bound exceeded by 0.05 rad, or lower-body tilt beyond 0.5 rad), diverged. Energies "
        "are ∫|τ·dq/dt| dt of the ankle and hip motors; for the paper convention energy_u1/u2 "
        "are "
        "those of the generalised pairs (τ1, q1), (τ2, q2).</p>",
        "<h3>Key numbers</h3><ul>" + "".join(f"<li>{html.escape(line)}</li>"
                                             for line in key_numbers(results)) + "</ul>",
        "<nav><ul>" + "".join(f'<li><a href="#{k}">{html.escape(h)}</a></li>'
                              for k, h in headings.items() if k != "overview") + "</ul></nav>")

    convention_numbers = {}
    for convention, res in results["conventions"].items():
        cfg = config.replace(controller={"convention": convention})
        ts_dir = figures / f"timeseries_{convention}"
        paths = {p.stem: p for p in plots.timeseries_figures(res["timeseries"], ts_dir)}
        section(f"timeseries-{convention}",
                _params(f"Reference loop, {convention} convention, F = "
                        f"{', '.join(f'{f:g}' for f in plan['timeseries_forces'])} N, "
                        f"T = {plan['push_duration']:g} s, t_end = {cfg.scenario.t_end:g} s."),
                _row(_img(paths["ankle_angle"], "ankle angle"),
                     _img(paths["hip_angle"], "hip angle")),
                _row(_img(paths["phase_ankle"], "ankle phase portrait"),
                     _img(paths["phase_hip"], "hip phase portrait")),
                _row(_img(paths["cop"], "CoP"), _img(paths["com"], "CoM")),
                _row(_img(paths["ankle_torque"], "ankle torque"),
                     _img(paths["hip_torque"], "hip torque")),
                _img(paths["energy"], "cumulative joint energy"),
                _table(res["summary"], SUMMARY_SHOWN))

        weights = res["weights"]
        path = save_figure(weight_figure(weights, convention),
                           figures / f"weights_{convention}.png")
        section(f"weights-{convention}",
                _params(f"Reference loop, {convention} convention, F = {plan['weight_force']:g} N, "
                        f"T = {plan['push_duration']:g} s; Q = s·I4 for s in "
                        f"{', '.join(f'{s:g}' for s in plan['q_scales'])} (R default); "
                        f"R = s·diag(1000, 1) for s in "
                        f"{', '.join(f'{s:g}' for s in plan['r_scales'])} (Q default)."),
                _img(path, "ankle, hip and total energy per weight setting"),
                f"<p>{(weights['outcome'] == 'recovered').sum()} of {len(weights)} settings "
                "recover; for a push that falls the energies are those up to the fall.</p>",
                _table(weights, ["weight", "scale", "outcome", "settle_time", "fall_time",
                                 "energy_ankle", "energy_hip", "energy_total", "energy_u1",
                                 "energy_u2", "peak_tau_ankle", "peak_tau_hip",
                                 "nonconverged_solves"]))

        table = res["table"]
        path = region_plots.plot_table(table, figures / f"table_{convention}.png", config=cfg)
        section(f"table-{convention}",
                _params(f"Batch backend {record['backend']}, {convention} convention: for each "
                        f"force the largest T (to 0.01 s) such that every T up to it recovers "
                        f"within t_end = {cfg.scenario.t_end:g} s (coarse scan, then bisection; "
                        f"sweep.max_acting_time). Energies at T = 0.1 s (_01) and at the max "
                        f"acting time (_max)."),
                _img(path, "max acting time and energies"), _table(table, TABLE_SHOWN))

        region = res["region"]
        p1 = region_plots.plot_region(region, figures / f"region_{convention}.png", config=cfg)
        p2 = region_plots.plot_energy(region, figures / f"region_energy_{convention}.png",
                                      config=cfg)
        numbers = studies.region_numbers(region)
        convention_numbers[convention] = numbers
        section(f"region-{convention}",
                _params(f"Batch backend {record['backend']}, {convention} convention, grid "
                        f"{html.escape(studies._grid_text(region))}."),
                _row(_img(p1, "outcome map"), _img(p2, "energy of the recovered pushes")),
                f"<p>Recovered area {numbers['area']:.3g} N·s ({numbers['fraction']:.0%} of the "
                f"grid, {numbers['recovered_cells']} of {numbers['cells']} cells); at T = "
                f"{numbers['t_ref']:g} s the largest recovered force is "
                f"{studies._fmax(numbers['f_max_ref'])}.</p>")

    if len(results["conventions"]) > 1:
        body.append(_side_by_side(results, convention_numbers, figures, headings))

    for key, res in results["studies"].items():
        st = studies.study(key)
        labels = {v["key"]: v["label"] for v in res["variants"]}
        images = []
        for vkey, region in res["regions"].items():
            vcfg = config_from_dict(res["variants"][list(labels).index(vkey)]["config"])
            path = region_plots.plot_region(region, figures / f"study_{key}_{vkey}.png",
                                            config=vcfg)
            images.append(_img(path, labels[vkey]))
        first = next(iter(res["regions"].values()))
        numbers = res["numbers"]
        files = ", ".join(v["file"] for v in res["variants"] if v["file"])
        section(f"study-{key}",
                _params(html.escape(st.question) + f" Sweep definitions: sweeps/{files}; "
                        f"convention {config.controller.convention}; batch backend "
                        f"{record['backend']}; grid {html.escape(studies._grid_text(first))}."),
                _row(*images),
                _table(numbers, ["label", "area", "fraction", "recovered_cells", "cells",
                                 "f_max_ref", "area_change", "gained_cells", "lost_cells"]),
                f'<p class="reading">{html.escape(studies.reading(st, numbers, first))}</p>')

    page = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<title>mjx_balance report</title><style>" + CSS + "</style></head><body>"
            "<h1>Standing balance under constrained MPC: the study reproduced, and beyond</h1>"
            + "".join(body) + "</body></html>")
    path = out / HTML
    path.write_text(page, encoding="utf-8")
    return path


def _side_by_side(results: dict, numbers: dict, figures: Path, headings: dict) -> str:
    convs = list(results["conventions"])
    tables = {c: results["conventions"][c]["table"] for c in convs}
    merged = None
    for c in convs:
        part = tables[c][["force", "max_acting_time", "energy_total_01", "energy_total_max"]]
        part = part.rename(columns={k: f"{k} ({c})" for k in part.columns if k != "force"})
        merged = part if merged is None else merged.merge(part, on="force", how="outer")
    path = save_figure(conventions_figure(tables), figures / "conventions_table.png")
    a, b = convs[0], convs[1]
    ta = tables[a].set_index("force")["max_acting_time"]
    tb = tables[b].set_index("force")["max_acting_time"]
    common = ta.index.intersection(tb.index)
    longer_a = int((ta[common] > tb[common]).sum())
    longer_b = int((tb[common] > ta[common]).sum())
    text = (f"Over the {len(common)} table forces the {a} convention has the longer max acting "
            f"time for {longer_a} forces and the {b} convention for {longer_b} "
            f"({len(common) - longer_a - longer_b} equal). The region maps recover "
            f"{numbers[a]['area']:.3g} N·s ({a}) and {numbers[b]['area']:.3g} N·s ({b}); at T = "
            f"{numbers[a]['t_ref']:g} s the largest recovered force is "
            f"{studies._fmax(numbers[a]['f_max_ref'])} ({a}) and "
            f"{studies._fmax(numbers[b]['f_max_ref'])} ({b}).")
    ts = {c: results["conventions"][c]["summary"] for c in convs}
    outcomes = pd.DataFrame({"force": ts[a]["force"]})
    for c in convs:
        outcomes[f"outcome ({c})"] = ts[c]["outcome"].to_numpy()
        outcomes[f"energy_total ({c})"] = ts[c]["energy_total"].to_numpy()
    images = [_img(figures / f"region_{c}.png", f"region map, {c}") for c in convs]
    return (f'<section id="conventions"><h2>{html.escape(headings["conventions"])}</h2>'
            + _params("Both conventions with the same configuration otherwise; the paper "
                      "convention reads the study's equations literally (generalised forces "
                      "τ1, τ2 on the absolute tilts), the joint convention uses the motor "
                      "torques and joint angles. Bounds apply to each convention's own x and u.")
            + _img(path, "max acting time per force") + _table(merged)
            + "<h3>Time-series pushes (T = 0.1 s)</h3>" + _table(outcomes)
            + _row(*images) + f'<p class="reading">{html.escape(text)}</p></section>')


# ---------------------------------------------------------------------------------------------
# The command


def report_command(args) -> int:
    """``mjx-balance report``: run (or resume) everything, then write DIR/report.html."""
    from .cli import load_run_config

    out = Path(args.out)
    if not getattr(args, "html_only", False):
        plan = PLANS[args.scale]
        conventions = tuple(args.conventions.split(",")) if args.conventions else CONVENTIONS
        bad = [c for c in conventions if c not in CONVENTIONS]
        if bad:
            raise ParameterError(f"--conventions: unknown {', '.join(bad)}")
        record = run_report(out, load_run_config(args), plan, backend=args.backend,
                            study_list=selected_studies(args.studies), conventions=conventions,
                            sweeps=Path(args.sweeps) if args.sweeps else None)
        print(f"tables saved in {out} ({record['seconds']:.0f} s)", file=sys.stderr)
    elif not (out / REPORT_JSON).exists():
        raise ParameterError(f"--html-only: {out / REPORT_JSON} not found (run the report first)")
    path = build_report(out)
    print(f"wrote {path}")
    return 0

