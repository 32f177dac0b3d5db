"""The report page, drawn from a report folder's saved tables alone.

:func:`load_results` reads every table of a folder (what the figures and the notebook use).
:func:`build_report` draws the figures into DIR/figures and writes DIR/report.html: one section
per experiment and convention, the conventions side by side, one section per study, each built
by its own function below from the saved tables; every figure is embedded in the page, which
loads nothing from elsewhere.
"""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import studies
from ..outcomes import OUTCOMES, RECOVERED
from ..params import Config, config_from_dict, with_convention
from ..sweep.store import write_atomic, write_figure
from .run import REPORT_JSON, read_record

HTML = "report.html"
FIGURES = "figures"

SUMMARY_SHOWN = ["force", "duration", "outcome", "settle_time", "fall_time", "peak_ankle",
                 "peak_hip", "cop_min", "cop_max", "com_min", "com_max", "peak_tau_ankle",
                 "peak_tau_hip", "energy_ankle", "energy_hip", "energy_total", "energy_u1",
                 "energy_u2", "nonconverged_solves"]
WEIGHTS_SHOWN = ["weight", "scale", "outcome", "settle_time", "fall_time", "energy_ankle",
                 "energy_hip", "energy_total", "energy_u1", "energy_u2", "peak_tau_ankle",
                 "peak_tau_hip", "nonconverged_solves"]
TABLE_SHOWN = ["force", "max_acting_time", "ending_outcome", "energy_ankle_01", "energy_hip_01",
               "energy_total_01", "outcome_01", "energy_ankle_max", "energy_hip_max",
               "energy_total_max", "energy_u1_max", "energy_u2_max", "note"]
STUDY_SHOWN = ["label", "area", "fraction", "recovered_cells", "cells", "f_max_ref",
               "area_change", "gained_cells", "lost_cells"]

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
TITLE = "Standing balance under constrained MPC: the study reproduced, and beyond"


# ---------------------------------------------------------------------------------------------
# The saved tables


def load_results(out: str | Path) -> dict[str, Any]:
    """Every saved table of a report folder (what the figures and the notebook read).

    Returns {"record": report.json, "config": the base Config, "conventions": {convention:
    {"summary", "timeseries", "weights", "table", "region"}}, "studies": {key: {"variants"
    (their report.json entries), "regions": {variant key: region map}, "numbers"}}}.
    """
    out = Path(out)
    record = read_record(out / REPORT_JSON)
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


def sections(out: str | Path) -> list[tuple[str, str]]:
    """(id, heading) of every section of the report in ``out`` (what build_report writes)."""
    record = read_record(Path(out) / REPORT_JSON)
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


# ---------------------------------------------------------------------------------------------
# Key numbers


def key_numbers(results: dict[str, Any]) -> list[str]:
    """Headline numbers of a report, one line each, from the saved tables."""
    lines = _experiment_lines(results["conventions"])
    st = results["studies"]
    if "ankle_only" in st:
        lines += _ankle_only_lines(st["ankle_only"]["numbers"])
    if "delay" in st:
        lines += _delay_lines(st["delay"]["numbers"])
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


def _experiment_lines(conventions: dict[str, dict]) -> list[str]:
    """Max acting time per force of every convention, then each convention's region area."""
    if not conventions:
        return []
    parts = []
    for convention, res in conventions.items():
        t = res["table"].sort_values("force")
        pairs = ", ".join(f"{f:g} N: {m:g} s" for f, m in zip(t["force"], t["max_acting_time"]))
        parts.append(f"{convention}: {pairs}")
    lines = ["Max acting time — " + "; ".join(parts) + "."]
    for convention, res in conventions.items():
        n = studies.region_numbers(res["region"])
        lines.append(f"Recoverable region ({convention}): {n['area']:.3g} N·s, "
                     f"{n['fraction']:.0%} of the grid.")
    return lines


def _ankle_only_lines(rows: pd.DataFrame) -> list[str]:
    """What the hip adds to the ankle-only region, and whether upright rest is lost."""
    added = rows["area"].iloc[0] - rows["area"].iloc[1]
    rel = added / rows["area"].iloc[1] if rows["area"].iloc[1] > 0 else float("nan")
    rest_lost = rows.get("rest_recovered", pd.Series([1, 1])).iloc[1] == 0
    return [f"The hip adds {added:+.3g} N·s to the ankle-only region"
            + (f" ({rel:+.0%})" if np.isfinite(rel) else "")
            + ("; with the hip held by its servo and the hip motor off even upright "
               "rest is lost." if rest_lost else ".")]


