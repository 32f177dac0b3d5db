"""Figures of sweep results (matplotlib): the recoverable region, its energy, the table curve.

All are drawn from saved tables (``region.parquet``, ``table.csv``). Each figure has a function
that draws it on a matplotlib ``Axes`` (``ax=None``: a new figure) and returns the ``Figure``,
so a notebook composes them, and a ``plot_*`` function that saves it to a file:

region_map / plot_region     outcome of every cell over force x duration, one colour per outcome
                             (the legend lists every outcome class with its count), the recovery
                             boundary on the grid, the bisected max acting time (table.csv) when
                             given or found beside the figure, lines of constant impulse F*T and
                             optional reference points
energy_map / plot_energy     total joint energy of the recovered cells (log colour scale); the
                             cells that did not recover are grey, their energy is not shown
table_figure / plot_table    max acting time against force, and the energies of the recovered
                             runs at 0.1 s and at the max acting time

Cells (:func:`cell_bounds`). Each sampled (F, T) is drawn as one cell around its sample: the
bound between two neighbouring samples is their midpoint (on a log axis their geometric mean),
and the outer bounds are the first and last samples themselves, so the map covers exactly the
sampled range [min, max] of each axis (the same cells as the recovered area of
``studies.catalog.region_numbers``) and nothing outside it is painted. Only an axis with a
single sample, which has no neighbour to take a width from, gets a band of +-5 % of its value
(at least 0.01), clipped at 0 when the value is >= 0. The duration axis is logarithmic when the
durations span more than a decade (all > 0 and max / min > 10).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib import patheffects
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter

from ..measures.capture import saved
from ..measures.outcomes import OUTCOMES, RECOVERED
from ..measures.strategy import HIP_SHARE_THRESHOLD, takeover
from ..model.params import Config
from ..store.files import TABLE
from . import style
from .style import OUTCOME_COLOURS, OUTCOME_HATCHES

RECOVERED_TEXT = OUTCOMES[RECOVERED]
TAKEOVER_COLOUR = "#CC79A7"  # the hip's take-over line (Okabe-Ito reddish purple)

OUTCOME_LABELS = {
    "recovered": "recovered",
    "not_settled": "not settled by t_end",
    "fell": "fell",
    "diverged": "diverged",
}
CONVENTION_TEXT = {
    "paper": "paper convention (x = [q1, q2, dq1, dq2], u = [τ1, τ2])",
    "joint": "joint convention (x = [q_a, q_h, dq_a, dq_h], u = [τ_ankle, τ_hip])",
}
FORCE_LABEL = "push force F [N]  (+ forward)"
DURATION_LABEL = "push duration T [s]"
LOG_SPAN = 10.0  # a duration axis spanning more than this ratio (a decade) is logarithmic


# The step boundaries (_step_lines): white over the outcome colours, dashed for one step,
# dotted for two, each with a thin black edge so that it reads on every cell colour.
STEP_STYLES = {
    n: {
        "color": "white",
        "lw": 2.0,
        "ls": dashes,
        "path_effects": [patheffects.withStroke(linewidth=3.6, foreground="black")],
    }
    for n, dashes in ((1, (0, (5, 2))), (2, (0, (1, 1.2))))
}


def _minor_log_label(value: float, _pos=None) -> str:
    """Label the 2 and 5 minor ticks of a log axis in plain numbers (none else)."""
    if not value > 0:
        return ""
    mantissa = round(value / 10 ** np.floor(np.log10(value)), 6)
    return f"{value:g}" if mantissa in (2.0, 5.0) else ""


def _plain_log_labels(axis) -> None:
    """Plain numbers on a log axis: every decade, and the 2 and 5 between."""
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axis.set_minor_formatter(FuncFormatter(_minor_log_label))


SAMPLE_DOTS = 400  # grids with at most this many cells show a dot on every sample


def save_png(fig, path: str | Path, dpi: int) -> Path:
    """Write the figure atomically (the file is whole or absent) in the current figure style
    (``style.save``: its format and size; a .png name takes the format's suffix), then close
    it; returns the path written."""
    return style.save(fig, path, dpi=dpi)


def new_axes(ax, figsize):
    """(figure, axes): the given axes and its figure, or a new figure (``figsize`` on a screen,
    else the current column size: ``style.subplots``)."""
    if ax is None:
        _, ax = style.subplots(figsize=figsize)
    return ax.figure, ax


def log_durations(durations) -> bool:
    """Whether a duration axis is drawn logarithmic: every duration > 0 and max / min > 10."""
    d = np.asarray(durations, dtype=float)
    return bool(d.size > 1 and d.min() > 0 and d.max() / d.min() > LOG_SPAN)


def cell_bounds(values, log: bool = False) -> np.ndarray:
    """Cell bounds of sampled values (n + 1 for n distinct values, ascending).

    Between two neighbouring samples the bound is their midpoint (``log``: their geometric
    mean); the outer bounds are the first and last samples themselves (nothing beyond the
    sampled range). A single sample gets v +- max(5 % of |v|, 0.01) (``log``: v / 1.1 .. v * 1.1),
    clipped at 0 when v >= 0.
    """
    values = np.unique(np.asarray(values, dtype=float))
    if values.size == 0:
        raise ValueError("no values")
    if values.size == 1:
        v = values[0]
        if log and v > 0:
            return np.array([v / 1.1, v * 1.1])
        half = max(0.05 * abs(v), 0.01)
        low = max(v - half, 0.0) if v >= 0 else v - half
        return np.array([low, v + half])
    if log:
        mid = np.sqrt(values[1:] * values[:-1])
    else:
        mid = 0.5 * (values[1:] + values[:-1])
    return np.concatenate([[values[0]], mid, [values[-1]]])


def pivot(region: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    table = region.pivot(index="duration", columns="force", values=column)
    table = table.reindex(index=durations, columns=forces)
    return forces, durations, table.to_numpy()


def recovery_boundary(region: pd.DataFrame, steps: int | None = None) -> pd.DataFrame:
    """Per force, the longest grid duration up to which every grid duration recovered
    (0 if the shortest fails), and whether a longer duration recovers again (not monotone).
    ``steps``: recovered with at most that many steps instead (``steps_needed``, capturability:
    a cell that did not fall needs none)."""
    rows = []
    for force, group in region.sort_values("duration").groupby("force"):
        in_place = (group["outcome"] == RECOVERED_TEXT).to_numpy()
        ok = saved(in_place, group.get("steps_needed"), steps)
        durations = group["duration"].to_numpy()
        first_fail = int(np.argmin(ok)) if not ok.all() else ok.size
        rows.append(
            {
                "force": force,
                "boundary": durations[first_fail - 1] if first_fail else 0.0,
                "first_failure": durations[first_fail] if first_fail < ok.size else np.nan,
                "monotone": not ok[first_fail:].any(),
            }
        )
    return pd.DataFrame(rows)


def map_title(kind: str, config: Config | None, region: pd.DataFrame) -> str:
    convention = config.controller.convention if config else str(region["convention"].iloc[0])
    t_end = f", recovery within t_end = {config.scenario.t_end:g} s" if config else ""
    return f"{kind}\n{CONVENTION_TEXT.get(convention, convention)}{t_end}"


def grid_text(forces: np.ndarray, durations: np.ndarray) -> str:
    return (
        f"grid: {forces.size} forces {forces.min():g}..{forces.max():g} N x "
        f"{durations.size} durations {durations.min():g}..{durations.max():g} s"
    )


def duration_axis(ax, durations: np.ndarray, bounds: np.ndarray, log: bool) -> None:
    if log:
        ax.set_yscale("log")
        _plain_log_labels(ax.yaxis)
    ax.set_ylim(bounds[0], bounds[-1])
    ax.set_ylabel(DURATION_LABEL + ("  (log scale)" if log else ""))


def _nice_impulses(low: float, high: float, count: int = 4) -> list[float]:
    """Up to ``count`` round impulses (1, 2, 5 x 10^k N s) strictly inside (low, high),
    spread evenly on a log scale."""
    if not (low > 0 and high > low):
        return []
    candidates = [
        m * 10.0**k
        for k in range(int(np.floor(np.log10(low))) - 1, int(np.ceil(np.log10(high))) + 1)
        for m in (1, 2, 5)
    ]
    inside = [c for c in candidates if low * 1.05 < c < high / 1.05]
    if len(inside) <= count:
        return inside
    picks = np.unique(np.round(np.linspace(0, len(inside) - 1, count)).astype(int))
    return [inside[i] for i in picks]


def _impulse_lines(ax, fx: np.ndarray, dy: np.ndarray, log: bool) -> list[float]:
    """Labelled lines of constant impulse |F| T over the map; returns the impulses drawn."""
    f_abs = np.abs(fx)
    f_low = max(f_abs.min() if (fx.min() > 0 or fx.max() < 0) else 0.0, 0.1 * f_abs.max())
    t_low, t_high = max(dy[0], 1e-9), dy[-1]
    impulses = _nice_impulses(f_low * t_low, f_abs.max() * t_high)
    if not impulses:
        return []
    f = np.linspace(fx[0], fx[-1], 400)
    t = np.geomspace(t_low, t_high, 300) if log else np.linspace(dy[0], dy[-1], 300)
    grid_f, grid_t = np.meshgrid(f, t)
    lines = ax.contour(
        grid_f,
        grid_t,
        np.abs(grid_f) * grid_t,
        levels=impulses,
        colors="0.15",
        linestyles="dashed",
        linewidths=0.9,
        alpha=0.8,
    )
    name = "|F|·T" if fx[0] < 0 else "F·T"
    ax.clabel(lines, fmt=lambda v: f"{name} = {v:g} N·s", fontsize=7, inline=True)
    return impulses


def _table_beside(path: str | Path, region: pd.DataFrame) -> pd.DataFrame | None:
    """table.csv in the figure's folder (a sweep folder), if it is of the region's convention."""
    candidate = Path(path).parent / TABLE
    if not candidate.exists():
        return None
    try:
        table = pd.read_csv(candidate)
    except Exception:
        return None
    if "convention" in table and "convention" in region and len(table) and len(region):
        if str(table["convention"].iloc[0]) != str(region["convention"].iloc[0]):
            return None
    return table if {"force", "max_acting_time"} <= set(table.columns) else None


def boundary_line(
    ax, region: pd.DataFrame, fx: np.ndarray, dy: np.ndarray, steps: int | None = None, **line_style
):
    """Draw the recovery boundary on the grid (:func:`recovery_boundary`, with at most
    ``steps`` steps if given) as a step line along the top of each force's first recovered
    range of durations (black, 2 pt, unless ``line_style``, matplotlib's ``plot`` keywords,
    says otherwise); returns the line."""
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    boundary = recovery_boundary(region, steps).set_index("force").reindex(forces)
    d_index = {d: i for i, d in enumerate(durations)}
    tops = np.array(
        [dy[d_index[b] + 1] if b in d_index else dy[0] for b in boundary["boundary"].to_numpy()]
    )
    line_style = {
        "color": "black",
        "lw": 2.0,
        "label": "recovery boundary on the grid",
        **line_style,
    }
    (line,) = ax.plot(np.repeat(fx, 2)[1:-1], np.repeat(tops, 2), **line_style)
    return line


def takeover_line(
    ax, region: pd.DataFrame, threshold: float, fx: np.ndarray, dy: np.ndarray, **style
):
    """Draw, per force, the bottom of the first cell where the hip takes over (a step line
    through the forces that have one); returns the line or None when no force has one."""
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    at = takeover(region, threshold).set_index("force").reindex(forces)["takeover"].to_numpy()
    index = {d: i for i, d in enumerate(durations)}
    bottoms = np.array([dy[index[d]] if np.isfinite(d) and d in index else np.nan for d in at])
    if not np.isfinite(bottoms).any():
        return None
    (line,) = ax.plot(np.repeat(fx, 2)[1:-1], np.repeat(bottoms, 2), **style)
    return line


def region_map(
    region: pd.DataFrame,
    *,
    config: Config | None = None,
    reference: pd.DataFrame | None = None,
    table: pd.DataFrame | None = None,
    impulses: bool = True,
    ax=None,
):
    """Draw the outcome map of a region; the recovery boundary on it.

    Cells are coloured by outcome (the axes' limits are the grid's cell bounds), the legend names
    every outcome class with its number of cells; the black step line is the recovery boundary
    (the top of each force's first recovered range of durations), with the boundaries with one
    and two steps.

    Args:
        region: A region map: region.parquet's rows (:func:`sweep`'s frame).
        config: The region's configuration (its bounds and units; None: the study's).
        reference: A reference table whose points are drawn over the map (None: none).
        table: A robustness table (table.csv) whose bisected max acting times are drawn (None:
            none).
        impulses: Draw labelled lines of constant impulse F T.
        ax: The matplotlib Axes to draw on (None: a new figure).

    Returns:
        The Figure.
    """
    forces, durations, outcome = pivot(region, "outcome")
    codes = np.full(outcome.shape, np.nan)
    for code, name in enumerate(OUTCOMES):
        codes[outcome == name] = code
    cmap = ListedColormap([OUTCOME_COLOURS[name] for name in OUTCOMES]).with_extremes(bad="white")
    norm = BoundaryNorm(np.arange(len(OUTCOMES) + 1) - 0.5, cmap.N)
    log = log_durations(durations)
    fx, dy = cell_bounds(forces), cell_bounds(durations, log)

    fig, ax = new_axes(ax, (8.5, 7.5))
    ax.pcolormesh(fx, dy, np.ma.masked_invalid(codes), cmap=cmap, norm=norm, shading="flat")
    _hatch_outcomes(ax, fx, dy, outcome)
    ax.set_xlim(fx[0], fx[-1])
    duration_axis(ax, durations, dy, log)
    handles: list = _sample_dots(ax, forces, durations)
    handles += _boundary_lines(ax, region, forces, fx, dy)
    if table is not None and len(table):
        handles += _table_overlay(ax, table, fx, dy)
    if impulses:
        handles += _impulse_legend(ax, fx, dy, log)
    if reference is not None and len(reference):
        handles += _reference_points(ax, reference)
    _outcome_legend(ax, region, handles, config, forces, durations)
    return fig


def _sample_dots(ax, forces: np.ndarray, durations: np.ndarray) -> list:
    """Dot the sampled (F, T) of a small grid; returns their legend handle (none if larger)."""
    handles = []
    if forces.size * durations.size <= SAMPLE_DOTS:
        grid_f, grid_d = np.meshgrid(forces, durations)
        ax.plot(
            grid_f.ravel(),
            grid_d.ravel(),
            ".",
            color="0.1",
            ms=5,
            alpha=0.7,
            clip_on=False,
            zorder=3,
        )
        handles.append(
            Line2D(
                [], [], ls="", marker=".", color="0.1", ms=5, label="sampled (F, T): one cell each"
            )
        )
    return handles


def _boundary_lines(
    ax, region: pd.DataFrame, forces: np.ndarray, fx: np.ndarray, dy: np.ndarray
) -> list:
    """Draw the recovery boundary, the hip's takeover and non-monotone marks; returns handles."""
    # Boundary on the grid: a step line along the top of each force's first recovered range.
    boundary = recovery_boundary(region).set_index("force").reindex(forces)
    handles = [boundary_line(ax, region, fx, dy, label="feet in place: recovery boundary")]
    handles += _step_lines(ax, region, fx, dy)
    if "energy_hip" in region:
        over = takeover_line(
            ax,
            region,
            HIP_SHARE_THRESHOLD,
            fx,
            dy,
            color=TAKEOVER_COLOUR,
            lw=2.0,
            ls="--",
            label=f"hip takes over above (hip's share of the work "
            f"> {HIP_SHARE_THRESHOLD:g}; "
            f"{style.figure_name('strategy.png')})",
        )
        if over is not None:
            handles.append(over)
    if not boundary["monotone"].all():
        odd = boundary.index[~boundary["monotone"].to_numpy()]
        (mark,) = ax.plot(
            odd,
            np.full(odd.size, dy[-1]),
            "v",
            color="black",
            ms=6,
            clip_on=False,
            label="recovers again beyond a failure (not monotone)",
        )
        handles.append(mark)
    return handles


