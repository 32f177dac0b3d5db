"""Time-series figures of reference runs, all scenarios overlaid (the study's experiment 1).

Input: the long time series written by ``mjx-balance simulate`` (``reference.TIMESERIES_COLUMNS``:
one row per physics step and scenario), optionally its summary rows (``summary.csv``: each
run's outcome) and configuration (the bounds). Output: one figure file per quantity (PNG; SVG
or PDF and paper sizes in a ``style.figure_style``).

Every time axis shades the push window [0, T] and ends where the action ends (the last settle
time or fall over the runs, plus a margin; ``full_window=True``: at t_end). The MPC's bounds are
drawn where they apply: the states x1, x2 and the inputs u1, u2 of the convention (figures
``states`` and ``inputs``), the CoP and CoM, and, in the joint convention where x = (q_a, q_h)
and u = (tau_ankle, tau_hip), the joint angles and motor torques too (in the paper convention
the motor torques are not bounded: u = (tau1, tau2) is, so the ankle motor may exceed the u1
bound). Every run's outcome is in the legend; a run that stops early (a fall) ends with a cross.
When runs that fell share the axes with runs that did not, the y axis is zoomed on the runs
that did not fall (a fallen run leaves the axes; its legend entry says so).

:func:`timeseries_figure` draws one quantity on a given matplotlib ``Axes`` (``ax=None``: a new
figure) and returns the Figure; :func:`timeseries_figures` writes all of them as PNG files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..model.params import Config
from ..model.config_files import load_config
from ..store.files import CONFIG
from . import style

# Okabe-Ito colours without the yellow (all with contrast on white), then darker extras.
PALETTE = [
    "#0072B2",
    "#D55E00",
    "#009E73",
    "#CC79A7",
    "#000000",
    "#E69F00",
    "#56B4E9",
    "#8C564B",
    "#7F7F7F",
    "#17BECF",
]
PUSH_COLOUR = "#f4a582"
BOUND_COLOUR = "#b2182b"
MARGIN_S = 0.5  # s after the action ends (settle or fall), and at least 25 % more
SUMMARY = "summary.csv"


@dataclass(frozen=True)
class Quantity:
    title: str
    x: str
    xlabel: str
    y: str
    ylabel: str


QUANTITIES: dict[str, Quantity] = {
    "ankle_angle": Quantity("Ankle angle", "time", "time [s]", "q_a", r"ankle angle $q_a$ [rad]"),
    "hip_angle": Quantity("Hip angle", "time", "time [s]", "q_h", r"hip angle $q_h$ [rad]"),
    "phase_ankle": Quantity(
        "Ankle phase portrait", "q_a", r"$q_a$ [rad]", "dq_a", r"$\dot q_a$ [rad/s]"
    ),
    "phase_hip": Quantity(
        "Hip phase portrait", "q_h", r"$q_h$ [rad]", "dq_h", r"$\dot q_h$ [rad/s]"
    ),
    "cop": Quantity("Centre of pressure (load cells)", "time", "time [s]", "cop", "CoP x [m]"),
    "com": Quantity("Centre of mass (whole body)", "time", "time [s]", "com", "CoM x [m]"),
    "com_vel": Quantity(
        "CoM velocity (whole body)", "time", "time [s]", "com_vel", r"$\dot x_{CoM}$ [m/s]"
    ),
    "mos": Quantity(
        "Margin of stability, push direction (< 0: XcoM beyond the foot)",
        "time",
        "time [s]",
        "mos",
        r"MoS [m]",
    ),
    "ankle_torque": Quantity(
        "Ankle motor torque", "time", "time [s]", "tau_ankle", r"$\tau_{ankle}$ [N m]"
    ),
    "hip_torque": Quantity(
        "Hip motor torque", "time", "time [s]", "tau_hip", r"$\tau_{hip}$ [N m]"
    ),
    "x1": Quantity("MPC state x1", "time", "time [s]", "x1", "x1 [rad]"),
    "x2": Quantity("MPC state x2", "time", "time [s]", "x2", "x2 [rad]"),
    "u1": Quantity("MPC input u1", "time", "time [s]", "u1", "u1 [N m]"),
    "u2": Quantity("MPC input u2", "time", "time [s]", "u2", "u2 [N m]"),
    "energy_ankle": Quantity(
        "cumulative ankle energy",
        "time",
        "time [s]",
        "energy_ankle",
        r"$\int |\tau\,\dot q|\,dt$ [J]",
    ),
    "energy_hip": Quantity(
        "cumulative hip energy", "time", "time [s]", "energy_hip", r"$\int |\tau\,\dot q|\,dt$ [J]"
    ),
    "energy_total": Quantity(
        "cumulative total energy",
        "time",
        "time [s]",
        "energy_total",
        r"$\int |\tau\,\dot q|\,dt$ [J]",
    ),
    # the study's energy (eq. 20): the magnitude of the signed work of the convention's pairs
    "study_energy_u1": Quantity(
        "study's energy (eq. 20), pair 1",
        "time",
        "time [s]",
        "study_energy_u1",
        r"$|\int u_1\,\dot x_1\,dt|$ [J]",
    ),
    "study_energy_u2": Quantity(
        "study's energy (eq. 20), pair 2",
        "time",
        "time [s]",
        "study_energy_u2",
        r"$|\int u_2\,\dot x_2\,dt|$ [J]",
    ),
    "study_energy_total": Quantity(
        "study's energy (eq. 20), total",
        "time",
        "time [s]",
        "study_energy_total",
        r"$|\int u_1 \dot x_1 dt| + |\int u_2 \dot x_2 dt|$ [J]",
    ),
}
SINGLE = [
    "ankle_angle",
    "hip_angle",
    "phase_ankle",
    "phase_hip",
    "cop",
    "com",
    "ankle_torque",
    "hip_torque",
]
PAIRS = {
    "states": ("x1", "x2"),
    "inputs": ("u1", "u2"),
    "energy": ("energy_ankle", "energy_hip", "energy_total"),
    # CoM velocity and margin of stability (Hof et al. 2005; docs/model.md)
    "balance": ("com_vel", "mos"),
}
CONVENTION_NAMES = {  # what x1, x2, u1, u2 are
    "paper": {
        "x1": "q1 (lower-body tilt)",
        "x2": "q2 (upper-body tilt)",
        "u1": "τ1 (generalised)",
        "u2": "τ2 (generalised)",
        "study_energy_u1": "|∫τ1 dq1|",
        "study_energy_u2": "|∫τ2 dq2|",
        "energy_ankle": "∫|τ_ankle dq_a| (motor)",
        "energy_hip": "∫|τ_hip dq_h| (motor)",
        "energy_total": "motors, ankle + hip",
    },
    "joint": {"x1": "q_a (ankle angle)", "x2": "q_h (hip angle)", "u1": "τ_ankle", "u2": "τ_hip"},
}
# The energy figure's rows: in the paper convention the study's definition (eq. 20, on its
# generalised pairs) heads it and the motors' absolute work is the row below; in the joint
# convention (and for a series without the study's columns) the motors' alone.
STUDY_ENERGY = ("study_energy_u1", "study_energy_u2", "study_energy_total")


def energy_rows(df: pd.DataFrame) -> list[tuple[str, ...]]:
    """The rows of quantities of the energy figure of ``df`` (see STUDY_ENERGY)."""
    paper = (df.convention == "paper").all() if len(df) else False
    if paper and all(c in df for c in STUDY_ENERGY):
        return [STUDY_ENERGY, PAIRS["energy"]]
    return [PAIRS["energy"]]


def energy_title(rows: list[tuple[str, ...]]) -> str:
    """The energy figure's heading for its rows (energy_rows)."""
    if len(rows) == 1:
        return "Joint energy (motors' absolute mechanical work ∫|τ·dq/dt| dt)"
    return (
        "Joint energy. Top: the study's (eq. 20), |∫τ_i dq_i| of the generalised pairs "
        "(τ1, q1), (τ2, q2); bottom: the motors' absolute work ∫|τ·dq/dt| dt"
    )


