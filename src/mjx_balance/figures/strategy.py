"""The strategy map: which strategy the recovered body uses over the force x duration plane.

strategy_map / plot_strategy      the hip's share of the motors' work in every recovered cell
                                  (``measures.strategy``), the recovery boundary and the line where
                                  the hip takes over (share above the threshold)
threshold_figure / plot_threshold how the map moves with the threshold: the share's histogram
                                  over the recovered cells, and the take-over line for several
                                  thresholds on one plane
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..measures.strategy import HIP_SHARE_THRESHOLD, hip_share
from ..model.params import Config
from . import region as region_plots
from . import style

# Colour-blind-safe (Okabe-Ito) colours for the take-over lines of several thresholds.
OKABE_ITO = style.SERIES
THRESHOLDS = (0.15, 0.2, 0.25, 0.3, 0.4, 0.5)


def strategy_map(
    region: pd.DataFrame,
    *,
    config: Config | None = None,
    threshold: float = HIP_SHARE_THRESHOLD,
    ax=None,
):
    """Draw the hip's share of the motors' work in each recovered cell.

    The cells that did not recover are grey; the recovery boundary is black and the hip's
    take-over line at ``threshold`` dashed.

    Args:
        region: A region map: region.parquet's rows (:func:`sweep`'s frame).
        config: The region's configuration (its bounds and units; None: the study's).
        threshold: The hip's share above which a recovery counts as ``hip_ankle``.
        ax: The matplotlib Axes to draw on (None: a new figure).

    Returns:
        The Figure.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    import matplotlib.pyplot as plt

    recovered = region["outcome"] == region_plots.RECOVERED_TEXT
    shown = region.assign(share=np.where(recovered, hip_share(region), np.nan))
    forces, durations, share = region_plots.pivot(shown, "share")
    log = region_plots.log_durations(durations)
    fx, dy = region_plots.cell_bounds(forces), region_plots.cell_bounds(durations, log)
    fig, ax = region_plots.new_axes(ax, (8.5, 7.0))
    ax.set_facecolor("#bdbdbd")
    mesh = ax.pcolormesh(
        fx, dy, np.ma.masked_invalid(share), cmap="cividis", vmin=0, vmax=1, shading="flat"
    )
    fig.colorbar(mesh, ax=ax, label="hip's share of the motors' work  ∫|τ_hip q̇_h| / total")
    ax.set_xlim(fx[0], fx[-1])
    region_plots.duration_axis(ax, durations, dy, log)
    handles: list[Patch | Line2D]
    handles = [
        Patch(
            facecolor="#bdbdbd",
            edgecolor="0.3",
            lw=0.5,
            label=f"not recovered ({int((~recovered).sum())} cells)",
        )
    ]
    handles.append(region_plots.boundary_line(ax, region, fx, dy))
    over = region_plots.takeover_line(
        ax, region, threshold, fx, dy, color=region_plots.TAKEOVER_COLOUR, lw=2.2, ls="--"
    )
    handles.append(
        over
        if over is not None
        else Line2D([], [], color=region_plots.TAKEOVER_COLOUR, lw=2.2, ls="--")
    )
    handles[-1].set_label(
        f"hip takes over: share > {threshold:g} above the line"
        + ("" if over is not None else " (no cell)")
    )
    ax.set_xlabel(region_plots.FORCE_LABEL)
    ax.set_title(
        region_plots.map_title("Recovery strategy: the hip's share of the work", config, region)
        + "\n"
        + region_plots.grid_text(forces, durations),
        fontsize=9,
    )
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.1),
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    plt.setp(ax.get_xticklabels(), fontsize=8)
    return fig


def threshold_figure(
    region: pd.DataFrame,
    *,
    config: Config | None = None,
    thresholds: tuple[float, ...] = THRESHOLDS,
    threshold: float = HIP_SHARE_THRESHOLD,
):
    """How the strategy map moves with its threshold: left, the histogram of the hip's share
    over the recovered cells (the chosen threshold marked); right, the take-over line of each
    threshold on the force x duration plane with the recovery boundary. Returns the Figure."""
    recovered = region[region["outcome"] == region_plots.RECOVERED_TEXT]
    share = hip_share(recovered)
    share = share[np.isfinite(share)]
    fig, (left, right) = style.subplots(
        1, 2, figsize=(12, 5.2), gridspec_kw={"width_ratios": [1, 1.4]}
    )
    left.hist(share, bins=np.linspace(0, 1, 41), color="0.45")
    for i, t in enumerate(thresholds):
        share_above = float((share > t).mean()) if share.size else float("nan")
        left.axvline(
            t,
            color=OKABE_ITO[i % len(OKABE_ITO)],
            lw=2.4 if t == threshold else 1.2,
            ls="-" if t == threshold else ":",
            label=f"{t:g}: {share_above:.0%} hip_ankle" + (" (default)" if t == threshold else ""),
        )
    left.set_xlabel("hip's share of the motors' work")
    left.set_ylabel(f"recovered cells (of {len(recovered)}; F = 0 has none)")
    left.legend(fontsize=8, title="threshold: cells above it", title_fontsize=8)
    left.set_title("Distribution over the recovered cells", fontsize=10)

    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    log = region_plots.log_durations(durations)
    fx, dy = region_plots.cell_bounds(forces), region_plots.cell_bounds(durations, log)
    region_plots.boundary_line(right, region, fx, dy)
    for i, t in enumerate(thresholds):
        region_plots.takeover_line(
            right,
            region,
            t,
            fx,
            dy,
            color=OKABE_ITO[i % len(OKABE_ITO)],
            lw=2.4 if t == threshold else 1.4,
            ls="--",
            label=f"hip takes over, {t:g}",
        )
    right.set_xlim(fx[0], fx[-1])
    region_plots.duration_axis(right, durations, dy, log)
    right.set_xlabel(region_plots.FORCE_LABEL)
    right.legend(fontsize=8, loc="upper right")
    right.set_title("Where the hip takes over, per threshold", fontsize=10)
    fig.suptitle(
        region_plots.map_title("How the strategy map moves with its threshold", config, region),
        fontsize=10,
    )
    return fig


def plot_strategy(region: pd.DataFrame, path: str | Path, *, config: Config | None = None) -> Path:
    """Save :func:`strategy_map` as ``path``."""
    return region_plots.save_png(strategy_map(region, config=config), path, dpi=130)


def plot_threshold(region: pd.DataFrame, path: str | Path, *, config: Config | None = None) -> Path:
    """Save :func:`threshold_figure` as ``path``."""
    return region_plots.save_png(threshold_figure(region, config=config), path, dpi=110)