def _step_lines(ax, region: pd.DataFrame, fx: np.ndarray, dy: np.ndarray) -> list:
    """The boundaries with one and with two steps (``steps_needed``, capturability: docs/model.md,
    "Stepping: capturability"), where the region has the column; returns their handles."""
    if "steps_needed" not in region:
        return []
    top = region["duration"].max()
    handles = []
    for n, label in ((1, "with one step (capturability)"), (2, "with two steps")):
        if (recovery_boundary(region, n)["boundary"] >= top).all():
            label = label.split(" (")[0] + ": whole grid (top edge)"
        handles.append(boundary_line(ax, region, fx, dy, steps=n, label=label, **STEP_STYLES[n]))
    return handles


def _impulse_legend(ax, fx: np.ndarray, dy: np.ndarray, log: bool) -> list:
    """Draw the lines of constant impulse; returns their legend handle (none if none drawn)."""
    handles = []
    drawn = _impulse_lines(ax, fx, dy, log)
    if drawn:
        handles.append(
            Line2D(
                [],
                [],
                color="0.15",
                ls="--",
                lw=0.9,
                label="constant impulse " + ("|F|·T" if fx[0] < 0 else "F·T") + " [N·s]",
            )
        )
    return handles


def _reference_points(ax, reference: pd.DataFrame) -> list:
    """Draw the reference's (F, T) points; returns their legend handle."""
    label = str(reference["label"].iloc[0]) if "label" in reference else "reference points"
    (ref,) = ax.plot(
        reference["force"],
        reference["duration"],
        "o",
        mfc="white",
        mec="black",
        mew=1.5,
        ms=6,
        label=label,
    )
    return [ref]


