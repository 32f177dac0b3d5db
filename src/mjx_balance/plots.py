"""Time-series figures of reference runs, all scenarios overlaid (the study's experiment 1).

Input: the long time series written by ``mjx-balance simulate`` (``reference.TIMESERIES_COLUMNS``:
one row per physics step and scenario). Output: PNG files, one per quantity. A run that stops
early (a fall) ends with a cross.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .sweep.store import write_figure  # noqa: E402

# (file stem, title, x column, x label, y column, y label)
_SINGLE = [
    ("ankle_angle", "Ankle angle", "time", "time [s]", "q_a", r"ankle angle $q_a$ [rad]"),
    ("hip_angle", "Hip angle", "time", "time [s]", "q_h", r"hip angle $q_h$ [rad]"),
    ("phase_ankle", "Ankle phase portrait", "q_a", r"$q_a$ [rad]", "dq_a", r"$\dot q_a$ [rad/s]"),
    ("phase_hip", "Hip phase portrait", "q_h", r"$q_h$ [rad]", "dq_h", r"$\dot q_h$ [rad/s]"),
    ("cop", "Centre of pressure (load cells)", "time", "time [s]", "cop", "CoP x [m]"),
    ("com", "Centre of mass (whole body)", "time", "time [s]", "com", "CoM x [m]"),
    ("ankle_torque", "Ankle motor torque", "time", "time [s]", "tau_ankle",
     r"$\tau_{ankle}$ [N m]"),
    ("hip_torque", "Hip motor torque", "time", "time [s]", "tau_hip", r"$\tau_{hip}$ [N m]"),
]
_ENERGY = [("energy_ankle", "ankle"), ("energy_hip", "hip"), ("energy_total", "total")]


def _save(fig, path: str | Path, dpi: int) -> None:
    """Write the figure atomically (the file is whole or absent), then close it."""
    try:
        write_figure(fig, path, dpi=dpi)
    finally:
        plt.close(fig)


def _label(run: pd.DataFrame, multi_duration: bool, multi_convention: bool) -> str:
    first = run.iloc[0]
    label = f"F = {first.force:g} N"
    if multi_duration:
        label += f", T = {first.duration:g} s"
    if multi_convention:
        label += f" ({first.convention})"
    return label


def _runs(df: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    multi_duration = df.duration.nunique() > 1
    multi_convention = df.convention.nunique() > 1
    runs = [run for _, run in df.groupby("scenario", sort=False)]
    runs.sort(key=lambda r: (r.convention.iloc[0], r.duration.iloc[0], r.force.iloc[0]))
    return [(_label(r, multi_duration, multi_convention), r) for r in runs]


def _plot_runs(ax, runs, x: str, y: str, t_last: float) -> None:
    colors = plt.cm.viridis(np.linspace(0.0, 0.9, max(len(runs), 1)))
    for (label, run), color in zip(runs, colors):
        ax.plot(run[x], run[y], color=color, lw=1.2, label=label)
        if run.time.iloc[-1] < t_last - 1e-9:  # stopped early: fell (or diverged)
            ax.plot(run[x].iloc[-1], run[y].iloc[-1], "x", color=color, ms=8, mew=2)


def _subtitle(df: pd.DataFrame) -> str:
    conventions = ", ".join(sorted(df.convention.unique()))
    text = f"convention: {conventions}"
    if df.duration.nunique() == 1:
        text += f", push duration T = {df.duration.iloc[0]:g} s"
    return text + ";  x = run stopped (fell)"


def timeseries_figures(df: pd.DataFrame, out_dir: str | Path) -> list[Path]:
    """Write the time-series figures of ``df`` into ``out_dir``; return the PNG paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    runs = _runs(df)
    t_last = float(df.time.max())
    paths = []
    for stem, title, x, xlabel, y, ylabel in _SINGLE:
        fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
        _plot_runs(ax, runs, x, y, t_last)
        if x != "time":
            ax.plot(0.0, 0.0, "k+", ms=10, label="upright")
        ax.axhline(0.0, color="0.6", lw=0.6, zorder=0)
        ax.set(title=f"{title}\n{_subtitle(df)}", xlabel=xlabel, ylabel=ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        path = out_dir / f"{stem}.png"
        _save(fig, path, dpi=120)
        paths.append(path)

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2), constrained_layout=True, sharey=False)
    for ax, (column, name) in zip(axes, _ENERGY):
        _plot_runs(ax, runs, "time", column, t_last)
        ax.set(title=f"cumulative {name} energy", xlabel="time [s]",
               ylabel=r"$\int |\tau\,\dot q|\,dt$ [J]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="center right")
    fig.suptitle(f"Joint energy (absolute mechanical work);  {_subtitle(df)}")
    path = out_dir / "energy.png"
    _save(fig, path, dpi=120)
    paths.append(path)
    return paths
