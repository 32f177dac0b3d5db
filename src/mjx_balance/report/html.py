"""The report page, drawn from a report folder's saved tables alone.

``results.load_results`` reads every table of a folder (what the figures and the notebook use).
:func:`build_report` draws the figures into DIR/figures and writes DIR/report.html: one section
per experiment and convention, the conventions side by side, one section per study, then the
sections of report/extra.py (the sensitivity of the robustness table, which the report's run
computes in DIR/sensitivity; the basin and the weight landscape when their folders are there),
each built by its own function from the saved tables as a list of blocks (paragraphs, figures,
tables with footnotes) that the Jinja2 template ``templates/report.html.j2`` (package data)
renders with autoescaping; every figure is embedded in the page, which loads nothing from
elsewhere. A tiny-scale report carries a banner saying its numbers are not meaningful.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from markupsafe import Markup

from ..figures.report import (
    conventions_figure,
    draw_region,
    draw_study,
    draw_table,
    draw_timeseries,
    draw_weights,
    region_figure,
    save_figure,
)
from ..measures.outcomes import OUTCOMES, RECOVERED
from ..measures.units import describe
from ..model.params import Config
from ..model.config_files import with_convention
from ..store.files import write_atomic
from ..studies import catalog
from ..studies.experiments import REPORT_JSON, read_record
from ..studies.reference_files import read_references
from .blocks import embed, img
from .extra import extra_sections
from .results import grid_of, key_numbers, load_results, number_list, sustained_text
from .reproduction import (
    SCORECARD_HEADING,
    reference_files,
    scorecard_section,
    strategy_blocks,
)

HTML = "report.html"
TEMPLATE = "report.html.j2"  # in templates/ (package data)
FIGURES = "figures"

SUMMARY_SHOWN = [
    "force",
    "duration",
    "outcome",
    "settle_time",
    "fall_time",
    "peak_ankle",
    "peak_hip",
    "cop_min",
    "cop_max",
    "com_min",
    "com_max",
    "peak_tau_ankle",
    "peak_tau_hip",
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "energy_u1",
    "energy_u2",
    "nonconverged_solves",
]
WEIGHTS_SHOWN = [
    "weight",
    "scale",
    "outcome",
    "settle_time",
    "fall_time",
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "energy_u1",
    "energy_u2",
    "peak_tau_ankle",
    "peak_tau_hip",
    "nonconverged_solves",
]
TABLE_SHOWN = [
    "force",
    "max_acting_time",
    "ending_outcome",
    "energy_ankle_01",
    "energy_hip_01",
    "energy_total_01",
    "outcome_01",
    "energy_ankle_max",
    "energy_hip_max",
    "energy_total_max",
    "energy_u1_max",
    "energy_u2_max",
    "note",
]
# In the paper convention the study's energy (eq. 20, docs/model.md) heads each table and the
# motors' absolute work is beside it (shown_columns); the lists above are the joint convention's.
STUDY_ENERGY = ["study_energy_u1", "study_energy_u2", "study_energy_total"]
STUDY_SHOWN = [
    "label",
    "area",
    "fraction",
    "recovered_cells",
    "cells",
    "f_max_ref",
    "area_change",
    "gained_cells",
    "lost_cells",
]

CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; max-width: 1150px;
       margin: 2em auto; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { border-bottom: 2px solid #444; } h2 { border-bottom: 1px solid #bbb; margin-top: 2.2em; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.3em 0; }
.row { display: flex; gap: 0.8em; flex-wrap: wrap; } .row figure { flex: 1 1 45%; margin: 0; }
figure { margin: 0.4em 0; } figcaption { font-size: 0.85em; color: #555; }
.table-wrap { max-width: 100%; overflow-x: auto; }
table { border-collapse: collapse; font-size: 0.76em; margin: 0.6em 0; }
th, td { border: 1px solid #ccc; padding: 2px 5px; text-align: right; }
th { background: #f2f2f2; overflow-wrap: anywhere; max-width: 9em; vertical-align: bottom; }
ol.notes { font-size: 0.8em; color: #444; margin-top: 0; }
.params { background: #f7f7f7; border-left: 4px solid #888;
padding: 0.4em 0.8em; font-size: 0.9em; } .reading { background: #eef6ee;
border-left: 4px solid #009E73; padding: 0.5em 0.9em; }
.banner { background: #fff3cd; border: 2px solid #d39e00; color: #5c4400; padding: 0.7em 1em;
          font-weight: 600; margin: 1em 0; }
nav ul { columns: 2; font-size: 0.9em; }
"""
TITLE = "Standing balance under constrained MPC: the study reproduced, and beyond"


