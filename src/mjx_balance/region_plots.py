"""Figures of sweep results (matplotlib, Agg): the recoverable region, its energy, the table curve.

All three are drawn from saved tables (``region.parquet``, ``table.csv``):

plot_region   outcome of every cell over force x duration, discrete colours, with the recovery
              boundary (per force, the top of the first recovered range of durations) and
              optional reference points
plot_energy   total joint energy of the recovered cells (log colour scale)
plot_table    max acting time against force, and the energies at 0.1 s and at the max acting time
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

from .outcomes import OUTCOMES, RECOVERED  # noqa: E402
from .params import Config, ParameterError  # noqa: E402
from .sweep.store import write_figure  # noqa: E402

RECOVERED_TEXT = OUTCOMES[RECOVERED]

OUTCOME_COLOURS = {
    "recovered": "#4daf4a",
    "not_settled": "#ffd92f",
    "fell": "#e41a1c",
    "diverged": "#3a3a3a",
}
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


def _save(fig, path: str | Path, dpi: int) -> None:
    """Write the figure atomically (the file is whole or absent), then close it."""
    try:
        write_figure(fig, path, dpi=dpi)
    finally:
        plt.close(fig)


def load_reference(path: str | Path) -> pd.DataFrame:
    """Reference points to draw over the region map: a CSV with columns force, duration
    (an optional column ``label`` names the source in the legend)."""
    path = Path(path)
    try:
        frame = pd.read_csv(path)
    except FileNotFoundError:
        raise ParameterError(f"reference points file not found: {path}") from None
    except Exception as exc:  # noqa: BLE001
        raise ParameterError(f"{path}: not a readable CSV ({exc})") from None
    frame.columns = [str(c).strip().lower() for c in frame.columns]
    missing = [c for c in ("force", "duration") if c not in frame]
    if missing:
        raise ParameterError(f"{path}: needs columns force, duration; missing {', '.join(missing)}")
    values = frame[["force", "duration"]].apply(pd.to_numeric, errors="coerce")
    if values.isna().any().any() or len(values) == 0:
        raise ParameterError(f"{path}: force and duration must be numbers (and at least one row)")
    frame[["force", "duration"]] = values
    return frame


def _edges(values: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (midpoints; the ends extend by half a neighbour gap)."""
    values = np.asarray(values, dtype=float)
    if values.size == 1:
        half = 0.5 * max(abs(values[0]) * 0.1, 0.01)
        return np.array([values[0] - half, values[0] + half])
    mid = 0.5 * (values[1:] + values[:-1])
    return np.concatenate([[values[0] - (mid[0] - values[0])], mid,
                           [values[-1] + (values[-1] - mid[-1])]])


