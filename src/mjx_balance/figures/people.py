"""people.png: the people scorecard at a glance (``studies.people``).

One row per reference measure that we predict or take as an input: our value's distance from
the published mean in published standard deviations, (ours - mean) / SD, on one axis, with the
agreement band (+-2 SD) shaded; each row is labelled with both values in the paper's units. A
predicted row is a filled circle (bluish green inside the band, vermillion outside), an input a
grey diamond. The title counts the rows not modelled (people.csv lists them with why) and
gives the predicted rows without a published SD, which the axis cannot place, by value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from . import style

INSIDE, OUTSIDE, INPUT = "#009E73", "#D55E00", "#7F7F7F"


def _label(row: Any) -> str:
    sd = "" if pd.isna(row.published_sd) else f" ± {row.published_sd:g}"
    return (
        f"{row.measure.replace('_', ' ')}\n"
        f"ours {row.ours:.3g} vs {row.published_mean:g}{sd} {row.unit} ({row.body})"
    )


def people_figure(card: pd.DataFrame) -> Any:
    """The figure of a scorecard (``studies.people.scorecard``'s rows)."""
    shown = card[card.kind.isin(("predicted", "input")) & card.published_sd.notna()]
    shown = shown.iloc[::-1]  # the first row on top
    z = ((shown.ours - shown.published_mean) / shown.published_sd).to_numpy(float)
    fig, ax = style.subplots(figsize=(9, 1.0 + 0.75 * max(len(shown), 1)))
    ax.axvspan(-2, 2, color="#DDDDDD", zorder=0, label="agreement: mean ± 2 SD")
    ax.axvline(0, color="black", lw=0.8)
    y = np.arange(len(shown))
    for yi, zi, row in zip(y, z, shown.itertuples()):
        if row.kind == "input":
            ax.plot(zi, yi, "D", color=INPUT, ms=7)
        else:
            ax.plot(zi, yi, "o", color=INSIDE if abs(zi) <= 2 else OUTSIDE, ms=8)
    ax.set_yticks(y, [_label(r) for r in shown.itertuples()], fontsize=7)
    reach = max(4.0, float(np.nanmax(np.abs(z))) + 0.5) if z.size else 4.0
    ax.set_xlim(-reach, reach)
    ax.set_xlabel("(ours − published mean) / published SD")
    ax.plot([], [], "o", color=INSIDE, label="predicted, agrees")
    ax.plot([], [], "o", color=OUTSIDE, label="predicted, differs")
    ax.plot([], [], "D", color=INPUT, label="an input taken from that row")
    ax.legend(fontsize=7, loc="lower right")
    missing = card[card.kind == "not modelled"]
    title = "People's measures beside the human bodies"
    if len(missing):
        title += f"\n({len(missing)} rows not modelled, listed in people.csv with why)"
    unscaled = card[(card.kind == "predicted") & card.published_sd.isna()]
    if len(unscaled):  # no SD to place them on the axis: their values in the title
        pairs = "\n".join(
            f"{r.measure.replace('_', ' ')}: ours {r.ours:.3g} vs {r.published_mean:g} {r.unit}"
            for r in unscaled.itertuples()
        )
        title += f"\nwithout a published SD (not on the axis):\n{pairs}"
    ax.set_title(title, fontsize=9 if not len(unscaled) else 7)
    return fig


def plot_people(card: pd.DataFrame, path: str | Path) -> Path:
    """Draw and save people.png (the current figure style's format)."""
    return style.save(people_figure(card), path, dpi=110)