def _delay_lines(rows: pd.DataFrame) -> list[str]:
    """The area change of each delay, and the delays that lose upright rest."""
    lines = ["Delay changes the area by " + ", ".join(
        f"{c:+.3g} N·s ({r:+.0%}) at {label}" for c, r, label in
        zip(rows["area_change"].iloc[1:], rows["relative_change"].iloc[1:],
            rows["label"].iloc[1:])) + "."]
    if "rest_recovered" in rows:
        lost = rows["label"][rows["rest_recovered"] == 0].tolist()
        if lost:
            lines.append(f"Upright rest (F = 0) is not held with a delay of {', '.join(lost)}.")
    return lines


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
            if row["outcome"] != OUTCOMES[RECOVERED]:
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
    """Save a matplotlib figure as PNG atomically (whole or absent) and close it."""
    import matplotlib.pyplot as plt

    try:
        write_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
    return path


def draw_timeseries(series: pd.DataFrame, figures: Path, convention: str) -> dict[str, Path]:
    """The time-series figures of one convention, by name (plots.timeseries_figures)."""
    from .. import plots

    folder = figures / f"timeseries_{convention}"
    return {p.stem: p for p in plots.timeseries_figures(series, folder)}


def draw_weights(weights: pd.DataFrame, figures: Path, convention: str) -> Path:
    """The weight study's energy bars of one convention (weight_figure)."""
    return save_figure(weight_figure(weights, convention), figures / f"weights_{convention}.png")


def draw_table(table: pd.DataFrame, figures: Path, config: Config) -> Path:
    """The max acting time and energies of one convention's table (region_plots.plot_table)."""
    from .. import region_plots

    convention = config.controller.convention
    return region_plots.plot_table(table, figures / f"table_{convention}.png", config=config)


def region_figure(figures: Path, convention: str) -> Path:
    """Where the outcome map of a convention's region is drawn."""
    return figures / f"region_{convention}.png"


def draw_region(region: pd.DataFrame, figures: Path, config: Config) -> tuple[Path, Path]:
    """The outcome map and the energy map of one convention's region."""
    from .. import region_plots

    convention = config.controller.convention
    outcome = region_plots.plot_region(region, region_figure(figures, convention), config=config)
    energy = region_plots.plot_energy(region, figures / f"region_energy_{convention}.png",
                                      config=config)
    return outcome, energy


def draw_study(key: str, res: dict, figures: Path) -> list[tuple[Path, str]]:
    """The outcome map of every variant of a study, with its label."""
    from .. import region_plots

    drawn = []
    for variant in res["variants"]:
        path = region_plots.plot_region(res["regions"][variant["key"]],
                                        figures / f"study_{key}_{variant['key']}.png",
                                        config=config_from_dict(variant["config"]))
        drawn.append((path, variant["label"]))
    return drawn


# ---------------------------------------------------------------------------------------------
# HTML pieces


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


def _numbers(values) -> str:
    return ", ".join(f"{v:g}" for v in values)


def _config_text(config: Config) -> str:
    c, s = config.controller, config.scenario
    return (f"N = {c.horizon}, Q = diag{c.q_diag}, R = diag{c.r_diag}, input bounds "
            f"{c.input1_bounds}, {c.input2_bounds} N·m, state bounds {c.state1_bounds}, "
            f"{c.state2_bounds} rad, CoP/CoM bounds {c.cop_bounds}/{c.com_bounds} m; "
            f"physics dt {s.physics_dt} s, control dt {s.control_dt} s, recovery within "
            f"t_end = {s.t_end:g} s; body mass {config.body.total_mass:g} kg, height "
            f"{config.body.lower_length + config.body.upper_length:g} m")


def _outcomes_text(config: Config) -> str:
    """The outcome rules in words, with the configuration's thresholds (outcomes.py)."""
    s = config.scenario
    return (f"Outcomes: recovered (every angle within {s.settle_angle_tol:g} rad and rate "
            f"within {s.settle_rate_tol:g} rad/s of upright at t_end), not settled, fell (foot "
            f"pitch, foot lift, a state bound exceeded by {s.bound_violation_limit:g} rad, or "
            f"lower-body tilt beyond {s.lower_tilt_limit:g} rad), diverged.")


@dataclass
class Page:
    """What every section of one report page needs."""

    results: dict[str, Any]  # load_results
    figures: Path  # where the figures are drawn
    headings: dict[str, str]  # section id -> heading (sections)

    @property
    def record(self) -> dict:
        return self.results["record"]

    @property
    def config(self) -> Config:
        return self.results["config"]

    @property
    def plan(self) -> dict:
        return self.record["plan"]

    def section(self, key: str, *content: str) -> str:
        return (f'<section id="{key}"><h2>{html.escape(self.headings[key])}</h2>'
                + "".join(content) + "</section>")


# ---------------------------------------------------------------------------------------------
# The sections


