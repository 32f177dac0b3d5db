"""A cohort's figures (``studies.cohort``), from cohort.csv's frame and the subjects' region
maps: the recoverable area over height x mass (:func:`plot_area`), the recovery boundaries of
chosen subjects on one force x duration plane (:func:`plot_boundaries`), the probability of
recovery per cell with its boundaries (:func:`plot_probability`) and one small outcome map per
subject (:func:`plot_regions`). Saved through ``figures.style`` (its palette, format and
sizes)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from . import style
from .region import (
    FORCE_LABEL,
    boundary_line,
    cell_bounds,
    duration_axis,
    log_durations,
    pivot,
)

SEX_MARKERS = {"male": "o", "female": "^"}
LEVEL_LINES = ("-", "--", ":")  # the probability boundaries' styles, innermost (highest) first
# where boundaries coincide (often: a grid has few durations) each level is shifted this many
# points towards its side (the highest level down and left), so that every line stays visible
LEVEL_SHIFT = 2.0
SCREEN_WIDTH = 8.5  # [in] cohort_probability.png on a screen
# [in] the smallest cell "100" at 7 pt fits in with a margin (the text: about 0.16 x 0.1 in)
WRITTEN_CELL = (0.3, 0.15)


def plot_area(frame: pd.DataFrame, path: str | Path) -> Path:
    """Each subject at (height, mass), coloured by its recoverable area [N s] (viridis: ordered,
    colour-blind safe, greyscale monotone); the marker gives the sex; subjects at the same
    height and mass (other strengths) are drawn side by side, a little apart."""
    fig, ax = style.subplots(figsize=(7, 5.5))
    low, high = float(np.nanmin(frame["area"])), float(np.nanmax(frame["area"]))
    same = frame.groupby(["height", "mass"])
    rank = same.cumcount().to_numpy(float)
    dx = 0.004 * (rank - (same["id"].transform("count").to_numpy(float) - 1) / 2)
    x = frame["height"].to_numpy(float) + dx
    points = None
    for sex, marker in SEX_MARKERS.items():
        rows = (frame["sex"] == sex).to_numpy()
        if rows.any():
            points = ax.scatter(
                x[rows],
                frame["mass"][rows],
                c=frame["area"][rows],
                cmap="viridis",
                vmin=low,
                vmax=high if high > low else low + 1,
                s=70,
                marker=marker,
                edgecolors="0.2",
                linewidths=0.6,
                label=sex,
            )
    fig.colorbar(points, ax=ax, label="recoverable area [N·s]")
    ax.set_xlabel("height [m]")
    ax.set_ylabel("mass [kg]")
    ax.set_title(f"Recoverable area of {len(frame)} subjects over height x mass")
    ax.legend(title="sex", fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    return style.save(fig, path, dpi=120)


def plot_boundaries(
    segments: dict[str, list], chosen: pd.DataFrame, every: pd.DataFrame, path: str | Path
) -> Path:
    """The recovery boundary (outline of the recovered cells; ``segments`` per subject id, as
    ``studies.compare.boundary_segments`` gives them) of each chosen subject on one plane, the
    legend naming the subject's body and area. ``chosen``: cohort.csv's rows of those subjects
    (indexed by id); ``every``: every region's rows (for the axes)."""
    from matplotlib.collections import LineCollection

    durations = np.sort(every["duration"].unique())
    log = log_durations(durations)
    fig, ax = style.subplots(figsize=(8, 5.5))
    lines = ["-", "--", "-.", ":"]
    for k, (ident, segs) in enumerate(segments.items()):
        row = chosen.loc[ident]
        label = (
            f"{ident}: {row['height']:g} m, {row['mass']:g} kg, {row['sex']}: {row['area']:.3g} N·s"
        )
        ax.add_collection(
            LineCollection(
                segs,
                colors=style.SERIES[k % len(style.SERIES)],
                linewidths=2.0,
                linestyles=lines[k % len(lines)],
                label=label,
            )
        )
    fb = cell_bounds(np.sort(every["force"].unique()))
    ax.set_xlim(fb[0], fb[-1])
    duration_axis(ax, durations, cell_bounds(durations, log=log), log)
    ax.set_xlabel("push force F [N]")
    ax.set_title("Recovery boundaries of chosen subjects (smallest to largest area)")
    ax.legend(loc="upper right", fontsize=8, title="subject: recoverable area")
    ax.grid(alpha=0.3)
    return style.save(fig, path, dpi=120)