def sections(out: str | Path) -> list[tuple[str, str]]:
    """(id, heading) of every section of the report in ``out`` (what build_report writes)."""
    record = read_record(Path(out) / REPORT_JSON)
    ids = [("overview", "Overview")]
    if any(r.kind == "table" for r in read_references(reference_files(out))):
        ids.insert(0, ("scorecard", SCORECARD_HEADING))
    for convention in record["conventions"]:
        ids += [
            (f"timeseries-{convention}", f"1. Time series — {convention} convention"),
            (f"weights-{convention}", f"2. Weight study — {convention} convention"),
            (f"table-{convention}", f"3. Robustness table — {convention} convention"),
            (f"region-{convention}", f"4. Recoverable region — {convention} convention"),
        ]
    if len(record["conventions"]) > 1:
        ids.append(("conventions", "Side by side: paper vs joint convention"))
    for entry in record["studies"]:
        ids.append((f"study-{entry['key']}", "Study: " + catalog.study(entry["key"]).title))
    ids += [(s["id"], s["heading"]) for s in extra_sections(out)]
    return ids


# ---------------------------------------------------------------------------------------------
# Figures from saved tables


# ---------------------------------------------------------------------------------------------
# Blocks: what the template draws (templates/report.html.j2); every text is escaped there


def _row(*figures: dict) -> dict:
    return {"kind": "row", "figures": list(figures)}


# A table's value smaller than this fraction of its column's largest magnitude is shown as 0:
# the batched path runs in float32 (eps 1.2e-7), so such a value (e.g. 1.6e-11 J of energy at
# F = 0 beside energies of 1 J) is below what the column's own numbers resolve. Only the page
# rounds; the saved tables keep every digit.
NOISE_FRACTION = 1e-6


def _cell(value: Any, noise: float = 0.0) -> str:
    """A value as table text: 4 significant digits, ``|value| < noise`` as 0, NaN as –."""
    if isinstance(value, str):
        return value
    if value is None or pd.isna(value):
        return "–"
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if abs(float(value)) < noise:
        return "0"
    return f"{float(value):.4g}"


def _noise(column: pd.Series) -> float:
    """The magnitude below which a float column's values show as 0 (NOISE_FRACTION): only for
    a measured quantity (a unit such as J, rad, s in measures/units.py), never for a setting or
    a ratio (a weight scale column holds 1e-8 beside 1e7 by design)."""
    if not pd.api.types.is_float_dtype(column) or _physical_unit(column.name) is None:
        return 0.0
    top = np.nanmax(np.abs(column.to_numpy(dtype=float)), initial=0.0)
    return float(top) * NOISE_FRACTION


def mark_outcomes(
    frame: pd.DataFrame,
    columns: list[str],
    outcome: str = "outcome",
) -> pd.DataFrame:
    """``frame`` with the values of ``columns`` as text; in a row whose ``outcome`` is not
    recovered the value is left out and that outcome shown instead (``– [fell]``): the energy
    of a run that did not recover is not a recovery cost, so it is never tabulated."""
    frame = frame.copy()
    # only a known outcome other than recovered is marked (an empty outcome_01: no such run)
    ok = ~frame[outcome].astype(str).isin([o for o in OUTCOMES if o != OUTCOMES[RECOVERED]])
    for column in columns:
        noise = _noise(frame[column][ok])
        frame[column] = [
            (_cell(v, noise) if good else f"– [{o}]")
            for v, good, o in zip(frame[column], ok, frame[outcome].astype(str))
        ]
    return frame