def overview_section(page: Page) -> str:
    """What was run, the outcome rules, the key numbers and the table of contents."""
    record, plan = page.record, page.plan
    return page.section(
        "overview",
        _params(f"mjx_balance {html.escape(str(record['version']))}, plan <b>{plan['name']}</b>, "
                f"batch backend <b>{record['backend']}</b> (table and region maps; the time "
                f"series and the weight study use the scalar reference loop, MuJoCo C + OSQP)"
                + (f", last run {record['seconds']:.0f} s (stages already saved are not rerun)"
                   if "seconds" in record else "")
                + ". Base configuration: " + html.escape(_config_text(page.config)) + "."),
        "<p>Pushes start at upright rest: a horizontal force F (+ forward) on the upper body's "
        "centre of mass for T seconds. " + _outcomes_text(page.config) + " Energies "
        "are ∫|τ·dq/dt| dt of the ankle and hip motors; for the paper convention energy_u1/u2 "
        "are those of the generalised pairs (τ1, q1), (τ2, q2).</p>",
        "<h3>Key numbers</h3><ul>" + "".join(f"<li>{html.escape(line)}</li>"
                                             for line in key_numbers(page.results)) + "</ul>",
        "<nav><ul>" + "".join(f'<li><a href="#{k}">{html.escape(h)}</a></li>'
                              for k, h in page.headings.items() if k != "overview")
        + "</ul></nav>")


def timeseries_section(page: Page, convention: str, res: dict) -> str:
    """Experiment 1: the time-series figures and the summary rows."""
    cfg = with_convention(page.config, convention)
    paths = draw_timeseries(res["timeseries"], page.figures, convention)
    return page.section(
        f"timeseries-{convention}",
        _params(f"Reference loop, {convention} convention, F = "
                f"{_numbers(page.plan['timeseries_forces'])} N, "
                f"T = {page.plan['push_duration']:g} s, t_end = {cfg.scenario.t_end:g} s."),
        _row(_img(paths["ankle_angle"], "ankle angle"), _img(paths["hip_angle"], "hip angle")),
        _row(_img(paths["phase_ankle"], "ankle phase portrait"),
             _img(paths["phase_hip"], "hip phase portrait")),
        _row(_img(paths["cop"], "CoP"), _img(paths["com"], "CoM")),
        _row(_img(paths["ankle_torque"], "ankle torque"),
             _img(paths["hip_torque"], "hip torque")),
        _img(paths["energy"], "cumulative joint energy"),
        _table(res["summary"], SUMMARY_SHOWN))


def weights_section(page: Page, convention: str, res: dict) -> str:
    """Experiment 2: the energies of every weight setting."""
    weights, plan = res["weights"], page.plan
    path = draw_weights(weights, page.figures, convention)
    recovered = studies.is_recovered(weights).sum()
    return page.section(
        f"weights-{convention}",
        _params(f"Reference loop, {convention} convention, F = {plan['weight_force']:g} N, "
                f"T = {plan['push_duration']:g} s; Q = s·I4 for s in "
                f"{_numbers(plan['q_scales'])} (R default); "
                f"R = s·diag(1000, 1) for s in {_numbers(plan['r_scales'])} (Q default)."),
        _img(path, "ankle, hip and total energy per weight setting"),
        f"<p>{recovered} of {len(weights)} settings "
        "recover; for a push that falls the energies are those up to the fall.</p>",
        _table(weights, WEIGHTS_SHOWN))


def table_section(page: Page, convention: str, res: dict) -> str:
    """Experiment 3: the max acting time per force."""
    cfg = with_convention(page.config, convention)
    path = draw_table(res["table"], page.figures, cfg)
    return page.section(
        f"table-{convention}",
        _params(f"Batch backend {page.record['backend']}, {convention} convention: for each "
                f"force the largest T (to 0.01 s) such that every T up to it recovers "
                f"within t_end = {cfg.scenario.t_end:g} s (coarse scan, then bisection; "
                f"sweep.max_acting_time). Energies at T = 0.1 s (_01) and at the max "
                f"acting time (_max)."),
        _img(path, "max acting time and energies"), _table(res["table"], TABLE_SHOWN))


def region_section(page: Page, convention: str, res: dict) -> str:
    """Experiment 4: the outcome and energy maps and the recovered area."""
    region = res["region"]
    outcome, energy = draw_region(region, page.figures, with_convention(page.config, convention))
    numbers = studies.region_numbers(region)
    return page.section(
        f"region-{convention}",
        _params(f"Batch backend {page.record['backend']}, {convention} convention, grid "
                f"{html.escape(studies.grid_text(region))}."),
        _row(_img(outcome, "outcome map"), _img(energy, "energy of the recovered pushes")),
        f"<p>Recovered area {numbers['area']:.3g} N·s ({numbers['fraction']:.0%} of the "
        f"grid, {numbers['recovered_cells']} of {numbers['cells']} cells); at T = "
        f"{numbers['t_ref']:g} s the largest recovered force is "
        f"{studies.force_text(numbers['f_max_ref'])}.</p>")