def _outcome_legend(
    ax,
    region: pd.DataFrame,
    handles: list,
    config: Config | None,
    forces: np.ndarray,
    durations: np.ndarray,
) -> None:
    """Label the map and draw its legend: the outcomes with their counts, then ``handles``."""
    counts = region["outcome"].value_counts()
    outcome_handles = [
        Patch(
            facecolor=OUTCOME_COLOURS[n],
            edgecolor="0.3",
            lw=0.5,
            hatch=OUTCOME_HATCHES[n],
            label=f"{OUTCOME_LABELS[n]} ({counts.get(n, 0)})",
        )
        for n in OUTCOMES
    ]
    ax.set_xlabel(FORCE_LABEL)
    ax.set_title(
        map_title("Outcome of a push (F, T) from upright rest", config, region)
        + "\n"
        + grid_text(forces, durations),
        fontsize=9,
    )
    fig = ax.get_figure()
    for ncol in (3, 2, 1):  # three columns where they fit in the figure's width, else fewer
        legend = ax.legend(
            handles=outcome_handles + handles,
            loc="upper center",
            bbox_to_anchor=(0.5, -0.1),
            ncol=ncol,
            fontsize=8,
            frameon=False,
            title=f"{len(region)} cells by outcome (count)",
            title_fontsize=8,
        )
        renderer = fig.canvas.get_renderer()
        if legend.get_window_extent(renderer).width <= fig.bbox.width:
            break