def _table(
    frame: pd.DataFrame, columns: list[str] | None = None, note_column: str | None = None
) -> dict:
    """A table block: the frame's cells as text (floats to 4 significant digits, float noise
    as 0: NOISE_FRACTION, NaN as –);
    ``note_column``'s texts become footnote markers ([1], [2], ...) with the notes below."""
    frame = frame[columns] if columns else frame
    noise = {column: _noise(frame[column]) for column in frame.columns}
    notes: list[str] = []
    rows = []
    for _, row in frame.iterrows():
        cells = []
        for column in frame.columns:
            value = row[column]
            if column == note_column:
                text = "" if value is None or pd.isna(value) else str(value)
                if text:
                    if text not in notes:
                        notes.append(text)
                    cells.append(f"[{notes.index(text) + 1}]")
                else:
                    cells.append("")
            else:
                cells.append(_cell(value, noise[column]))
        rows.append(cells)
    return {
        "kind": "table",
        "header": [_header(c) for c in frame.columns],
        "rows": rows,
        "notes": notes,
    }


def _header(column: Any) -> str:
    """A table's column heading: its name and, where it has one, its unit (measures/units.py;
    no unit shown for labels, dimensionless numbers or a row-dependent unit)."""
    unit = _physical_unit(column)
    return str(column) if unit is None else f"{column} [{unit}]"


def _physical_unit(column: Any) -> str | None:
    """The column's physical unit (measures/units.py: J, rad, s, ...), or None for a label, a
    dimensionless number, a row-dependent unit (``mixed``, ``(unit column)``) or an unknown
    column."""
    found = describe(str(column))
    unit = found[0] if found else ""
    return None if unit in ("", "1", "mixed") or unit.startswith("(") else unit


def _run_settings(text: str | Markup) -> dict:
    return {"kind": "params", "text": text}


def _paragraph(text: str | Markup, cls: str = "") -> dict:
    return {"kind": "paragraph", "text": text, "cls": cls}


def _config_text(config: Config) -> str:
    c, s = config.controller, config.scenario
    return (
        f"N = {c.horizon}, Q = diag{c.q_diag}, R = diag{c.r_diag}, input bounds "
        f"{c.input1_bounds}, {c.input2_bounds} N·m, state bounds {c.state1_bounds}, "
        f"{c.state2_bounds} rad, CoP/CoM bounds {c.cop_bounds}/{c.com_bounds} m; "
        f"physics dt {s.physics_dt} s, control dt {s.control_dt} s, recovery within "
        f"t_end = {s.t_end:g} s; body mass {config.body.total_mass:g} kg, height "
        f"{config.body.lower_length + config.body.upper_length:g} m"
    )


def _outcomes_text(config: Config) -> str:
    """The outcome rules in words, with the configuration's thresholds (outcomes.py)."""
    s = config.scenario
    return (
        f"Outcomes: recovered (every angle within {s.settle_angle_tol:g} rad and rate "
        f"within {s.settle_rate_tol:g} rad/s of upright at t_end), not settled, fell (foot "
        f"pitch, foot lift, a state bound exceeded by {s.bound_violation_limit:g} rad, or "
        f"lower-body tilt beyond {s.lower_tilt_limit:g} rad), diverged."
    )


def banner(record: dict, config: Config) -> str | None:
    """The warning on a tiny-scale report (plan ``tiny``): its numbers are not meaningful."""
    plan = record.get("plan", {})
    if plan.get("name") != "tiny":
        return None
    return (
        f"Tiny-scale smoke run (plan tiny): t_end = {config.scenario.t_end:g} s, region "
        f"grids of forces {plan.get('region_forces')} N x durations "
        f"{plan.get('region_durations')} s, table forces "
        f"{number_list(plan.get('table_forces', []))} N, the reference solver capped at "
        f"{plan.get('osqp_max_iter')} iterations. It checks that every stage runs; its "
        "numbers are NOT meaningful results. Run `mjx-balance report` (default scale) for "
        "results."
    )


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

    def section(self, key: str, *blocks: dict) -> dict:
        return {"id": key, "heading": self.headings[key], "blocks": list(blocks)}