def _conventions_reading(tables: dict[str, pd.DataFrame], numbers: dict[str, dict]) -> str:
    """Which convention has the longer max acting time, and both region areas."""
    a, b = list(tables)[:2]
    ta = tables[a].set_index("force")["max_acting_time"]
    tb = tables[b].set_index("force")["max_acting_time"]
    common = ta.index.intersection(tb.index)
    longer_a = int((ta[common] > tb[common]).sum())
    longer_b = int((tb[common] > ta[common]).sum())
    return (f"Over the {len(common)} table forces the {a} convention has the longer max acting "
            f"time for {longer_a} forces and the {b} convention for {longer_b} "
            f"({len(common) - longer_a - longer_b} equal). The region maps recover "
            f"{numbers[a]['area']:.3g} N·s ({a}) and {numbers[b]['area']:.3g} N·s ({b}); at T = "
            f"{numbers[a]['t_ref']:g} s the largest recovered force is "
            f"{studies.force_text(numbers[a]['f_max_ref'])} ({a}) and "
            f"{studies.force_text(numbers[b]['f_max_ref'])} ({b}).")


def conventions_section(page: Page) -> str:
    """The experiments of the first two conventions side by side (region maps drawn by
    region_section)."""
    results = page.results["conventions"]
    convs = list(results)
    tables = {c: results[c]["table"] for c in convs}
    merged = None
    for c in convs:
        part = tables[c][["force", "max_acting_time", "energy_total_01", "energy_total_max"]]
        part = part.rename(columns={k: f"{k} ({c})" for k in part.columns if k != "force"})
        merged = part if merged is None else merged.merge(part, on="force", how="outer")
    path = save_figure(conventions_figure(tables), page.figures / "conventions_table.png")
    numbers = {c: studies.region_numbers(results[c]["region"]) for c in convs}
    a = convs[0]
    outcomes = pd.DataFrame({"force": results[a]["summary"]["force"]})
    for c in convs:
        outcomes[f"outcome ({c})"] = results[c]["summary"]["outcome"].to_numpy()
        outcomes[f"energy_total ({c})"] = results[c]["summary"]["energy_total"].to_numpy()
    images = [_img(region_figure(page.figures, c), f"region map, {c}") for c in convs]
    return page.section(
        "conventions",
        _params("Both conventions with the same configuration otherwise; the paper "
                "convention reads the study's equations literally (generalised forces "
                "τ1, τ2 on the absolute tilts), the joint convention uses the motor "
                "torques and joint angles. Bounds apply to each convention's own x and u."),
        _img(path, "max acting time per force"), _table(merged),
        "<h3>Time-series pushes (T = 0.1 s)</h3>", _table(outcomes),
        _row(*images),
        f'<p class="reading">{html.escape(_conventions_reading(tables, numbers))}</p>')


def study_section(page: Page, key: str, res: dict) -> str:
    """A study: every variant's outcome map, the numbers and the reading."""
    st = studies.study(key)
    images = [_img(path, label) for path, label in draw_study(key, res, page.figures)]
    first = next(iter(res["regions"].values()))
    numbers = res["numbers"]
    files = ", ".join(v["file"] for v in res["variants"] if v["file"])
    return page.section(
        f"study-{key}",
        _params(html.escape(st.question) + f" Sweep definitions: sweeps/{files}; "
                f"convention {page.config.controller.convention}; batch backend "
                f"{page.record['backend']}; grid {html.escape(studies.grid_text(first))}."),
        _row(*images),
        _table(numbers, STUDY_SHOWN),
        f'<p class="reading">{html.escape(studies.reading(st, numbers, first))}</p>')


# ---------------------------------------------------------------------------------------------
# The page


def page_html(body: list[str]) -> str:
    """The whole self-contained HTML document around the sections."""
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<title>mjx_balance report</title><style>" + CSS + "</style></head><body>"
            f"<h1>{TITLE}</h1>" + "".join(body) + "</body></html>")


def build_report(out: str | Path) -> Path:
    """Draw the figures (DIR/figures) and write DIR/report.html from the saved tables."""
    out = Path(out)
    figures = out / FIGURES
    figures.mkdir(exist_ok=True)
    page = Page(load_results(out), figures, dict(sections(out)))
    body = [overview_section(page)]
    for convention, res in page.results["conventions"].items():
        body += [timeseries_section(page, convention, res),
                 weights_section(page, convention, res),
                 table_section(page, convention, res),
                 region_section(page, convention, res)]
    if len(page.results["conventions"]) > 1:
        body.append(conventions_section(page))
    for key, res in page.results["studies"].items():
        body.append(study_section(page, key, res))
    path = out / HTML
    text = page_html(body)
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path