@dataclass
class Run:
    label: str
    frame: pd.DataFrame
    outcome: str
    end: float  # when the action ends: settle time, fall time, or the last sample
    colour: str

    @property
    def stopped(self) -> bool:
        return self.outcome in ("fell", "diverged")


def _save(fig, path: str | Path, dpi: int) -> Path:
    """Write the figure atomically (the file is whole or absent) in the current figure style
    (``style.save``), then close it; returns the path written."""
    return style.save(fig, path, dpi=dpi)


def bounds(config: Config | None, convention: str, column: str) -> tuple[float, float] | None:
    """The MPC bound that applies to a time-series column, or None (none, or no config)."""
    if config is None:
        return None
    c = config.controller
    mapping = {
        "x1": c.state1_bounds,
        "x2": c.state2_bounds,
        "u1": c.input1_bounds,
        "u2": c.input2_bounds,
        "cop": c.cop_bounds,
        "com": c.com_bounds,
    }
    if convention == "joint":
        mapping.update(
            {
                "q_a": c.state1_bounds,
                "q_h": c.state2_bounds,
                "tau_ankle": c.input1_bounds,
                "tau_hip": c.input2_bounds,
            }
        )
    value = mapping.get(column)
    return (float(value[0]), float(value[1])) if value is not None else None