def _hatch_outcomes(ax, fx: np.ndarray, dy: np.ndarray, outcome: np.ndarray) -> None:
    """Hatch the cells of the outcomes that have a hatch (OUTCOME_HATCHES: fell), so that the
    map reads in greyscale too (fell and recovered are about as light)."""
    for name, hatch in OUTCOME_HATCHES.items():
        cells = outcome == name
        if hatch and cells.any():
            ax.pcolor(
                fx,
                dy,
                np.ma.masked_where(~cells, np.ones(cells.shape)),
                hatch=hatch,
                facecolor="none",
                edgecolor="0.15",
                linewidth=0.0,
                shading="flat",
            )


# table.csv's max acting times on the map: blue, open markers
TABLE_MARKS = {"color": "#1f3fbf", "mfc": "white", "mew": 1.5, "ms": 5}


def _table_overlay(ax, table: pd.DataFrame, fx: np.ndarray, dy: np.ndarray) -> list:
    """The bisected max acting time of the table's forces inside the map's force range."""
    t = table.sort_values("force")
    force = t["force"].to_numpy(dtype=float)
    tmax = t["max_acting_time"].to_numpy(dtype=float)
    inside = (force >= fx[0]) & (force <= fx[-1]) & np.isfinite(tmax)
    if not inside.any():
        return []
    force, tmax = force[inside], tmax[inside]
    shown = (tmax >= dy[0]) & (tmax <= dy[-1])
    handles = []
    if shown.any():
        (curve,) = ax.plot(
            force[shown],
            tmax[shown],
            "o-",
            lw=1.5,
            label="max acting time, bisected to 0.01 s (table.csv)",
            **TABLE_MARKS,
        )
        handles.append(curve)
    below = tmax < dy[0]
    if below.any():
        (low,) = ax.plot(
            force[below],
            np.full(below.sum(), dy[0]),
            "v",
            color="#1f3fbf",
            ms=7,
            clip_on=False,
            label="max acting time below the grid (table.csv)",
        )
        handles.append(low)
    above = tmax > dy[-1]
    if above.any():
        (high,) = ax.plot(
            force[above],
            np.full(above.sum(), dy[-1]),
            "^",
            color="#1f3fbf",
            ms=7,
            clip_on=False,
            label="max acting time above the grid (table.csv)",
        )
        handles.append(high)
    if "max_acting_time_one_step" in t:
        one = t["max_acting_time_one_step"].to_numpy(dtype=float)[inside]
        on_grid = np.isfinite(one) & (one >= dy[0]) & (one <= dy[-1])
        if on_grid.any():
            (steps,) = ax.plot(
                force[on_grid],
                one[on_grid],
                "s--",
                lw=1.2,
                label="max acting time with one step (table.csv)",
                **TABLE_MARKS,
            )
            handles.append(steps)
    return handles