def _pivot(region: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    table = region.pivot(index="duration", columns="force", values=column)
    table = table.reindex(index=durations, columns=forces)
    return forces, durations, table.to_numpy()


def recovery_boundary(region: pd.DataFrame) -> pd.DataFrame:
    """Per force, the longest grid duration up to which every grid duration recovered
    (0 if the shortest fails), and whether a longer duration recovers again (not monotone)."""
    rows = []
    for force, group in region.sort_values("duration").groupby("force"):
        ok = (group["outcome"] == RECOVERED_TEXT).to_numpy()
        durations = group["duration"].to_numpy()
        first_fail = int(np.argmin(ok)) if not ok.all() else ok.size
        rows.append({"force": force,
                     "boundary": durations[first_fail - 1] if first_fail else 0.0,
                     "first_failure": durations[first_fail] if first_fail < ok.size else np.nan,
                     "monotone": not ok[first_fail:].any()})
    return pd.DataFrame(rows)


def _title(kind: str, config: Config | None, region: pd.DataFrame) -> str:
    convention = config.controller.convention if config else str(region["convention"].iloc[0])
    t_end = f", recovery within t_end = {config.scenario.t_end:g} s" if config else ""
    return f"{kind}\n{CONVENTION_TEXT.get(convention, convention)}{t_end}"


def plot_region(region: pd.DataFrame, path: str | Path, *, config: Config | None = None,
                reference: pd.DataFrame | None = None) -> Path:
    """Outcome heatmap over force x duration with the recovery boundary."""
    forces, durations, outcome = _pivot(region, "outcome")
    codes = np.full(outcome.shape, np.nan)
    for code, name in enumerate(OUTCOMES):
        codes[outcome == name] = code
    cmap = ListedColormap([OUTCOME_COLOURS[name] for name in OUTCOMES]).with_extremes(bad="white")
    norm = BoundaryNorm(np.arange(len(OUTCOMES) + 1) - 0.5, cmap.N)

    fig, ax = plt.subplots(figsize=(8.5, 7), layout="constrained")
    fx, dy = _edges(forces), _edges(durations)
    ax.pcolormesh(fx, dy, np.ma.masked_invalid(codes), cmap=cmap, norm=norm, shading="flat")

    # Boundary: a step line along the top of each force's first recovered range.
    boundary = recovery_boundary(region).set_index("force").reindex(forces)
    d_index = {d: i for i, d in enumerate(durations)}
    tops = np.array([dy[d_index[b] + 1] if b in d_index else dy[0]
                     for b in boundary["boundary"].to_numpy()])
    xs = np.repeat(fx, 2)[1:-1]
    ys = np.repeat(tops, 2)
    ax.plot(xs, ys, color="black", lw=2.0, label="recovery boundary (max acting time on the grid)")
    if not boundary["monotone"].all():
        odd = boundary.index[~boundary["monotone"].to_numpy()]
        ax.plot(odd, np.full(odd.size, dy[-1]), "v", color="black", ms=6, clip_on=False,
                label="force with recovery beyond a failure (not monotone)")

    handles = [Patch(color=OUTCOME_COLOURS[n], label=OUTCOME_LABELS[n]) for n in OUTCOMES
               if (outcome == n).any()]
    handles += ax.get_legend_handles_labels()[0]
    if reference is not None and len(reference):
        label = str(reference["label"].iloc[0]) if "label" in reference else "reference points"
        (ref,) = ax.plot(reference["force"], reference["duration"], "o", mfc="white", mec="black",
                         mew=1.5, ms=6, label=label)
        handles.append(ref)
    counts = region["outcome"].value_counts()
    summary = ", ".join(f"{counts.get(n, 0)} {n}" for n in OUTCOMES if counts.get(n, 0))
    ax.set_xlabel("push force F [N]  (+ forward)")
    ax.set_ylabel("push duration T [s]")
    ax.set_xlim(fx[0], fx[-1])
    ax.set_ylim(dy[0], dy[-1])
    ax.set_title(_title("Outcome of a push (F, T) from upright rest", config, region), fontsize=10)
    fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=8, frameon=False,
               title=f"{len(region)} cells: {summary}", title_fontsize=8)
    _save(fig, path, dpi=130)
    return Path(path)


def plot_energy(region: pd.DataFrame, path: str | Path, *, config: Config | None = None) -> Path:
    """Total joint energy (∫|τ_ankle dq_a| + |τ_hip dq_h| dt) of the recovered cells, log scale."""
    recovered = region.assign(energy=np.where(region["outcome"] == RECOVERED_TEXT,
                                              region["energy_total"], np.nan))
    forces, durations, energy = _pivot(recovered, "energy")
    fig, ax = plt.subplots(figsize=(8.5, 6), layout="constrained")
    fx, dy = _edges(forces), _edges(durations)
    ax.set_facecolor("#d9d9d9")
    positive = energy[np.isfinite(energy) & (energy > 0)]
    if positive.size:
        vmax = positive.max()
        vmin = max(positive.min(), vmax * 1e-4)
        if vmin >= vmax:
            vmin = vmax / 10
        cmap = plt.get_cmap("viridis").with_extremes(under="white")
        mesh = ax.pcolormesh(fx, dy, np.ma.masked_invalid(energy), cmap=cmap,
                             norm=LogNorm(vmin=vmin, vmax=vmax), shading="flat")
        fig.colorbar(mesh, ax=ax, label="total joint energy [J]  (ankle + hip, ∫|τ·dq/dt| dt)")
    handles = [Patch(color="#d9d9d9", label="not recovered")]
    if positive.size and np.nanmin(energy) < vmin:
        handles.append(Patch(facecolor="white", edgecolor="black", lw=0.5,
                             label=f"< {vmin:.2g} J (about 0, e.g. F = 0)"))
    ax.legend(handles=handles, loc="upper right", fontsize=8)
    ax.set_xlabel("push force F [N]  (+ forward)")
    ax.set_ylabel("push duration T [s]")
    ax.set_xlim(fx[0], fx[-1])
    ax.set_ylim(dy[0], dy[-1])
    ax.set_title(_title("Joint energy of the recovered pushes", config, region), fontsize=10)
    _save(fig, path, dpi=130)
    return Path(path)


