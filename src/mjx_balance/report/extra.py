"""Report sections read from result folders that other commands wrote inside the report's
folder (nothing is computed here):

    DIR/landscape/    mjx-balance landscape --out DIR/landscape     (report/landscape.py)
    DIR/sensitivity/  mjx-balance sensitivity --out DIR/sensitivity
    DIR/basin/        mjx-balance basin --out DIR/basin

``build_report`` adds a section for each folder that holds its results, after the studies.
The landscape and the basin are too costly for the report's own run (98 configurations'
tables, 441 scenarios and 24 reference pushes), so the report shows them when they are there;
the sensitivity folder is also filled by the report's run itself (studies/experiments.py
``run_sensitivity_stage``: the plan's table forces, the experiments' tables reused).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..studies import basin
from ..studies.sensitivity import READINGS, SENSITIVITY_CSV, SENSITIVITY_PNG, SENSITIVITY_TXT
from .blocks import img
from .landscape import landscape_section

LANDSCAPE_DIR, SENSITIVITY_DIR, BASIN_DIR = "landscape", "sensitivity", "basin"
SENSITIVITY_HEADING = "Sensitivity: the robustness table under every reading of the study"


def sensitivity_section(folder: str | Path) -> dict | None:
    """The section of a ``mjx-balance sensitivity`` folder (None without sensitivity.csv)."""
    folder = Path(folder)
    if not (folder / SENSITIVITY_CSV).exists():
        return None
    frame = pd.read_csv(folder / SENSITIVITY_CSV)
    keys = [k for k in READINGS if f"max_acting_time_{k}" in frame]
    blocks: list[dict] = [
        {
            "kind": "paragraph",
            "cls": "",
            "text": (
                "The robustness table (max acting time per force, the energies of the longest "
                "recovered push) run under each reading of the study the package supports: "
                "the convention (paper: the study's absolute tilts and generalised torques; "
                "joint: joint angles and motor torques) and the controller (the study's MPC "
                "or the offset-free MPC), each with both energies (the study's eq. 20 and "
                "the motors'). The spread shows which conclusions survive every reading."
            ),
        }
    ]
    if (folder / SENSITIVITY_PNG).exists():
        blocks.append(
            img(
                folder / SENSITIVITY_PNG,
                "One line per reading; grey: the spread of the max acting time; "
                "energies of the longest recovered push (top) and of the 0.1-s push "
                "where it recovers (bottom).",
                alt="sensitivity",
            )
        )
    header = (
        ["force [N]"]
        + [f"max acting time, {READINGS[k][0]} [s]" for k in keys]
        + [
            "max/min",
            "study's energy, longest push, range [J]",
            "motors' energy, longest push, range [J]",
            "study's energy, 0.1-s push, range [J]",
            "motors' energy, 0.1-s push, range [J]",
        ]
    )

    def span(r: pd.Series, name: str) -> str:
        lo, hi = r.get(f"energy_{name}_min"), r.get(f"energy_{name}_max")
        return "–" if lo is None or pd.isna(lo) else f"{lo:.3g}-{hi:.3g}"

    rows = []
    for _, r in frame.iterrows():
        rows.append(
            [f"{r['force']:g}"]
            + [f"{r[f'max_acting_time_{k}']:.2f}" for k in keys]
            + [f"{r['max_acting_time_ratio']:.2f}"]
            + [span(r, n) for n in ("study", "motors", "study_01", "motors_01")]
        )
    blocks.append({"kind": "table", "header": header, "rows": rows, "notes": []})
    if (folder / SENSITIVITY_TXT).exists():
        blocks.append(
            {
                "kind": "paragraph",
                "cls": "reading",
                "text": (folder / SENSITIVITY_TXT).read_text().strip(),
            }
        )
    return {"id": "sensitivity", "heading": SENSITIVITY_HEADING, "blocks": blocks}


def basin_section(folder: str | Path) -> dict | None:
    """The section of a ``mjx-balance basin`` folder (None without basin.parquet)."""
    folder = Path(folder)
    if not (folder / basin.BASIN).exists():
        return None
    frame = pd.read_parquet(folder / basin.BASIN)
    ends = pd.read_csv(folder / basin.PUSHES) if (folder / basin.PUSHES).exists() else None
    blocks: list[dict] = [
        {
            "kind": "paragraph",
            "cls": "",
            "text": (
                "Which initial states recover with no push at all: each cell is a whole-body "
                "CoM position relative to the ankle and a CoM velocity, realised by a posture "
                "family (docs/model.md), run with the outcome rules of the push maps. The "
                "dashed lines bound the linear inverted pendulum's capture point on the foot; "
                "the markers are the push map's cells at the end of their pushes."
            ),
        }
    ]
    if (folder / basin.BASIN_PNG).exists():
        blocks.append(
            img(
                folder / basin.BASIN_PNG,
                "Left: outcome (green recovers); right: recovery energy.",
                alt="recovery basin",
            )
        )
    blocks.append({"kind": "paragraph", "cls": "reading", "text": basin.reading(frame, ends)})
    return {"id": "basin", "heading": "The recovery basin in the CoM plane", "blocks": blocks}


def extra_sections(out: str | Path) -> list[dict]:
    """The sections of the result folders inside the report's folder, in a fixed order."""
    out = Path(out)
    found = [
        basin_section(out / BASIN_DIR),
        landscape_section(out / LANDSCAPE_DIR),
        sensitivity_section(out / SENSITIVITY_DIR),
    ]
    return [s for s in found if s is not None]