def plot_region(
    region: pd.DataFrame,
    path: str | Path,
    *,
    config: Config | None = None,
    reference: pd.DataFrame | None = None,
    table: pd.DataFrame | None = None,
) -> Path:
    """Save the outcome map (:func:`region_map`) as ``path``. ``table`` None: the table.csv in
    the folder of ``path`` is drawn when there is one (of the same convention)."""
    if table is None:
        table = _table_beside(path, region)
    fig = region_map(region, config=config, reference=reference, table=table)
    return save_png(fig, path, dpi=130)


def energy_map(region: pd.DataFrame, *, config: Config | None = None, ax=None):
    """Draw the total joint energy of a region's recovered cells.

    The energy is the integral of |tau_ankle dq_a| + |tau_hip dq_h|, on a log colour scale; the
    cells that did not recover are grey.

    Args:
        region: A region map: region.parquet's rows (:func:`sweep`'s frame).
        config: The region's configuration (its bounds and units; None: the study's).
        ax: The matplotlib Axes to draw on (None: a new figure).

    Returns:
        The Figure.
    """
    recovered = region.assign(
        energy=np.where(region["outcome"] == RECOVERED_TEXT, region["energy_total"], np.nan)
    )
    forces, durations, energy = pivot(recovered, "energy")
    log = log_durations(durations)
    fx, dy = cell_bounds(forces), cell_bounds(durations, log)
    fig, ax = new_axes(ax, (8.5, 6.5))
    ax.set_facecolor("#bdbdbd")
    positive = energy[np.isfinite(energy) & (energy > 0)]
    vmin = None
    if positive.size:
        vmax = positive.max()
        vmin = max(positive.min(), vmax * 1e-4)
        if vmin >= vmax:
            vmin = vmax / 10
        cmap = plt.get_cmap("viridis").with_extremes(under="white")
        mesh = ax.pcolormesh(
            fx,
            dy,
            np.ma.masked_invalid(energy),
            cmap=cmap,
            norm=LogNorm(vmin=vmin, vmax=vmax),
            shading="flat",
        )
        fig.colorbar(mesh, ax=ax, label="total joint energy [J]  (ankle + hip, ∫|τ·dq/dt| dt)")
    not_recovered = int((region["outcome"] != RECOVERED_TEXT).sum())
    handles = [
        Patch(
            facecolor="#bdbdbd",
            edgecolor="0.3",
            lw=0.5,
            label=f"not recovered ({not_recovered} cells): energy not shown",
        )
    ]
    if vmin is not None and np.nanmin(energy) < vmin:
        handles.append(
            Patch(
                facecolor="white",
                edgecolor="black",
                lw=0.5,
                label=f"< {vmin:.2g} J (about 0, e.g. F = 0)",
            )
        )
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.1),
        fontsize=8,
        frameon=False,
        ncol=2,
    )
    ax.set_xlabel(FORCE_LABEL)
    ax.set_xlim(fx[0], fx[-1])
    duration_axis(ax, durations, dy, log)
    ax.set_title(
        map_title("Joint energy of the recovered pushes", config, region)
        + "\n"
        + grid_text(forces, durations),
        fontsize=9,
    )
    return fig


