"""The report's section on the weight landscape, rendered from a landscape folder
(``mjx-balance landscape --out DIR``: landscape.csv, landscape.png, landscape.txt).

:func:`landscape_section` returns a section in the form ``report/html.py``'s sections take
(``{"id", "heading", "blocks"}``, the blocks kinds of templates/report.html.j2: paragraph,
figure, table), or None when the folder holds no landscape. Nothing is computed here: the
numbers are landscape.csv's, the reading is written again from them
(``landscape.reading``), so the section always agrees with the folder.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from ..studies.landscape import LANDSCAPE_CSV, LANDSCAPE_PNG, Delay, reading
from .blocks import img

SECTION_ID = "landscape"
HEADING = "The weight landscape: Q and R scales, with and without delay"


def _cell(value: Any, digits: int = 4) -> str:
    if value is None or pd.isna(value):
        return "–"
    return f"{float(value):.{digits}g}"


def summary_rows(frame: pd.DataFrame) -> pd.DataFrame:
    """Per delay setting: the base weights' row, the largest-area row and the largest
    sustained-limit row (the first of ties, in run order)."""
    rows = []
    for delay in dict.fromkeys(frame["delay"]):
        part = frame[frame["delay"] == delay]
        label = Delay(float(part["delay_ms"].iloc[0]), bool(part["compensated"].iloc[0])).label
        picks = [
            ("base weights (1, 1)", part[part["study"].astype(bool)]),
            ("largest area", part.loc[[part["area"].idxmax()]]),
            (
                "largest sustained limit",
                part.loc[[part["sustained_push_limit"].idxmax()]]
                if part["sustained_push_limit"].notna().any()
                else part.iloc[:0],
            ),
        ]
        for what, pick in picks:
            if len(pick):
                r = pick.iloc[0]
                rows.append(
                    {
                        "delay": label,
                        "which": what,
                        "Q scale": f"{r['q_scale']:g}",
                        "R scale": f"{r['r_scale']:g}",
                        "area [N s]": _cell(r["area"]),
                        "sustained limit [N]": _cell(r["sustained_push_limit"]),
                        "mean recovery energy [J]": _cell(r["mean_recovery_energy"], 3),
                        "energy vs base, same pushes": _cell(r["energy_vs_study"], 3),
                    }
                )
    return pd.DataFrame(rows)


def landscape_section(folder: str | Path) -> dict | None:
    """The section of the landscape in ``folder`` (None if it has no landscape.csv)."""
    folder = Path(folder)
    if not (folder / LANDSCAPE_CSV).exists():
        return None
    frame = pd.read_csv(folder / LANDSCAPE_CSV, dtype={"delay": str})
    blocks: list[dict] = [
        {
            "kind": "paragraph",
            "cls": "",
            "text": (
                f"Each setting is the base configuration with controller.q_diag x Q scale and "
                f"r_diag x R scale ({frame['q_scale'].nunique()} x "
                f"{frame['r_scale'].nunique()} scales), run as mjx-balance compare runs a "
                "configuration: its region map (area, mean energy of its recovered pushes) and "
                "its table (the sustained-push limit). 'Energy vs base' compares like with "
                "like: the mean energy over the pushes that the setting and the base weights "
                "both recover, as a multiple of the base weights'."
            ),
        }
    ]
    if (folder / LANDSCAPE_PNG).exists():
        blocks.append(
            img(
                folder / LANDSCAPE_PNG,
                "Heatmaps: rows are delay settings, the base weights' cell is outlined in red.",
                alt="weight landscape",
            )
        )
    table = summary_rows(frame)
    blocks.append(
        {
            "kind": "table",
            "header": list(table.columns),
            "rows": table.astype(str).values.tolist(),
            "notes": [],
        }
    )
    for line in reading(frame).splitlines():
        blocks.append({"kind": "paragraph", "cls": "", "text": line})
    return {"id": SECTION_ID, "heading": HEADING, "blocks": blocks}