def _outcome_panel(ax: Any, region: pd.DataFrame) -> None:
    """One subject's outcome map, in the palette (fell hatched), no legend."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    forces, durations, outcome = pivot(region, "outcome")
    names = list(style.OUTCOME_COLOURS)
    codes = np.full(outcome.shape, np.nan)
    for code, name in enumerate(names):
        codes[outcome == name] = code
    log = log_durations(durations)
    fx, dy = cell_bounds(forces), cell_bounds(durations, log)
    cmap = ListedColormap([style.OUTCOME_COLOURS[n] for n in names]).with_extremes(bad="white")
    ax.pcolormesh(
        fx,
        dy,
        np.ma.masked_invalid(codes),
        cmap=cmap,
        norm=BoundaryNorm(np.arange(len(names) + 1) - 0.5, cmap.N),
        shading="flat",
    )
    for name, hatch in style.OUTCOME_HATCHES.items():
        if hatch and (outcome == name).any():
            ax.pcolor(
                fx,
                dy,
                np.ma.masked_where(outcome != name, np.ones(outcome.shape)),
                facecolor="none",
                edgecolor="0.2",
                hatch=hatch,
                linewidth=0,
            )
    ax.set_xlim(fx[0], fx[-1])
    if log:
        ax.set_yscale("log")
    ax.set_ylim(dy[0], dy[-1])


def plot_regions(regions: dict[str, pd.DataFrame], frame: pd.DataFrame, path: str | Path) -> Path:
    """One small outcome map per subject (cohorts of up to 16), titled with its id, body and
    area; one legend of the outcomes below."""
    from matplotlib.patches import Patch

    n = len(regions)
    cols = min(4, n)
    rows = -(-n // cols)
    fig, axes = style.subplots(
        rows, cols, figsize=(2.6 * cols, 2.3 * rows + 0.6), sharex=True, sharey=True, squeeze=False
    )
    numbers = frame.set_index("id")
    for ax, (ident, region) in zip(axes.flat, regions.items()):
        _outcome_panel(ax, region)
        row = numbers.loc[ident]
        ax.set_title(
            f"{ident}: {row['height']:g} m, {row['mass']:g} kg\n{row['area']:.3g} N·s", fontsize=8
        )
    for k in range(n, rows * cols):  # empty panels: the force axis on the panel above
        axes.flat[k].set_visible(False)
        above = axes.flat[k - cols]
        above.xaxis.set_tick_params(labelbottom=True)
        above.set_xlabel("F [N]")
    for ax in axes[-1, : n - (rows - 1) * cols]:
        ax.set_xlabel("F [N]")
    for ax in axes[:, 0]:
        ax.set_ylabel("T [s]")
    fig.legend(
        handles=[
            Patch(
                facecolor=style.OUTCOME_COLOURS[o],
                edgecolor="0.3",
                hatch=style.OUTCOME_HATCHES[o],
                label=o.replace("_", " "),
            )
            for o in style.OUTCOME_COLOURS
        ],
        loc="outside lower center",
        ncol=4,
        fontsize=8,
        frameon=False,
    )
    return style.save(fig, path, dpi=120)


def _write_shares(ax: Any, share: np.ndarray, fx: np.ndarray, dy: np.ndarray, log: bool) -> None:
    """Each cell's P in percent at its centre (the geometric centre on a log axis): dark text
    on viridis' light half, light text on its dark half."""
    fc = (fx[:-1] + fx[1:]) / 2
    dc = np.sqrt(dy[:-1] * dy[1:]) if log else (dy[:-1] + dy[1:]) / 2
    for (j, i), value in np.ndenumerate(share):
        if np.isfinite(value):
            ax.text(
                fc[i],
                dc[j],
                f"{100 * value:.0f}",
                ha="center",
                va="center",
                fontsize=7,
                color="0.1" if value > 0.55 else "0.95",
            )