def plot_energy(region: pd.DataFrame, path: str | Path, *, config: Config | None = None) -> Path:
    """Save the energy map (:func:`energy_map`) as ``path``."""
    return save_png(energy_map(region, config=config), path, dpi=130)


def _acting_time_axes(ax, table: pd.DataFrame, t_end: float | None) -> None:
    """Draw the max acting time against force on ``ax`` (``table`` sorted by force; t_end
    None: no configuration, so no force is marked as recovering up to t_end)."""
    force = table["force"].to_numpy(dtype=float)
    tmax = table["max_acting_time"].to_numpy(dtype=float)
    monotone = table["monotone"].astype(str).str.lower().isin(["true", "1"]).to_numpy()
    full = np.isfinite(tmax) & (t_end is not None) & np.isclose(tmax, t_end if t_end else -1)
    zero = np.isfinite(tmax) & (tmax <= 0)
    regular = np.isfinite(tmax) & ~full & ~zero

    floor = 0.005
    ax.plot(
        force[np.isfinite(tmax) & ~zero],
        tmax[np.isfinite(tmax) & ~zero],
        "-",
        color="C0",
        lw=1,
        alpha=0.6,
    )
    window = (table["ending_outcome"].astype(str) == "not_settled").to_numpy() & regular
    ax.plot(
        force[regular & monotone & ~window],
        tmax[regular & monotone & ~window],
        "o",
        color="C0",
        label="max acting time",
    )
    if (window & monotone).any():
        ax.plot(
            force[window & monotone],
            tmax[window & monotone],
            "s",
            mfc="white",
            mec="C0",
            mew=1.5,
            label="max acting time (longer pushes do not settle by t_end)",
        )
    if (regular & ~monotone).any():
        ax.plot(
            force[regular & ~monotone],
            tmax[regular & ~monotone],
            "o",
            mfc="white",
            mec="C3",
            mew=1.5,
            label="not monotone (recovers again later)",
        )
    if full.any():
        ax.plot(
            force[full],
            tmax[full],
            "^",
            color="C2",
            ms=8,
            label=f"recovers for every T up to t_end = {t_end:g} s",
        )
    if zero.any():
        ax.plot(
            force[zero],
            np.full(zero.sum(), floor),
            "x",
            color="C3",
            ms=8,
            label="fails at the shortest push (0.01 s)",
        )
    shown = tmax[np.isfinite(tmax) & (tmax > 0)]
    if zero.any() or (shown.size and shown.max() / shown.min() > 30):
        ax.set_yscale("log")  # from 0.01 s to t_end: a log axis keeps both ends readable
        _plain_log_labels(ax.yaxis)
    else:
        ax.set_ylim(0, 1.1 * shown.max() if shown.size else 1.0)
    ax.set_xlabel("push force F [N]")
    ax.set_ylabel("max acting time [s]  (resolution 0.01 s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Longest push that still recovers ({force.size} forces)", fontsize=10)


