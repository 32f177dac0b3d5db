"""The report's own figures, drawn from a report folder's saved tables into DIR/figures: the
weight study's bars, the conventions side by side, and the experiments' and studies' figures
(from figures.timeseries and figures.region), each saved atomically and closed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..measures.outcomes import OUTCOMES, RECOVERED
from ..model.params import Config
from ..model.config_files import config_from_dict
from ..store.files import write_figure
from . import region as region_plots
from . import timeseries as plots


# The weight study's bars: the study's energy (eq. 20, docs/model.md) heads the paper
# convention's figure, the motors' absolute work in the row below; the joint convention's, the
# motors' alone (weight_rows).
MOTOR_BARS = [
    ("energy_ankle", "ankle motor", "#0072B2"),
    ("energy_hip", "hip motor", "#D55E00"),
    ("energy_total", "total", "0.3"),
]
STUDY_BARS = [
    ("study_energy_u1", "(τ1, q1)", "#009E73"),
    ("study_energy_u2", "(τ2, q2)", "#CC79A7"),
    ("study_energy_total", "total", "0.3"),
]


def weight_rows(weights: pd.DataFrame, convention: str) -> list[tuple[list, str]]:
    """The bar rows of the weight figure: (parts, y label), the headline first."""
    motor = (MOTOR_BARS, r"motors' energy $\int|\tau\,\dot q|\,dt$ [J]")
    if convention == "paper" and all(c in weights for c, _, _ in STUDY_BARS):
        return [(STUDY_BARS, r"study's energy (eq. 20) $|\int\tau_i\,\dot q_i\,dt|$ [J]"), motor]
    return [motor]


def weight_figure(weights: pd.DataFrame, convention: str, axes=None):
    """Bar charts of the energies for each Q and each R weight setting.

    In the paper convention the study's energy (its eq. 20) on top and the motors' below; in the
    joint convention the motors'. A setting that did not recover has no bars, only its outcome.

    Args:
        weights: A report's weight-study rows.
        convention: ``"paper"`` or ``"joint"``.
        axes: The Axes to draw on, two per row (two: the headline row only; None: a new figure).

    Returns:
        The Figure.
    """
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    rows = weight_rows(weights, convention)
    if axes is None:
        fig, axes = plt.subplots(
            len(rows), 2, figsize=(12, 4.6 * len(rows)), layout="constrained", squeeze=False
        )
    else:
        axes = np.asarray(axes, dtype=object).reshape(-1, 2)
        fig = axes[0, 0].figure
    handles, labels = [], []
    for (parts, ylabel), row_axes in zip(rows, axes):
        _weight_bars(row_axes, weights, parts, ylabel)
        handles += [Patch(color=colour) for _, _, colour in parts]
        which = "study" if parts is STUDY_BARS else "motors"
        labels += [name if len(rows) == 1 else f"{name} ({which})" for _, name, _ in parts]
    if (weights["outcome"] != OUTCOMES[RECOVERED]).any():
        handles.append(Patch(facecolor="white", edgecolor="white"))
        labels.append(
            "a setting that did not recover: no bars (an energy of a fall is not a "
            "recovery cost), its outcome written instead"
        )
    fig.legend(handles, labels, loc="outside lower center", ncol=4, fontsize=8, frameon=False)
    force = weights["force"].iloc[0]
    duration = weights["duration"].iloc[0]
    fig.suptitle(
        f"Weight study, {convention} convention: F = {force:g} N, T = {duration:g} s"
        + ("; top: the study's energy (eq. 20), bottom: the motors'" if len(rows) > 1 else ""),
        fontsize=11,
    )
    return fig


def _weight_bars(axes, weights: pd.DataFrame, parts: list, ylabel: str) -> None:
    """One row of the weight figure: the bars of ``parts`` for the Q and the R settings."""
    for ax, which, label in (
        (axes[0], "Q", r"Q = s$\cdot$I$_4$  (R default)"),
        (axes[1], "R", r"R = s$\cdot$diag(1000, 1)  (Q default)"),
    ):
        rows = weights[weights["weight"] == which].reset_index(drop=True)
        x = np.arange(len(rows))
        ok = (rows["outcome"] == OUTCOMES[RECOVERED]).to_numpy()
        for j, (column, _name, colour) in enumerate(parts):
            values = rows[column].to_numpy(float)
            values = np.where(values > 0, values, np.nan)
            ax.bar(x[ok] + (j - 1) * 0.27, values[ok], 0.27, color=colour)
        for i, row in rows.iterrows():
            if row["outcome"] != OUTCOMES[RECOVERED]:
                ax.annotate(
                    row["outcome"],
                    (i, 0.5),
                    xycoords=("data", "axes fraction"),
                    ha="center",
                    va="center",
                    rotation=90,
                    fontsize=9,
                    color="#b2182b",
                )
        ax.set_xticks(x, [f"{s:.0e}" for s in rows["scale"]])
        ax.set_xlim(-0.6, len(rows) - 0.4)  # every setting's slot, with or without bars
        values = rows.loc[ok, [c for c, _, _ in parts]].to_numpy(float)
        positive = values[np.isfinite(values) & (values > 0)]
        if positive.size and positive.max() / positive.min() > 100:
            ax.set_yscale("log")  # the energies span decades
        else:
            ax.set_ylim(0, 1.15 * (positive.max() if positive.size else 1.0))
        ax.set_xlabel(f"s, {label}")
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", which="both", alpha=0.3)


def conventions_figure(tables: dict[str, pd.DataFrame], ax=None):
    """Draw max acting time against force, one line per convention.

    Args:
        tables: Convention -> its robustness table.
        ax: The matplotlib Axes to draw on (None: a new figure).

    Returns:
        The Figure.
    """
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4.2), layout="constrained")
    fig = ax.figure
    for i, (convention, table) in enumerate(tables.items()):
        t = table.sort_values("force")
        ax.plot(
            t["force"],
            np.maximum(t["max_acting_time"], 0.005),
            "o-",
            color=f"C{i}",
            label=convention,
        )
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


def draw_timeseries(
    series: pd.DataFrame,
    figures: Path,
    convention: str,
    config: Config | None = None,
    summary: pd.DataFrame | None = None,
) -> dict[str, Path]:
    """The time-series figures of one convention, by name (plots.timeseries_figures)."""
    folder = figures / f"timeseries_{convention}"
    return {
        p.stem: p for p in plots.timeseries_figures(series, folder, config=config, summary=summary)
    }


def draw_weights(
    weights: pd.DataFrame, figures: Path, convention: str, name: str = "weights"
) -> Path:
    """The weight study's energy bars of one convention (weight_figure), as
    ``figures/<name>_<convention>.png``."""
    return save_figure(weight_figure(weights, convention), figures / f"{name}_{convention}.png")


def draw_table(table: pd.DataFrame, figures: Path, config: Config) -> Path:
    """The max acting time and energies of one convention's table (region_plots.plot_table)."""
    convention = config.controller.convention
    return region_plots.plot_table(table, figures / f"table_{convention}.png", config=config)


def region_figure(figures: Path, convention: str) -> Path:
    """Where the outcome map of a convention's region is drawn."""
    return figures / f"region_{convention}.png"


def draw_region(
    region: pd.DataFrame, figures: Path, config: Config, table: pd.DataFrame | None = None
) -> tuple[Path, Path]:
    """The outcome map (with the table's max acting time) and the energy map of one
    convention's region."""
    convention = config.controller.convention
    outcome = region_plots.plot_region(
        region,
        region_figure(figures, convention),
        config=config,
        table=table if table is not None else pd.DataFrame(),
    )
    energy = region_plots.plot_energy(
        region, figures / f"region_energy_{convention}.png", config=config
    )
    return outcome, energy


def draw_study(key: str, res: dict, figures: Path) -> list[tuple[Path, str]]:
    """The outcome map of every variant of a study, with its label."""
    drawn = []
    for variant in res["variants"]:
        path = region_plots.plot_region(
            res["regions"][variant["key"]],
            figures / f"study_{key}_{variant['key']}.png",
            config=config_from_dict(variant["config"]),
            table=pd.DataFrame(),
        )
        drawn.append((path, variant["label"]))
    return drawn