def plot_probability(
    cells: pd.DataFrame,
    levels: dict[float, pd.DataFrame],
    base: tuple[str, pd.DataFrame],
    half_width: float,
    path: str | Path,
) -> Path:
    """P(recover | F, T) per cell (``cells``: cohort_probability.csv's frame) in viridis from 0
    to 1, each cell's P in percent written in it where the cells are large enough for it
    (:data:`WRITTEN_CELL`; not at one column on the default grid); over it the boundary
    where P >= each level (``levels``: level -> the probability map read as an outcome map,
    recovered where P >= level; highest first, each shifted by :data:`LEVEL_SHIFT` points from
    the next) and, beneath them, the base body's own recovery boundary (``base``: its name and
    its region map), all drawn as ``region.boundary_line`` draws a subject's. Lines and shifts
    are thinner on a figure narrower than the screen's. ``half_width``: the interval's
    worst-case half-width, in the title."""
    from matplotlib import patheffects
    from matplotlib.transforms import offset_copy

    forces, durations, share = pivot(cells, "p_recover")
    log = log_durations(durations)
    fx, dy = cell_bounds(forces), cell_bounds(durations, log)
    fig, ax = style.subplots(figsize=(SCREEN_WIDTH, 6.5))
    width = fig.get_figwidth()
    scale = min(1.0, width / SCREEN_WIDTH)  # one column: 0.41
    mesh = ax.pcolormesh(
        fx, dy, np.ma.masked_invalid(share), cmap="viridis", vmin=0.0, vmax=1.0, shading="flat"
    )
    fig.colorbar(mesh, ax=ax, label="P(recover | F, T)")
    # the axes take about 3/4 of the figure's width and 2/3 of its height
    written = (
        0.75 * width / forces.size >= WRITTEN_CELL[0]
        and 0.66 * fig.get_figheight() / durations.size >= WRITTEN_CELL[1]
    )
    if written:
        _write_shares(ax, share, fx, dy, log)
    name, region = base
    boundary_line(
        ax,
        region,
        fx,
        dy,
        color=style.SERIES[1],
        lw=7.0 * scale,
        solid_capstyle="butt",
        label=f"{name} recovers",
    )
    halo = [patheffects.withStroke(linewidth=3.5 * scale, foreground="white")]
    middle = (len(levels) - 1) / 2
    for k, (level, region) in enumerate(levels.items()):
        shift = LEVEL_SHIFT * scale * (k - middle)
        boundary_line(
            ax,
            region,
            fx,
            dy,
            color="black",
            lw=max(1.6 * scale, 1.0),
            ls=LEVEL_LINES[k % len(LEVEL_LINES)],
            path_effects=halo,
            transform=offset_copy(ax.transData, fig=fig, x=shift, y=shift, units="points"),
            label=f"P(recover) ≥ {100 * level:g} %",
        )
    ax.set_xlim(fx[0], fx[-1])
    duration_axis(ax, durations, dy, log)
    ax.set_xlabel(FORCE_LABEL)
    subjects = int(cells["subjects"].max())
    ax.set_title(
        f"Probability of recovery over {subjects} subject"
        f"{'' if subjects == 1 else 's'}{' (in % in each cell)' if written else ''}"
        f"\n95 % Wilson interval within ±{100 * half_width:.1f} % at worst"
    )
    fig.legend(
        loc="outside lower center",
        ncol=2,  # four columns ran past the figure's edges at the screen size
        frameon=False,
        title="per force, the longest duration up to which",
    )
    return style.save(fig, path, dpi=120)