def _settle_end(run: pd.DataFrame, config: Config | None) -> float:
    """Time of the last sample outside the settle band (0 if none)."""
    s = (config or Config()).scenario
    outside = (
        (run[["q_a", "q_h"]].abs() > s.settle_angle_tol).any(axis=1)
        | (run[["dq_a", "dq_h"]].abs() > s.settle_rate_tol).any(axis=1)
    ).to_numpy()
    return float(run["time"].to_numpy()[outside][-1]) if outside.any() else 0.0


def runs_of(
    df: pd.DataFrame, summary: pd.DataFrame | None = None, config: Config | None = None
) -> list[Run]:
    """The runs of a long time series, sorted by convention, duration and force, each with
    its label (force, and duration / convention where they vary), outcome and the end of its
    action. Outcomes from ``summary`` (matched on force, duration, convention) when given, else
    from the series: stopped before the last time -> fell, else recovered when the last sample
    is in the settle band, else not_settled."""
    multi_duration = df.duration.nunique() > 1
    multi_convention = df.convention.nunique() > 1
    t_last = float(df.time.max())
    outcomes = {}
    if summary is not None and len(summary):
        for row in summary.itertuples():
            outcomes[
                (round(float(row.force), 9), round(float(row.duration), 9), str(row.convention))
            ] = str(row.outcome)
    frames = [run.sort_values("time") for _, run in df.groupby("scenario", sort=False)]
    frames.sort(key=lambda r: (r.convention.iloc[0], r.duration.iloc[0], r.force.iloc[0]))
    runs = []
    for i, run in enumerate(frames):
        first = run.iloc[0]
        key = (round(float(first.force), 9), round(float(first.duration), 9), str(first.convention))
        stopped = run.time.iloc[-1] < t_last - 1e-9
        settle = _settle_end(run, config)
        outcome = outcomes.get(key) or (
            "fell" if stopped else "recovered" if settle < run.time.iloc[-1] else "not_settled"
        )
        end = float(run.time.iloc[-1]) if stopped or outcome == "not_settled" else settle
        label = f"F = {first.force:g} N"
        if multi_duration:
            label += f", T = {first.duration:g} s"
        if multi_convention:
            label += f" ({first.convention})"
        label += {
            "recovered": f": recovered (settled {settle:.2f} s)",
            "fell": f": fell at {run.time.iloc[-1]:.2f} s",
            "diverged": f": diverged at {run.time.iloc[-1]:.2f} s",
            "not_settled": ": not settled by t_end",
        }.get(outcome, f": {outcome}")
        runs.append(Run(label, run, outcome, end, PALETTE[i % len(PALETTE)]))
    return runs


def time_limit(runs: list[Run], df: pd.DataFrame, full_window: bool = False) -> float:
    """End of the time axis: t_end (the last sample) with ``full_window``, else where the
    action ends over the runs (and the push) plus max(MARGIN_S, 25 %), within t_end."""
    t_last = float(df.time.max())
    if full_window or not runs:
        return t_last
    action = max([r.end for r in runs] + [float(df.duration.max())])
    return float(min(t_last, action + max(MARGIN_S, 0.25 * action)))


def _range(runs: list[Run], column: str, t_end: float) -> tuple[float, float] | None:
    parts = [r.frame.loc[r.frame.time <= t_end, column].to_numpy(float) for r in runs]
    values = np.concatenate(parts) if parts else np.array([])
    values = values[np.isfinite(values)]
    return (float(values.min()), float(values.max())) if values.size else None