# ---------------------------------------------------------------------------------------------
# The sections


def overview_section(page: Page) -> dict:
    """What was run, the outcome rules, the key numbers and the table of contents."""
    record, plan = page.record, page.plan
    run = (
        Markup(
            "mjx_balance {}, plan <b>{}</b>, batch backend <b>{}</b> (table and region "
            "maps; the time series and the weight study use the scalar reference loop, "
            "MuJoCo C + OSQP)"
        ).format(str(record["version"]), plan["name"], record["backend"])
        + (
            f", last run {record['seconds']:.0f} s (stages already saved are not rerun)"
            if "seconds" in record
            else ""
        )
        + ". Base configuration: "
        + _config_text(page.config)
        + "."
    )
    return page.section(
        "overview",
        _run_settings(run),
        _paragraph(
            "Pushes start at upright rest: a horizontal force F (+ forward) on the upper "
            "body's centre of mass for T seconds. "
            + _outcomes_text(page.config)
            + " Two energies. The study's (its eq. 20), headlined in the paper convention: "
            "|∫ τ1 dq1| and |∫ τ2 dq2|, the magnitude of the signed work of its generalised "
            "pairs (study_energy_u1/u2, their sum study_energy_total; a recovery's signed work "
            "is negative). The motors' absolute mechanical work ∫|τ·dq/dt| dt of the ankle "
            "and hip (energy_ankle/hip/total), headlined in the joint convention and shown "
            "beside the study's in the paper convention; energy_u1/u2 are ∫|τ_i dq_i| of the "
            "convention's pairs. Energies are those of recovered runs; a value of a run that "
            "did not recover is marked with its outcome in brackets, or left out (–)."
        ),
        {"kind": "heading", "text": "Key numbers"},
        {"kind": "list", "entries": key_numbers(page.results)},
        {"kind": "nav", "links": [(k, h) for k, h in page.headings.items() if k != "overview"]},
    )


ENERGY_COLUMNS = [
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "energy_u1",
    "energy_u2",
    *STUDY_ENERGY,
]
ENERGY_01 = [f"{c}_01" for c in ENERGY_COLUMNS]


def shown_columns(kind: str, convention: str, frame: pd.DataFrame | None = None) -> list[str]:
    """The columns a section's table shows (kind: summary, weights or table): in the paper
    convention the study's energies (eq. 20) come first among the energies, the motors' after
    them; in the joint convention the motors' alone (SUMMARY_SHOWN, WEIGHTS_SHOWN,
    TABLE_SHOWN). Only columns ``frame`` has (a table saved before a column existed)."""
    base = {"summary": SUMMARY_SHOWN, "weights": WEIGHTS_SHOWN, "table": TABLE_SHOWN}[kind]
    columns = list(base)
    if convention == "paper":
        if kind == "table":
            study = [f"{c}_{s}" for s in ("01", "max") for c in STUDY_ENERGY]
            first = columns.index("energy_ankle_01")
        else:
            study = list(STUDY_ENERGY)
            first = columns.index("energy_ankle")
        columns[first:first] = study
    return [c for c in columns if frame is None or c in frame]


def _marked(frame: pd.DataFrame, columns: list[str], outcome: str = "outcome") -> pd.DataFrame:
    """mark_outcomes on the energy columns that ``frame`` has."""
    return mark_outcomes(frame, [c for c in columns if c in frame], outcome)