def _energy_axes(ax2, table: pd.DataFrame, convention: str) -> None:
    """Draw the energies of the recovered runs against force on ``ax2`` (``table`` sorted by
    force): the study's (eq. 20) headlined and the motors' in grey in the paper convention,
    the motors' alone in the joint one; the forces whose T = 0.1 s push did not recover are
    marked on the axis."""
    force = table["force"].to_numpy(dtype=float)
    recovered_01 = (table["outcome_01"].astype(str) == RECOVERED_TEXT).to_numpy()
    # the paper convention headlines the study's energy (eq. 20, docs/model.md), the motors'
    # absolute work beside it in grey; the joint convention, the motors' alone
    study = convention == "paper" and "study_energy_total_max" in table
    lines: list[tuple[str, str, str, dict[str, object]]]  # (column, format, label, line style)
    lines = [
        ("energy_total_01", "s-", "total, T = 0.1 s", {}),
        ("energy_total_max", "o-", "total, T = max acting time", {}),
        ("energy_ankle_max", ".--", "ankle, T = max acting time", {}),
        ("energy_hip_max", ".:", "hip, T = max acting time", {}),
    ]
    if study:
        grey = {"color": "0.55", "lw": 1, "ms": 4}
        lines = [
            ("study_energy_total_01", "s-", "study's total, T = 0.1 s", {}),
            ("study_energy_total_max", "o-", "study's total, T = max acting time", {}),
            ("study_energy_u1_max", ".--", "study's (τ1, q1), T = max acting time", {}),
            ("study_energy_u2_max", ".:", "study's (τ2, q2), T = max acting time", {}),
            (
                "energy_total_01",
                "s-",
                "motors' total ∫|τ·dq/dt|, T = 0.1 s",
                {**grey, "mfc": "white"},
            ),
            ("energy_total_max", "o-", "motors' total ∫|τ·dq/dt|, T = max acting time", grey),
        ]
    for column, fmt, label, options in lines:
        values = table[column].to_numpy(dtype=float)
        ok = np.isfinite(values) & (values > 0)
        if column.endswith("_01"):
            ok &= recovered_01  # energies of pushes that did not recover are not plotted
        if ok.any():
            ax2.plot(force[ok], values[ok], fmt, label=label, **options)
    failed_01 = ~recovered_01 & (table["outcome_01"].astype(str) != "")
    if failed_01.any():
        ax2.plot(
            force[failed_01],
            np.zeros(failed_01.sum()),
            "x",
            color="C3",
            ms=8,
            mew=2,
            transform=ax2.get_xaxis_transform(),
            clip_on=False,
            label="T = 0.1 s did not recover: energy not shown",
        )
    ax2.set_yscale("log")
    _plain_log_labels(ax2.yaxis)
    ax2.set_xlabel("push force F [N]")
    ax2.set_ylabel(
        "joint energy [J]  (study's eq. 20: |∫τ_i dq_i|; grey: ∫|τ·dq/dt| dt)"
        if study
        else "joint energy [J]  (∫|τ·dq/dt| dt)"
    )
    ax2.grid(True, which="both", alpha=0.3)
    if ax2.get_legend_handles_labels()[0]:  # none where no energy was measured
        ax2.legend(fontsize=7 if study else 8)
    ax2.set_title(
        "Energy of the recovered runs"
        + (": the study's (eq. 20), the motors' in grey" if study else ""),
        fontsize=10,
    )


