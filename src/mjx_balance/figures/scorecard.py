"""scorecard.png: ours beside each reference, per force, for every measure a reference gives.

One panel per measure (the max acting time first, then the energies): our value per force as a
line with its uncertainty as an error bar (the bisection step; an energy's change over one
step), each reference as its own marker; a reference row that differs beyond its tolerance is a
filled marker, one within it an open one, one we could not compare (our push fell, the force
is not in our table) a cross. A measure whose values span more than a decade gets a
log axis. Colours are Okabe-Ito (colour-blind safe). Drawn from the scorecard's rows
(``studies.scorecard``), and from our table for the forces no reference gives.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from . import style

OURS = "#000000"
SOURCES = ("#E69F00", "#0072B2", "#009E73", "#D55E00", "#CC79A7", "#56B4E9", "#F0E442")
MARKERS = ("o", "s", "D", "^", "v", "P", "X")
TITLES = {"max_acting_time": "max acting time [s]"}


def plain(text: object) -> str:
    """``text`` drawn as written: a ``$`` in a reference's label is a dollar sign, not the start
    of mathematics (matplotlib's mathtext)."""
    return str(text).replace("$", r"\$")


def _title(measure: str) -> str:
    if measure in TITLES:
        return TITLES[measure]
    which = "study's eq. 20" if measure.startswith("study_") else "motors' work"
    when = "T = 0.1 s" if measure.endswith("_01") else "at the max acting time"
    part = measure.split("_")[-2]
    return f"energy {part}, {which}, {when} [J]"


def scorecard_figure(card: pd.DataFrame, *, table: pd.DataFrame | None = None):
    """The scorecard's figure (see the module); ``table``: our table.csv, for our curve over
    every force we computed. Returns the Figure (None when no measure has a value)."""
    measures = [m for m in dict.fromkeys(card["measure"]) if m != "recovered"]
    if not measures:
        return None
    ncols = min(3, len(measures))
    nrows = math.ceil(len(measures) / ncols)
    fig, axes = style.subplots(nrows, ncols, figsize=(4.6 * ncols, 3.8 * nrows), squeeze=False)
    sources = list(dict.fromkeys(card["source"]))
    for ax, measure in zip(axes.ravel(), measures):
        rows = card[card["measure"] == measure]
        _our_curve(ax, rows, table, measure)
        for k, source in enumerate(sources):
            mine = rows[rows["source"] == source]
            if not len(mine):
                continue
            colour, marker = SOURCES[k % len(SOURCES)], MARKERS[k % len(MARKERS)]
            status = mine["status"]
            for shown, look, what in (
                (status == "agrees", {"mfc": "white", "mec": colour, "mew": 1.6}, "within"),
                (status == "differs", {"color": colour}, "differs"),
                (
                    ~status.isin(["agrees", "differs"]),
                    {"color": colour, "alpha": 0.6},
                    "not compared",
                ),
            ):
                if shown.any():
                    ax.plot(
                        mine["force"][shown],
                        mine["reference"][shown],
                        marker if what != "not compared" else "x",
                        ls="",
                        ms=7,
                        label=f"{plain(source)} ({what})",
                        **look,
                    )
        values = np.concatenate([rows["reference"].to_numpy(float), rows["ours"].to_numpy(float)])
        values = values[np.isfinite(values) & (values > 0)]
        if values.size and values.max() / values.min() > 10:
            ax.set_yscale("log")
        ax.set_title(_title(measure), fontsize=9)
        ax.set_xlabel("push force F [N]", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, frameon=False)
    for ax in axes.ravel()[len(measures) :]:
        ax.set_visible(False)
    agree = int((card["status"] == "agrees").sum())
    compared = int(card["status"].isin(["agrees", "differs"]).sum())
    title = (
        f"Scorecard: ours (black, with our uncertainty) beside each reference; "
        f"{agree} of {compared} compared rows within tolerance"
    )
    # wrapped to the figure's width (a one-panel figure is 4.6 in wide): about 0.55 em a
    # character at 10 pt, 72 pt an inch
    width = max(30, int(fig.get_figwidth() * 72 / (0.55 * 10)) - 4)
    fig.suptitle(textwrap.fill(title, width), fontsize=10)
    return fig


def _our_curve(ax, rows: pd.DataFrame, table: pd.DataFrame | None, measure: str) -> None:
    """Our value per force: the table's column where given, else the scorecard's."""
    if table is not None and measure in table:
        ours = table[["force", measure]].rename(columns={measure: "ours"}).sort_values("force")
        unc = rows.drop_duplicates("force").set_index("force")["our_uncertainty"]
        err = unc.reindex(ours["force"]).to_numpy(float)
    else:
        ours = rows.drop_duplicates("force").sort_values("force")
        err = ours["our_uncertainty"].to_numpy(float)
    ax.errorbar(
        ours["force"],
        ours["ours"],
        yerr=np.where(np.isfinite(err), err, 0.0),
        fmt="-",
        color=OURS,
        lw=1.4,
        capsize=3,
        label="ours",
    )


def plot_scorecard(
    card: pd.DataFrame, path: str | Path, *, table: pd.DataFrame | None = None
) -> Path | None:
    """Save :func:`scorecard_figure` as ``path`` (nothing when it has no panel)."""
    fig = scorecard_figure(card, table=table)
    if fig is None:
        return None
    return style.save(fig, path, dpi=120)