def _zoom(
    ax,
    runs: list[Run],
    column: str,
    x_column: str | None,
    limit: tuple[float, float] | None,
    t_end: float,
) -> bool:
    """Limits on the runs that did not stop (and the bounds when comparable) when runs that
    stopped go far (3 x) beyond them: the y axis, and for a phase portrait (``x_column``)
    the x axis too; True if zoomed."""
    kept = [r for r in runs if not r.stopped]
    if not kept or len(kept) == len(runs):
        return False
    inner, outer = _range(kept, column, t_end), _range(runs, column, t_end)
    if inner is None or outer is None:
        return False
    width = max(inner[1] - inner[0], 1e-9)
    if (outer[1] - outer[0]) < 3 * width:
        return False
    low, high = inner
    if limit is not None and (limit[1] - limit[0]) < 4 * width:
        low, high = min(low, limit[0]), max(high, limit[1])
    pad = 0.12 * (high - low or 1.0)
    ax.set_ylim(low - pad, high + pad)
    if x_column is not None:
        x_inner = _range(kept, x_column, t_end)
        if x_inner is not None:
            x_pad = 0.12 * (x_inner[1] - x_inner[0] or 1.0)
            ax.set_xlim(x_inner[0] - x_pad, x_inner[1] + x_pad)
    return True


def _shade_push(ax, df: pd.DataFrame) -> None:
    durations = sorted(set(float(d) for d in df.duration.unique()))
    for i, d in enumerate(durations):
        if d > 0:
            ax.axvspan(
                0.0,
                d,
                color=PUSH_COLOUR,
                alpha=0.35 if i == 0 else 0.2,
                lw=0,
                zorder=0,
                label=f"push, 0 to {d:g} s"
                if i == 0 and len(durations) == 1
                else ("push windows" if i == 0 else None),
            )


def _no_samples(ax, q: Quantity, summary: pd.DataFrame | None) -> None:
    """The panel of a quantity when no run has a sample: what happened, from the summary."""
    why = "every run ended before its first sample"
    if summary is not None and len(summary) and "outcome" in summary:
        causes = summary.get("fall_cause", pd.Series([""] * len(summary))).fillna("")
        ends = sorted(
            {f"{o}" + (f" ({c})" if c else "") for o, c in zip(summary["outcome"], causes)}
        )
        why += ": " + ", ".join(ends)
    ax.text(
        0.5,
        0.5,
        f"nothing to draw\n{why}\n(summary.csv has the outcome rows)",
        ha="center",
        va="center",
        transform=ax.transAxes,
        fontsize=10,
    )
    ax.set_title(q.title)
    ax.set_xlabel(q.xlabel)
    ax.set_ylabel(q.ylabel)
    ax.set_xticks([])
    ax.set_yticks([])


def timeseries_figure(
    df: pd.DataFrame,
    quantity: str,
    *,
    config: Config | None = None,
    summary: pd.DataFrame | None = None,
    full_window: bool = False,
    ax=None,
    legend: bool = True,
):
    """Draw one quantity of every run of :func:`simulate`'s series over time.

    The push window is shaded, the bound that applies drawn (with ``config``), the time axis
    trimmed to the action and zoomed on the runs that did not fall when a fall goes far beyond.

    Args:
        df: The time series (:func:`simulate`'s second frame).
        quantity: A key of ``QUANTITIES`` (e.g. ``"ankle_angle"``, ``"cop"``).
        config: The runs' configuration (its bounds are drawn; None: none).
        summary: The runs' summary rows (their outcomes label the lines; None: none).
        full_window: Draw up to t_end instead of trimming to the action.
        ax: The matplotlib Axes to draw on (None: a new figure).
        legend: Draw the legend.

    Returns:
        The Figure.
    """
    q = QUANTITIES[quantity]
    if ax is None:
        fig, ax = style.subplots(figsize=(7.5, 4.6))
    fig = ax.figure
    if df.empty:  # every run ended before its first sample (e.g. diverged at once)
        _no_samples(ax, q, summary)
        return fig
    runs = runs_of(df, summary, config)
    convention = str(df.convention.iloc[0])
    t_end = time_limit(runs, df, full_window)
    if q.x == "time":
        _shade_push(ax, df)
    _plot_runs(ax, runs, q, t_end)
    limit = bounds(config, convention, q.y)
    x_limit = bounds(config, convention, q.x) if q.x != "time" else None
    zoomed = _zoom(
        ax, runs, q.y, None if q.x == "time" else q.x, limit, t_end if q.x == "time" else np.inf
    )
    if limit is not None:
        _bound_lines(ax, runs, q, limit, zoomed, t_end)
    if x_limit is not None:
        for b in x_limit:
            ax.axvline(b, color=BOUND_COLOUR, ls="--", lw=1.1)
    if q.x != "time":
        ax.plot(0.0, 0.0, "k+", ms=10, label="upright")
    else:
        ax.set_xlim(0.0, t_end)
    ax.axhline(0.0, color="0.6", lw=0.6, zorder=0)
    name = CONVENTION_NAMES.get(convention, {}).get(q.y)
    title = (
        q.title
        + (f" = {name}" if name else "")
        + (f";  MPC bound [{limit[0]:g}, {limit[1]:g}]" if limit is not None else "")
    )
    notes = []
    if zoomed:
        notes.append("zoomed on the runs that did not fall")
    if q.x == "time" and not full_window and t_end < float(df.time.max()) - 1e-9:
        notes.append(f"trimmed at {t_end:.2f} s of t_end = {float(df.time.max()):g} s")
    if convention == "paper" and q.y in ("tau_ankle", "tau_hip"):
        notes.append("paper convention: the MPC bounds u = (τ1, τ2), not this motor torque")
    ax.set(
        title=title + ("\n(" + "; ".join(notes) + ")" if notes else ""),
        xlabel=q.xlabel,
        ylabel=q.ylabel,
    )
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    if zoomed:
        _overview(ax, runs, q, limit, x_limit, t_end, df)
    if legend:
        ax.legend(
            fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, frameon=False
        )
    return fig