def timeseries_section(page: Page, convention: str, res: dict) -> dict:
    """Experiment 1: the time-series figures and the summary rows."""
    cfg = with_convention(page.config, convention)
    paths = draw_timeseries(res["timeseries"], page.figures, convention, cfg, res["summary"])
    return page.section(
        f"timeseries-{convention}",
        _run_settings(
            f"Reference loop, {convention} convention, F = "
            f"{number_list(page.plan['timeseries_forces'])} N, "
            f"T = {page.plan['push_duration']:g} s (shaded), t_end = "
            f"{cfg.scenario.t_end:g} s; time axes end where the action ends; dashed red: "
            "the MPC's bounds where they apply."
        ),
        _row(img(paths["ankle_angle"], "ankle angle"), img(paths["hip_angle"], "hip angle")),
        img(paths["states"], "MPC states x1, x2 against their bounds"),
        img(paths["inputs"], "MPC inputs u1, u2 against their bounds"),
        _row(
            img(paths["phase_ankle"], "ankle phase portrait"),
            img(paths["phase_hip"], "hip phase portrait"),
        ),
        _row(img(paths["cop"], "CoP"), img(paths["com"], "CoM")),
        _row(img(paths["ankle_torque"], "ankle torque"), img(paths["hip_torque"], "hip torque")),
        img(
            paths["energy"],
            "cumulative joint energy"
            + (
                ": the study's (eq. 20, top) and the motors' (bottom)"
                if convention == "paper"
                else ""
            ),
        ),
        _table(
            _marked(res["summary"], ENERGY_COLUMNS),
            shown_columns("summary", convention, res["summary"]),
        ),
    )


def weights_section(page: Page, convention: str, res: dict) -> dict:
    """Experiment 2: the energies of every weight setting, as the study ran it (its push) and
    on a push that recovers under every setting; a setting that did not recover shows its
    outcome, never its energy (the energy of a fall is not a recovery cost)."""
    plan = page.plan
    blocks = [
        _run_settings(
            f"Reference loop, {convention} convention, T = "
            f"{plan['push_duration']:g} s; Q = s·I4 for s in "
            f"{number_list(plan['q_scales'])} (R default); R = s·diag(1000, 1) for s in "
            f"{number_list(plan['r_scales'])} (Q default)."
        )
    ]
    blocks += _weight_blocks(
        page,
        convention,
        res["weights"],
        "weights",
        f"As the study ran it: F = {plan['weight_force']:g} N.",
    )
    if res.get("weights_recovering") is not None:
        blocks += _weight_blocks(
            page,
            convention,
            res["weights_recovering"],
            "weights_recovering",
            f"On a push every setting should recover: F = "
            f"{plan.get('weight_recovering_force', 50):g} N, the largest of the study's "
            "time-series forces that recovers under all ten settings on the default body "
            "(scalar reference, paper convention, measured 2026-11-25; 80 N falls under Q ≥ "
            "1e4 and under R = 1e-5), so that the energies below compare recovery costs.",
        )
    return page.section(f"weights-{convention}", *blocks)


def _weight_blocks(
    page: Page, convention: str, weights: pd.DataFrame, name: str, lead: str
) -> list[dict]:
    """One weight comparison: its lead, figure, outcome count and table."""
    path = draw_weights(weights, page.figures, convention, name=name)
    recovered = int(catalog.is_recovered(weights).sum())
    verdict = f"{recovered} of {len(weights)} settings recover" + (
        "."
        if recovered == len(weights)
        else "; the others show their outcome instead of an energy: the energy of a fall "
        "is not a recovery cost, so they are not compared."
    )
    return [
        _paragraph(lead + " " + verdict),
        img(
            path,
            (
                "the study's energy (eq. 20, top) and the motors' (bottom) per weight setting"
                if convention == "paper"
                else "ankle, hip and total energy per weight setting"
            ),
        ),
        _table(_marked(weights, ENERGY_COLUMNS), shown_columns("weights", convention, weights)),
    ]