def plot_table(table: pd.DataFrame, path: str | Path, *, config: Config | None = None) -> Path:
    """Max acting time against force (left) and the energies of the table (right)."""
    table = table.sort_values("force")
    t_end = config.scenario.t_end if config else None
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.8), layout="constrained")
    force = table["force"].to_numpy(dtype=float)
    tmax = table["max_acting_time"].to_numpy(dtype=float)
    monotone = table["monotone"].astype(str).str.lower().isin(["true", "1"]).to_numpy()
    full = np.isfinite(tmax) & (t_end is not None) & np.isclose(tmax, t_end if t_end else -1)
    zero = np.isfinite(tmax) & (tmax <= 0)
    regular = np.isfinite(tmax) & ~full & ~zero

    floor = 0.005
    ax.plot(force[np.isfinite(tmax) & ~zero], tmax[np.isfinite(tmax) & ~zero], "-", color="C0",
            lw=1, alpha=0.6)
    window = (table["ending_outcome"].astype(str) == "not_settled").to_numpy() & regular
    ax.plot(force[regular & monotone & ~window], tmax[regular & monotone & ~window], "o",
            color="C0", label="max acting time")
    if (window & monotone).any():
        ax.plot(force[window & monotone], tmax[window & monotone], "s", mfc="white", mec="C0",
                mew=1.5, label="max acting time (longer pushes do not settle by t_end)")
    if (regular & ~monotone).any():
        ax.plot(force[regular & ~monotone], tmax[regular & ~monotone], "o", mfc="white", mec="C3",
                mew=1.5, label="not monotone (recovers again later)")
    if full.any():
        ax.plot(force[full], tmax[full], "^", color="C2", ms=8,
                label=f"recovers for every T up to t_end = {t_end:g} s")
    if zero.any():
        ax.plot(force[zero], np.full(zero.sum(), floor), "x", color="C3", ms=8,
                label="fails at the shortest push (0.01 s)")
    shown = tmax[np.isfinite(tmax) & (tmax > 0)]
    if zero.any() or (shown.size and shown.max() / shown.min() > 30):
        ax.set_yscale("log")  # from 0.01 s to t_end: a log axis keeps both ends readable
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    else:
        ax.set_ylim(0, 1.1 * shown.max() if shown.size else 1.0)
    ax.set_xlabel("push force F [N]")
    ax.set_ylabel("max acting time [s]  (resolution 0.01 s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Longest push that still recovers", fontsize=10)

    recovered_01 = (table["outcome_01"] == RECOVERED_TEXT).to_numpy()
    for column, style, label in (("energy_total_01", "s-", "total, T = 0.1 s"),
                                 ("energy_total_max", "o-", "total, T = max acting time"),
                                 ("energy_ankle_max", ".--", "ankle, T = max acting time"),
                                 ("energy_hip_max", ".:", "hip, T = max acting time")):
        values = table[column].to_numpy(dtype=float)
        ok = np.isfinite(values) & (values > 0)
        if column.endswith("_01"):
            ok &= recovered_01  # energies of pushes that did not recover are not plotted
        if ok.any():
            ax2.plot(force[ok], values[ok], style, label=label)
    ax2.set_yscale("log")
    ax2.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    ax2.set_xlabel("push force F [N]")
    ax2.set_ylabel("joint energy [J]  (∫|τ·dq/dt| dt)")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=8)
    ax2.set_title("Energy of the recovery", fontsize=10)
    convention = config.controller.convention if config else str(table["convention"].iloc[0])
    fig.suptitle(f"Robustness table — {CONVENTION_TEXT.get(convention, convention)}", fontsize=11)
    _save(fig, path, dpi=130)
    return Path(path)