def _plot_runs(ax, runs: list[Run], q: Quantity, t_end: float) -> None:
    """Draw every run's curve (up to ``t_end`` against time), a cross where a run stopped."""
    for run in runs:
        frame = run.frame[run.frame.time <= t_end + 1e-9] if q.x == "time" else run.frame
        ax.plot(frame[q.x], frame[q.y], color=run.colour, lw=1.4, label=run.label)
        if run.stopped and len(frame) == len(run.frame):
            ax.plot(frame[q.x].iloc[-1], frame[q.y].iloc[-1], "x", color=run.colour, ms=9, mew=2.2)


def _bound_lines(
    ax, runs: list[Run], q: Quantity, limit: tuple[float, float], zoomed: bool, t_end: float
) -> None:
    """Draw the MPC bound ``limit``, the view kept on the runs if far bounds would flatten them."""
    fixed = zoomed
    data = _range(runs, q.y, t_end if q.x == "time" else np.inf)
    if not zoomed and data is not None:
        width = max(data[1] - data[0], 1e-9)
        if limit[1] - limit[0] > 4 * width:  # far bounds would flatten the runs
            pad = 0.12 * width
            ax.set_ylim(data[0] - pad, data[1] + pad)
            fixed = True
    low, high = ax.get_ylim()
    hidden = fixed and (limit[0] < low or limit[1] > high)
    for i, b in enumerate(limit):
        ax.axhline(
            b,
            color=BOUND_COLOUR,
            ls="--",
            lw=1.1,
            label=(
                f"MPC bound [{limit[0]:g}, {limit[1]:g}]"
                + (" (partly outside the view)" if hidden else "")
            )
            if i == 0
            else None,
        )
    if fixed:
        ax.set_ylim(low, high)


INSET_CORNERS = (
    [0.64, 0.58, 0.34, 0.36],
    [0.64, 0.33, 0.34, 0.36],
    [0.64, 0.11, 0.34, 0.36],
    [0.11, 0.58, 0.34, 0.36],
    [0.11, 0.11, 0.34, 0.36],
    [0.38, 0.33, 0.34, 0.36],
)