def table_section(page: Page, convention: str, res: dict) -> dict:
    """Experiment 3: the max acting time per force."""
    cfg = with_convention(page.config, convention)
    path = draw_table(res["table"], page.figures, cfg)
    return page.section(
        f"table-{convention}",
        _run_settings(
            f"Batch backend {page.record['backend']}, {convention} convention, table "
            f"forces {number_list(res['table']['force'])} N: for each force the largest T "
            f"(to 0.01 s) such that every T up to it recovers within t_end = "
            f"{cfg.scenario.t_end:g} s (coarse scan, then bisection; "
            f"sweep.max_acting_time). Energies at T = 0.1 s (_01) and at the max "
            f"acting time (_max), of recovered runs only (– when that run did not "
            f"recover; its outcome is outcome_01)"
            + (
                "; study_energy_*: the study's energy (eq. 20), energy_*: the motors' absolute work"
                if convention == "paper"
                else ""
            )
            + f". Sustained-push limit, the largest "
            f"force held (not fallen) when it pushes for the whole window: "
            f"{sustained_text(res['table'])}."
        ),
        img(path, "max acting time and energies"),
        _table(
            _marked(res["table"], ENERGY_01, "outcome_01"),
            shown_columns("table", convention, res["table"]),
            note_column="note",
        ),
    )


def region_section(page: Page, convention: str, res: dict) -> dict:
    """Experiment 4: the outcome and energy maps and the recovered area."""
    region = res["region"]
    outcome, energy = draw_region(
        region, page.figures, with_convention(page.config, convention), res["table"]
    )
    numbers = catalog.region_numbers(region)
    cfg = with_convention(page.config, convention)
    return page.section(
        f"region-{convention}",
        _run_settings(
            f"Batch backend {page.record['backend']}, {convention} convention, grid "
            f"{catalog.grid_text(region)}; each sampled (F, T) is one cell (bounds half-way "
            "between samples, the outer ones on the first and last sample); blue: the "
            "table's bisected max acting time."
        ),
        _row(img(outcome, "outcome map"), img(energy, "energy of the recovered pushes")),
        _paragraph(
            f"Recovered area {numbers['area']:.3g} N·s ({numbers['fraction']:.0%} of the "
            f"grid, {numbers['recovered_cells']} of {numbers['cells']} cells); at T = "
            f"{numbers['t_ref']:g} s the largest recovered force is "
            f"{catalog.force_text(numbers['f_max_ref'])}."
        ),
        _paragraph(
            f"Why the falls happened ({catalog.grid_text(region)}): "
            + catalog.infeasibility_text(region)
        ),
        *strategy_blocks(region, res["table"], page.figures, cfg, convention),
    )


def _conventions_reading(
    tables: dict[str, pd.DataFrame], numbers: dict[str, dict], grid: str = ""
) -> str:
    """Which convention has the longer max acting time, and both region areas (on ``grid``)."""
    a, b = list(tables)[:2]
    ta = tables[a].set_index("force")["max_acting_time"]
    tb = tables[b].set_index("force")["max_acting_time"]
    common = ta.index.intersection(tb.index)
    longer_a = int((ta[common] > tb[common]).sum())
    longer_b = int((tb[common] > ta[common]).sum())
    return (
        f"Over the {len(common)} table forces the {a} convention has the longer max acting "
        f"time for {longer_a} forces and the {b} convention for {longer_b} "
        f"({len(common) - longer_a - longer_b} equal). The region maps"
        + (f" ({grid})" if grid else "")
        + " recover "
        f"{numbers[a]['area']:.3g} N·s ({a}) and {numbers[b]['area']:.3g} N·s ({b}); at T = "
        f"{numbers[a]['t_ref']:g} s the largest recovered force is "
        f"{catalog.force_text(numbers[a]['f_max_ref'])} ({a}) and "
        f"{catalog.force_text(numbers[b]['f_max_ref'])} ({b})."
    )


