"""A report folder's saved tables, read back (:func:`load_results`: what ``mb.load_report``,
the page and the notebook read), and the report's key numbers written from them
(:func:`key_numbers`, each naming the grid it came from).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..model.params import Config
from ..model.config_files import config_from_dict
from ..studies import catalog
from ..studies.experiments import REPORT_JSON, WEIGHTS_RECOVERING, read_record


def load_results(out: str | Path) -> dict[str, Any]:
    """Every saved table of a report folder (what the figures and the notebook read).

    Args:
        out: The report folder (``mjx-balance report --out DIR``).

    Returns:
        A dict ``{"record": report.json, "config": the base Config, "conventions": {convention:
        {"summary", "timeseries", "weights", "table", "region"}}, "studies": {key: {"variants"
        (their report.json entries), "regions": {variant key: region map}, "numbers"}}}``.
    """
    out = Path(out)
    record = read_record(out / REPORT_JSON)
    results: dict[str, Any] = {
        "record": record,
        "config": config_from_dict(record["config"]),
        "conventions": {},
        "studies": {},
    }
    for convention in record["conventions"]:
        folder = out / convention
        results["conventions"][convention] = {
            "summary": pd.read_csv(folder / "summary.csv"),
            "timeseries": pd.read_parquet(folder / "timeseries.parquet"),
            "weights": pd.read_csv(folder / "weights.csv"),
            # a report from before the recovering comparison has none
            "weights_recovering": (
                pd.read_csv(folder / WEIGHTS_RECOVERING)
                if (folder / WEIGHTS_RECOVERING).exists()
                else None
            ),
            "table": pd.read_csv(folder / "table" / "table.csv"),
            "region": pd.read_parquet(folder / "region" / "region.parquet"),
        }
    for entry in record["studies"]:
        folder = out / "studies" / entry["key"]
        results["studies"][entry["key"]] = {
            "variants": entry["variants"],
            "regions": {
                v["key"]: pd.read_parquet(folder / v["key"] / "region.parquet")
                for v in entry["variants"]
            },
            "numbers": pd.read_csv(folder / "numbers.csv"),
        }
    return results


def number_list(values) -> str:
    """Numbers as a comma list, each as short as it reads (``%g``)."""
    return ", ".join(f"{v:g}" for v in values)


def sustained_text(table: pd.DataFrame) -> str:
    """The table's sustained-push limit in words (a table from before the column: not measured)."""
    values = table.get("sustained_push_limit")
    if values is None or not np.isfinite(values).any():
        return "not measured"
    return f"{float(values.dropna().iloc[0]):g} N"


def grid_of(region: pd.DataFrame) -> str:
    return "grid " + catalog.grid_text(region)


def _study_grid(res: dict) -> str:
    return grid_of(next(iter(res["regions"].values())))


def key_numbers(results: dict[str, Any]) -> list[str]:
    """Headline numbers of a report, one line each, from the saved tables; each line names
    the grid (or the table forces) its numbers come from."""
    lines = _experiment_lines(results["conventions"], results.get("config"))
    st = results["studies"]
    if "ankle_only" in st:
        lines += [
            line[:-1] + f" ({_study_grid(st['ankle_only'])})."
            for line in _ankle_only_lines(st["ankle_only"]["numbers"])
        ]
    if "delay" in st:
        lines += [
            line[:-1] + f" ({_study_grid(st['delay'])})."
            for line in _delay_lines(st["delay"]["numbers"])
        ]
    for key in ("older_adult", "controllers", "push_height"):
        if key in st:
            rows = st[key]["numbers"]
            lines.append(
                f"{catalog.study(key).title}: "
                + ", ".join(f"{label} {a:.3g} N·s" for label, a in zip(rows["label"], rows["area"]))
                + f" ({_study_grid(st[key])})."
            )
    if "backward" in st:
        rows = st["backward"]["numbers"]
        lines.append(
            f"Backward vs forward pushes: {rows['area'].iloc[0]:.3g} vs "
            f"{rows['area'].iloc[1]:.3g} N·s ({_study_grid(st['backward'])})."
        )
    return lines


def _experiment_lines(conventions: dict[str, dict], config: Config | None = None) -> list[str]:
    """Max acting time per force of every convention (with the table's forces and
    resolution), then each convention's region area (with its grid)."""
    if not conventions:
        return []
    parts = []
    forces = None
    for convention, res in conventions.items():
        t = res["table"].sort_values("force")
        forces = t["force"].to_numpy()
        pairs = ", ".join(f"{f:g} N: {m:g} s" for f, m in zip(t["force"], t["max_acting_time"]))
        parts.append(f"{convention}: {pairs}")
    window = f" within t_end = {config.scenario.t_end:g} s" if config is not None else ""
    lines = [
        f"Max acting time (table forces {number_list(forces)} N, bisected to 0.01 s{window})"
        " — " + "; ".join(parts) + "."
    ]
    limits = [f"{c}: {sustained_text(res['table'])}" for c, res in conventions.items()]
    lines.append(
        "Sustained-push limit (the largest force held for the whole window, to 0.1 N)"
        " — " + "; ".join(limits) + "."
    )
    for convention, res in conventions.items():
        n = catalog.region_numbers(res["region"])
        lines.append(
            f"Recoverable region ({convention}): {n['area']:.3g} N·s, "
            f"{n['fraction']:.0%} of the grid ({grid_of(res['region'])})."
        )
    return lines


def _ankle_only_lines(rows: pd.DataFrame) -> list[str]:
    """What the hip adds to the ankle-only region, and whether upright rest is lost."""
    added = rows["area"].iloc[0] - rows["area"].iloc[1]
    rel = added / rows["area"].iloc[1] if rows["area"].iloc[1] > 0 else float("nan")
    rest_lost = rows.get("rest_recovered", pd.Series([1, 1])).iloc[1] == 0
    return [
        f"The hip adds {added:+.3g} N·s to the ankle-only region"
        + (f" ({rel:+.0%})" if np.isfinite(rel) else "")
        + (
            "; with the hip held by its servo and the hip motor off even upright rest is lost."
            if rest_lost
            else "."
        )
    ]


def _delay_lines(rows: pd.DataFrame) -> list[str]:
    """The area change of each delay, and the delays that lose upright rest."""
    lines = [
        "Delay changes the area by "
        + ", ".join(
            f"{c:+.3g} N·s ({r:+.0%}) at {label}"
            for c, r, label in zip(
                rows["area_change"].iloc[1:],
                rows["relative_change"].iloc[1:],
                rows["label"].iloc[1:],
            )
        )
        + "."
    ]
    if "rest_recovered" in rows:
        lost = rows["label"][rows["rest_recovered"] == 0].tolist()
        if lost:
            lines.append(f"Upright rest (F = 0) is not held with a delay of {', '.join(lost)}.")
    return lines