def _emptiest_corner(ax, runs: list[Run], q: Quantity, t_end: float) -> list[float]:
    """The inset place (INSET_CORNERS, the first that does best) that covers the fewest of
    the axes' 40 x 40 cells that a run passes through."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    xs, ys = [], []
    for run in runs:
        frame = run.frame[run.frame.time <= t_end + 1e-9] if q.x == "time" else run.frame
        xs.append((frame[q.x].to_numpy(float) - x0) / ((x1 - x0) or 1.0))
        ys.append((frame[q.y].to_numpy(float) - y0) / ((y1 - y0) or 1.0))
    x, y = np.concatenate(xs), np.concatenate(ys)
    inside = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x < 1) & (y >= 0) & (y < 1)
    cells = {(int(a * 40), int(b * 40)) for a, b in zip(x[inside], y[inside])}
    centres = np.array([((i + 0.5) / 40, (j + 0.5) / 40) for i, j in cells]).reshape(-1, 2)

    def covered(box):
        return int(
            (
                (centres[:, 0] >= box[0] - 0.03)
                & (centres[:, 0] <= box[0] + box[2] + 0.03)
                & (centres[:, 1] >= box[1] - 0.03)
                & (centres[:, 1] <= box[1] + box[3] + 0.03)
            ).sum()
        )

    return min(INSET_CORNERS, key=covered)


def _overview(
    ax, runs: list[Run], q: Quantity, limit, x_limit, t_end: float, df: pd.DataFrame
) -> None:
    """An inset at full scale (every run, the bounds) beside a zoomed axes; the zoomed range
    is shaded grey in it."""
    low, high = ax.get_ylim()
    inset = ax.inset_axes(_emptiest_corner(ax, runs, q, t_end))
    if q.x == "time":
        _shade_push(inset, df)
    for run in runs:
        frame = run.frame[run.frame.time <= t_end + 1e-9] if q.x == "time" else run.frame
        inset.plot(frame[q.x], frame[q.y], color=run.colour, lw=0.9)
        if run.stopped and len(frame) == len(run.frame):
            inset.plot(frame[q.x].iloc[-1], frame[q.y].iloc[-1], "x", color=run.colour, ms=5)
    for b in limit or ():
        inset.axhline(b, color=BOUND_COLOUR, ls="--", lw=0.8)
    for b in x_limit or ():
        inset.axvline(b, color=BOUND_COLOUR, ls="--", lw=0.8)
    inset.axhspan(low, high, color="0.5", alpha=0.25, lw=0, label="zoomed range")
    if q.x == "time":
        inset.set_xlim(0.0, t_end)
    inset.tick_params(labelsize=6)
    inset.set_title("full scale (grey: the zoomed range)", fontsize=6, pad=2)
    inset.set_facecolor("white")


def _subtitle(df: pd.DataFrame, config: Config | None) -> str:
    if df.empty:
        return "no samples"
    conventions = ", ".join(sorted(df.convention.unique()))
    text = f"convention: {conventions}"
    if df.duration.nunique() == 1:
        text += f", push duration T = {df.duration.iloc[0]:g} s (shaded)"
    if config is None:
        text += "; no configuration: bounds not drawn"
    return text + ";  x = run stopped (fell)"


def timeseries_figures(
    df: pd.DataFrame,
    out_dir: str | Path,
    *,
    config: Config | None = None,
    summary: pd.DataFrame | None = None,
    full_window: bool = False,
) -> list[Path]:
    """Write the time-series figures of ``df`` into ``out_dir`` (in the current figure style:
    ``style.save``); return their paths.

    config: the bounds to draw (None: ``out_dir/config.toml`` if there is one); summary: the
    runs' outcomes (None: ``out_dir/summary.csv`` if there is one, else read from the series);
    full_window: time axes up to t_end instead of trimmed to the action.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if config is None and (out_dir / CONFIG).exists():
        try:
            config = load_config(out_dir / CONFIG)
        except Exception:
            config = None
    if summary is None and (out_dir / SUMMARY).exists():
        try:
            summary = pd.read_csv(out_dir / SUMMARY)
        except Exception:
            summary = None
    options: dict[str, Any] = {"config": config, "summary": summary, "full_window": full_window}
    paths = []
    for stem in SINGLE:
        fig = timeseries_figure(df, stem, **options)
        fig.suptitle(_subtitle(df, config), fontsize=8)
        paths.append(_save(fig, out_dir / f"{stem}.png", dpi=120))
    for stem, quantities in PAIRS.items():
        if not set(quantities) <= set(df.columns):  # a series written before these columns
            continue
        rows = energy_rows(df) if stem == "energy" else [quantities]
        width = max(len(r) for r in rows)
        fig, axes = style.subplots(
            len(rows), width, figsize=(6.5 * width, 4.6 * len(rows)), squeeze=False
        )
        for r, row in enumerate(rows):
            for i, (ax, quantity) in enumerate(zip(axes[r], row)):
                timeseries_figure(
                    df, quantity, ax=ax, legend=i == 0 and r == len(rows) - 1, **options
                )
        fig.suptitle(
            {
                "states": "MPC states",
                "inputs": "MPC inputs",
                "energy": energy_title(rows),
                "balance": "CoM velocity and margin of stability (XcoM, Hof et al. 2005)",
            }[stem]
            + f";  {_subtitle(df, config)}",
            fontsize=9,
        )
        paths.append(_save(fig, out_dir / f"{stem}.png", dpi=120))
    return paths