def conventions_section(page: Page) -> dict:
    """The experiments of the first two conventions side by side (region maps drawn by
    region_section); every energy marked with its run's outcome."""
    results = page.results["conventions"]
    convs = list(results)
    tables = {c: results[c]["table"] for c in convs}
    merged = None
    for c in convs:
        part = tables[c][
            ["force", "max_acting_time", "energy_total_01", "energy_total_max", "outcome_01"]
        ]
        part = mark_outcomes(part, ["energy_total_01"], "outcome_01").drop(columns="outcome_01")
        part = part.rename(columns={k: f"{k} ({c})" for k in part.columns if k != "force"})
        merged = part if merged is None else merged.merge(part, on="force", how="outer")
    path = save_figure(conventions_figure(tables), page.figures / "conventions_table.png")
    numbers = {c: catalog.region_numbers(results[c]["region"]) for c in convs}
    a = convs[0]
    outcomes = pd.DataFrame({"force": results[a]["summary"]["force"]})
    for c in convs:
        summary = mark_outcomes(results[c]["summary"], ["energy_total"])
        outcomes[f"outcome ({c})"] = summary["outcome"].to_numpy()
        outcomes[f"energy_total ({c})"] = summary["energy_total"].to_numpy()
    images = [img(region_figure(page.figures, c), f"region map, {c}") for c in convs]
    return page.section(
        "conventions",
        _run_settings(
            "Both conventions with the same configuration otherwise; the paper "
            "convention reads the study's equations literally (generalised forces "
            "τ1, τ2 on the absolute tilts), the joint convention uses the motor "
            "torques and joint angles. Bounds apply to each convention's own x and u. "
            "An energy of a run that did not recover carries its outcome in brackets."
        ),
        img(path, "max acting time per force"),
        _table(merged),
        {"kind": "heading", "text": f"Time-series pushes (T = {page.plan['push_duration']:g} s)"},
        _table(outcomes),
        _row(*images),
        _paragraph(_conventions_reading(tables, numbers, grid_of(results[a]["region"])), "reading"),
    )


def study_section(page: Page, key: str, res: dict) -> dict:
    """A study: every variant's outcome map, the numbers and the reading."""
    st = catalog.study(key)
    images = [img(path, label) for path, label in draw_study(key, res, page.figures)]
    first = next(iter(res["regions"].values()))
    numbers = res["numbers"]
    files = ", ".join(v["file"] for v in res["variants"] if v["file"])
    return page.section(
        f"study-{key}",
        _run_settings(
            st.question + f" Sweep definitions (shipped with the package): {files}; "
            f"convention {page.config.controller.convention}; batch backend "
            f"{page.record['backend']}; grid {catalog.grid_text(first)}."
        ),
        _row(*images),
        _table(numbers, STUDY_SHOWN),
        _paragraph(catalog.reading(st, numbers, first), "reading"),
        *(  # (a QP's infeasibility: the MPC's; another controller solves none)
            _paragraph(f"{v['label']}: " + catalog.infeasibility_text(res["regions"][v["key"]]))
            for v in res["variants"]
            if v.get("config", {}).get("controller", {}).get("kind", "mpc") == "mpc"
        ),
    )


# ---------------------------------------------------------------------------------------------
# The page


def _environment():
    """The Jinja2 environment of the report templates (package data), autoescaping on."""
    from jinja2 import Environment, PackageLoader, StrictUndefined

    return Environment(
        loader=PackageLoader("mjx_balance.report", "templates"),
        autoescape=True,
        undefined=StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def page_html(sections_: list[dict], banner_text: str | None = None) -> str:
    """The whole self-contained HTML document around the sections (templates/report.html.j2)."""
    return (
        _environment()
        .get_template(TEMPLATE)
        .render(title=TITLE, css=CSS, banner=banner_text, sections=embed(sections_))
    )


def build_report(out: str | Path) -> Path:
    """Draw the figures (DIR/figures) and write DIR/report.html from the saved tables."""
    out = Path(out)
    figures = out / FIGURES
    figures.mkdir(exist_ok=True)
    page = Page(load_results(out), figures, dict(sections(out)))
    card = scorecard_section(out, list(page.results["conventions"]), figures)
    body = ([card] if card is not None else []) + [overview_section(page)]
    for convention, res in page.results["conventions"].items():
        body += [
            timeseries_section(page, convention, res),
            weights_section(page, convention, res),
            table_section(page, convention, res),
            region_section(page, convention, res),
        ]
    if len(page.results["conventions"]) > 1:
        body.append(conventions_section(page))
    for key, res in page.results["studies"].items():
        body.append(study_section(page, key, res))
    body += extra_sections(out)  # DIR/landscape, DIR/sensitivity when they hold results
    path = out / HTML
    text = page_html(body, banner(page.record, page.config))
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path