def table_figure(table: pd.DataFrame, *, config: Config | None = None, axes=None):
    """Draw a robustness table: max acting time and the energies against force.

    Energies are drawn only for runs that recovered; the forces whose T = 0.1 s push did not
    recover are marked on the axis.

    Args:
        table: table.csv's rows (:func:`table`'s frame).
        config: The region's configuration (its bounds and units; None: the study's).
        axes: Two matplotlib Axes (max acting time, energies; None: a new figure).

    Returns:
        The Figure.
    """
    table = table.sort_values("force")
    t_end = config.scenario.t_end if config else None
    if axes is None:
        fig, (ax, ax2) = style.subplots(1, 2, figsize=(11, 4.8))
    else:
        ax, ax2 = axes
        fig = ax.figure
    _acting_time_axes(ax, table, t_end)
    convention = config.controller.convention if config else str(table["convention"].iloc[0])
    _energy_axes(ax2, table, convention)
    fig.suptitle(f"Robustness table — {CONVENTION_TEXT.get(convention, convention)}", fontsize=11)
    return fig


def plot_table(table: pd.DataFrame, path: str | Path, *, config: Config | None = None) -> Path:
    """Save the table's figure (:func:`table_figure`) as ``path``."""
    return save_png(table_figure(table, config=config), path, dpi=130)
