"""The weight landscape (``mjx-balance landscape``, :func:`run_landscape`): the recoverable
area, the sustained-push limit and the mean recovery energy over a grid of Q and R scales,
with and without a sensorimotor delay.

A *weight setting* (q, r) is the base configuration with its controller's ``q_diag``
multiplied by q and its ``r_diag`` by r (so (1, 1) is the base's, the study's, weights). A
*delay setting* is a controller delay in ms, plain or compensated
(``controller.delay_compensation``): ``"0"``, ``"10"``, ``"100c"``. Every (delay, q, r) is a
configuration run exactly as ``mjx-balance compare`` runs one (``compare``: its region map
and its table in its own sweep folder ``OUT/<delay>/q<q>_r<r>/``, resumable, so a rerun
computes only what is missing), and its numbers are ``compare.numbers`` of that folder.
The compiled rollout is shared between configurations of equal shapes (weights are data, not
shapes), so each setting costs only its scenarios; each delay compiles once.

Files in OUT:

landscape.csv   one row per (delay, q, r) (:data:`COLUMNS`), rewritten after each setting
landscape.png   heatmaps: one row per delay setting, one column per number; the base's cell
                (scale 1, 1) outlined
landscape.txt   the reading (:func:`reading`): sentences written from the numbers

Energy columns: ``mean_recovery_energy`` is the mean motor energy of the setting's own
recovered cells (as compare.csv's), so a setting that recovers harder pushes pays for them;
``energy_vs_study`` compares like with like: the setting's mean energy over the cells that it
and the base weights (same delay) both recover, divided by the base weights' mean over the
same cells. ``nonconverged_solves`` counts the region's QP solves that the ADMM did not report
solved (a check that an extreme weight's numbers are the controller's, not the solver's).
"""

from __future__ import annotations

import math
import re
import textwrap
import time
from dataclasses import dataclass
import os
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np
import pandas as pd

from . import catalog, compare as comparison
from ..model.params import Config, ParameterError
from ..runs.acting_time import table_scenarios
from ..runs.chunks import PlanHook, PlannedWork
from ..runs.grid import Grid, check_durations, parse_grid
from ..store.files import REGION, TABLE, write_atomic, write_csv
from ..store.folder import folder_lock
from ..runs.folders import (
    batch_function,
    check_batched,
    check_float32_grid,
    run_region,
    run_table_folder,
)
from ..runs.population import check_queue, run_maps
from .defaults import DEFAULT_DELAYS, DEFAULT_SCALES, DEFAULT_TABLE_FORCES
from ..figures import style as figure_style

LANDSCAPE_CSV = "landscape.csv"
LANDSCAPE_PNG = "landscape.png"
LANDSCAPE_TXT = "landscape.txt"

KEY_COLUMNS = ["delay", "delay_ms", "compensated", "q_scale", "r_scale"]
COLUMNS = [
    *KEY_COLUMNS,
    "study",
    "area",
    "fraction",
    "recovered_cells",
    "cells",
    "t_ref",
    "f_max_ref",
    "rest_recovered",
    "mean_recovery_energy",
    "sustained_push_limit",
    "paired_cells",
    "energy_vs_study",
    "nonconverged_solves",
]
# then max_acting_time_<F>N per table force


@dataclass(frozen=True)
class Delay:
    """A delay setting: the controller sees the state ``ms`` late; ``compensated``: it
    predicts the present state (``controller.delay_compensation``)."""

    ms: float
    compensated: bool = False

    @property
    def key(self) -> str:
        """Its folder name in OUT: delay_000ms, delay_100ms_comp, delay_012.5ms."""
        ms = f"{self.ms:03.0f}" if float(self.ms).is_integer() else f"{self.ms:05.1f}"
        return f"delay_{ms}ms" + ("_comp" if self.compensated else "")

    @property
    def label(self) -> str:
        if self.ms == 0:
            return "no delay"
        return f"{self.ms:g} ms, " + ("compensated" if self.compensated else "plain")

    @property
    def spec(self) -> str:
        return f"{self.ms:g}" + ("c" if self.compensated else "")


def parse_delays(spec: str | Sequence[str | float]) -> list[Delay]:
    """Delay settings from ``"0,10,100c"`` (ms; a trailing ``c``: compensated) or a list of
    such items, in the order given. ParameterError for a bad item, a repeat, a negative delay
    or a compensated 0 ms (nothing to compensate)."""
    items = (
        [s.strip() for s in spec.split(",")]
        if isinstance(spec, str)
        else [str(s).strip() for s in spec]
    )
    items = [s for s in items if s]
    if not items:
        raise ParameterError(
            "delays: give at least one delay setting, e.g. 0,100c (ms; a "
            "trailing c: the delay-compensated controller)"
        )
    delays: list[Delay] = []
    for item in items:
        match = re.fullmatch(r"([0-9.eE+-]+)\s*(ms)?\s*(c|comp)?", item)
        try:
            ms = float(match.group(1)) if match else float("nan")
        except ValueError:
            ms = float("nan")
        if not math.isfinite(ms):
            raise ParameterError(
                f"delays: {item!r} is not a delay setting; write the delay in "
                "ms, with a trailing c for the compensated controller (0, 10, "
                "100c)"
            )
        if ms < 0:
            raise ParameterError(f"delays: {item!r}: a delay must be >= 0 ms")
        assert match is not None  # (no match: ms is NaN, refused above)
        compensated = bool(match.group(3))
        if compensated and ms == 0:
            raise ParameterError(f"delays: {item!r}: a compensated delay needs a delay > 0 ms")
        delay = Delay(ms, compensated)
        if delay in delays:
            raise ParameterError(f"delays: {item!r} is given twice")
        delays.append(delay)
    return delays


def parse_scales(spec: str | float | Sequence[float], name: str) -> np.ndarray:
    """Scale factors (``parse_grid``: a comma list, sorted, each once), every one > 0 and
    distinct in its folder name."""
    values = parse_grid(spec, name)
    if not np.all(values > 0):
        raise ParameterError(f"{name}: every scale must be > 0, got {values[values <= 0][0]:g}")
    labels = [scale_label(v) for v in values]
    for a, b in zip(labels, labels[1:]):
        if a == b:
            raise ParameterError(f"{name}: scales too close to tell apart ({a})")
    return values


def scale_label(value: float) -> str:
    return f"{value:.6g}"


def setting_name(q: float, r: float) -> str:
    """The folder name of a weight setting: q0.1_r10."""
    return f"q{scale_label(q)}_r{scale_label(r)}"


def scaled(value: float, scale: float) -> float:
    """value x scale to 12 significant digits: 1e-4 x 0.1 is 1e-05, not 1.0000000000000001e-05,
    so that the configuration written by hand (a TOML file with r_diag = [0.01, 1e-05]) is the
    same configuration, with the same numbers."""
    return float(f"{value * scale:.12g}")


def setting_config(base: Config, delay: Delay, q: float, r: float) -> Config:
    """The base configuration with Q x q, R x r (each entry, :func:`scaled`) and the delay
    setting (ParameterError naming the setting if the result breaks a rule)."""
    c = base.controller
    try:
        return base.replace(
            controller={
                "q_diag": tuple(scaled(v, q) for v in c.q_diag),
                "r_diag": tuple(scaled(v, r) for v in c.r_diag),
                "delay_compensation": delay.compensated,
            },
            scenario={"controller_delay": round(delay.ms / 1000.0, 12)},
        )
    except ParameterError as exc:
        raise ParameterError(f"delay {delay.spec} ms, Q x {q:g}, R x {r:g}: {exc}") from None


def plan(
    base: Config, delays: Sequence[Delay], q_scales: np.ndarray, r_scales: np.ndarray
) -> list[tuple[Delay, float, float, str, Config]]:
    """Every setting in run order (delay, then Q scale, then R scale): (delay, q, r, folder
    relative to OUT, configuration)."""
    return [
        (
            d,
            float(q),
            float(r),
            f"{d.key}/{setting_name(q, r)}",
            setting_config(base, d, float(q), float(r)),
        )
        for d in delays
        for q in q_scales
        for r in r_scales
    ]


def check_landscape(
    out: str | Path,
    base: Config,
    forces: Any,
    durations: Any,
    q_scales: Any = DEFAULT_SCALES,
    r_scales: Any = DEFAULT_SCALES,
    delays: Any = DEFAULT_DELAYS,
    table_forces: Any = DEFAULT_TABLE_FORCES,
) -> dict[str, Any]:
    """Every input of a landscape checked, nothing written: the scales and delays, every
    setting's configuration, the grids (durations within each window, on its physics step) and
    every setting's folder in ``out`` (left by another configuration or holding a map over
    another grid). Returns the parsed values and the settings (:func:`plan`); ParameterError
    naming the setting otherwise."""
    out = Path(out)
    q_scales = parse_scales(q_scales, "Q scales")
    r_scales = parse_scales(r_scales, "R scales")
    delays = parse_delays(delays)
    forces = parse_grid(forces, "forces")
    durations = parse_grid(durations, "durations")
    table_forces = parse_grid(table_forces, "table forces")
    check_float32_grid(forces, "forces")
    check_float32_grid(table_forces, "table forces")
    settings = plan(base, delays, q_scales, r_scales)
    for _delay, _q, _r, name, config in settings:
        try:
            durations = check_durations(
                durations, config.scenario.t_end, physics_dt=config.scenario.physics_dt
            )
            check_batched(config)  # the scaled weights' QP builds and float32 resolves it
        except ParameterError as exc:
            raise ParameterError(f"{name}: {exc}") from None
        comparison.check_folder(out / name, name, config, forces, durations)
    return {
        "q_scales": q_scales,
        "r_scales": r_scales,
        "delays": delays,
        "forces": forces,
        "durations": durations,
        "table_forces": table_forces,
        "settings": settings,
    }


def run_landscape(
    out: str | os.PathLike[str],
    base: Config,
    forces: Any,
    durations: Any,
    *,
    q_scales: Any = DEFAULT_SCALES,
    r_scales: Any = DEFAULT_SCALES,
    delays: Any = DEFAULT_DELAYS,
    table_forces: Any = DEFAULT_TABLE_FORCES,
    make_batch: Callable[..., Any] | None = None,
    progress: bool = False,
    say: Callable[[str], None] | None = print,
    plan: PlanHook | None = None,
    wait: bool = False,
    **engine: Any,
) -> pd.DataFrame:
    """Every setting's region map and table in ``out/<delay>/q<q>_r<r>/``, then
    landscape.csv, landscape.png and landscape.txt in ``out``; returns the landscape
    (:data:`COLUMNS`, one row per setting in run order).

    Everything is checked once, before any work (:func:`check_landscape`): the scales and
    delays, every setting's configuration, the grids against its window, and every setting's
    folder (left by another configuration or holding a map over another grid: refused,
    naming it). Then ``plan`` (if given) hears the planned work (``runs.chunks.PlannedWork``)
    and the work runs under ``out``'s lock (``wait``: for another run that holds it).
    make_batch: ``make_batch(config, slots=, full_length=, physics=)`` -> a batch function
    (default ``batch_function``; tests pass a stand-in); engine: ``slots``, ``full_length``,
    ``physics``, ``queue`` ("each": every setting's map its own engine run; "one": through one
    engine queue per compiled shape, ``runs.population.run_maps``, MJX only)."""
    say = say or (lambda _msg: None)
    out = Path(out)
    queue = check_queue(engine.get("queue", "each"), engine.get("physics") or "auto")
    checked = check_landscape(
        out, base, forces, durations, q_scales, r_scales, delays, table_forces
    )
    n = len(checked["settings"])
    if plan is not None:
        plan(
            PlannedWork(
                base,
                n * checked["forces"].size * checked["durations"].size,
                "cells",
                extra=n * table_scenarios(base, checked["table_forces"].size),
            )
        )
    with folder_lock(out, wait=wait):
        return _landscape(out, checked, queue, make_batch, engine, progress, say)


def _landscape(
    out: Path,
    checked: dict[str, Any],
    queue: str,
    make_batch: Callable[..., Any] | None,
    engine: dict[str, Any],
    progress: bool,
    say: Callable[[str], None],
) -> pd.DataFrame:
    """:func:`run_landscape`'s work, its inputs checked and the folder locked."""
    q_scales, r_scales, delays = checked["q_scales"], checked["r_scales"], checked["delays"]
    forces, durations = checked["forces"], checked["durations"]
    table_forces, settings = checked["table_forces"], checked["settings"]
    make_batch = make_batch or batch_function
    options = {
        "slots": engine.get("slots"),
        "full_length": engine.get("full_length", False),
        "physics": engine.get("physics") or "auto",
    }
    say(
        f"landscape: {len(delays)} delay setting(s) x {q_scales.size} Q scales x "
        f"{r_scales.size} R scales = {len(settings)} settings, each a region map of "
        f"{forces.size} x {durations.size} pushes and a table ({table_forces.size} force(s) + "
        f"the sustained-push limit); output {out}"
    )
    out.mkdir(parents=True, exist_ok=True)
    if queue == "one":  # every setting's map through one engine queue per compiled shape
        run_maps(
            [(out / name, config) for *_, name, config in settings],
            forces,
            durations,
            slots=options["slots"],
            full_length=options["full_length"],
            say=lambda text: say(f"landscape: {text}"),
        )
    rows: list[dict[str, Any]] = []
    regions: dict[str, pd.DataFrame] = {}
    start = time.perf_counter()
    for k, (delay, q, r, name, config) in enumerate(settings, 1):
        folder = out / name
        t0 = time.perf_counter()
        done = (folder / REGION).exists() and (folder / TABLE).exists()
        say(
            f"landscape [{k}/{len(settings)}] {delay.label}, Q x {q:g}, R x {r:g} -> {folder}"
            + (" (kept: checking)" if done else "")
        )
        run_batch = make_batch(config, **options)
        if queue != "one":
            run_region(
                folder,
                config,
                Grid.of(forces, durations, config),
                run_batch=run_batch,
                progress=progress,
            )
        run_table_folder(folder, config, table_forces, run_batch=run_batch, progress=progress)
        del run_batch
        regions[name] = pd.read_parquet(folder / REGION)
        row = _setting_row(delay, q, r, regions[name], pd.read_csv(folder / TABLE))
        rows.append(row)
        frame = _frame(rows, regions, settings)
        write_csv(frame, out / LANDSCAPE_CSV)
        elapsed = time.perf_counter() - start
        say(
            f"landscape [{k}/{len(settings)}] area {row['area']:.4g} N s, sustained "
            f"{row['sustained_push_limit']:g} N, mean energy {row['mean_recovery_energy']:.3g} J"
            f" ({time.perf_counter() - t0:.1f} s; {elapsed:.0f} s so far)"
        )
    frame = _frame(rows, regions, settings)
    write_csv(frame, out / LANDSCAPE_CSV)
    figure = plot_landscape(frame, out / LANDSCAPE_PNG)  # in the figure style
    text = reading(frame)
    write_atomic(out / LANDSCAPE_TXT, lambda tmp: tmp.write_text(text + "\n"))
    say(text)
    say(
        f"wrote {out / LANDSCAPE_CSV}, {figure} and {out / LANDSCAPE_TXT} "
        f"({time.perf_counter() - start:.0f} s)"
    )
    return frame


def _setting_row(
    delay: Delay, q: float, r: float, region: pd.DataFrame, table: pd.DataFrame
) -> dict[str, Any]:
    """The landscape's row of one setting: its delay and weights, and its map's numbers."""
    return {
        "delay": delay.spec,
        "delay_ms": delay.ms,
        "compensated": delay.compensated,
        "q_scale": q,
        "r_scale": r,
        "study": q == 1.0 and r == 1.0,
        **comparison.numbers(region, table),
        # QP solves the ADMM did not report solved, over the region's cells (a check
        # that an extreme weight's numbers are the controller's, not the solver's)
        "nonconverged_solves": int(region["nonconverged_solves"].sum()),
    }


def _frame(
    rows: list[dict[str, Any]],
    regions: dict[str, pd.DataFrame],
    settings: list[tuple[Delay, float, float, str, Config]],
) -> pd.DataFrame:
    """The landscape so far, with the paired energy columns (against the base weights of the
    same delay, once that setting has run)."""
    frame = pd.DataFrame(rows)
    names = {(d.spec, q, r): name for d, q, r, name, _ in settings}
    paired, ratio = [], []
    for row in rows:
        mine = regions[names[(row["delay"], row["q_scale"], row["r_scale"])]]
        base = regions.get(names.get((row["delay"], 1.0, 1.0), ""))
        n, value = paired_energy(mine, base) if base is not None else (0, float("nan"))
        paired.append(n)
        ratio.append(value)
    frame["paired_cells"] = paired
    frame["energy_vs_study"] = ratio
    extra = [c for c in frame.columns if c not in COLUMNS]
    return frame[[c for c in COLUMNS if c in frame.columns] + extra]


def paired_energy(region: pd.DataFrame, base: pd.DataFrame) -> tuple[int, float]:
    """(cells both maps recover, mean energy_total of ``region`` over them / that of ``base``;
    NaN when there are none or the base's mean is 0)."""
    keys = ["force", "duration"]
    a = region[catalog.is_recovered(region)].set_index(keys)["energy_total"]
    b = base[catalog.is_recovered(base)].set_index(keys)["energy_total"]
    both = a.index.intersection(b.index)
    if not len(both) or not b.loc[both].mean() > 0:
        return int(len(both)), float("nan")
    return int(len(both)), float(a.loc[both].mean() / b.loc[both].mean())


# ---------------------------------------------------------------------------------------------
# The figure and the reading

PANELS = (
    ("area", "recoverable area [N s]", "{:.3g}"),
    ("sustained_push_limit", "sustained-push limit [N]", "{:.3g}"),
    ("mean_recovery_energy", "mean recovery energy [J]", "{:.2g}"),
    ("energy_vs_study", "energy vs base weights,\nsame pushes [x]", "{:.2f}"),
)


def grid_of(frame: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Q scales, R scales, values [Q, R]) of one delay setting's rows."""
    qs = np.sort(frame["q_scale"].unique())
    rs = np.sort(frame["r_scale"].unique())
    values = np.full((qs.size, rs.size), np.nan)
    for _, row in frame.iterrows():
        values[np.searchsorted(qs, row["q_scale"]), np.searchsorted(rs, row["r_scale"])] = row[
            column
        ]
    return qs, rs, values


def plot_landscape(frame: pd.DataFrame, path: Path) -> Path:
    """Heatmaps: one row per delay setting, one column per number (:data:`PANELS`); rows are Q
    scales, columns R scales (log spaced as given), each cell's value written in it, the base
    weights' cell (1, 1) outlined; a colour scale per column, shared by the rows. At one
    column (``figure_style``) the grid is transposed: one row per number, one column per delay
    setting, each panel titled with both."""
    from matplotlib.patches import Rectangle

    delays = list(dict.fromkeys(frame["delay"]))
    narrow = figure_style.current().size == "one-column"
    shape = (len(PANELS), len(delays)) if narrow else (len(delays), len(PANELS))
    fig, grid = figure_style.subplots(
        *shape, squeeze=False, stack=False, figsize=(4.3 * len(PANELS), 3.9 * len(delays))
    )
    axes = grid.T if narrow else grid  # axes[i, j]: delay i, number j
    for j, (column, title, fmt) in enumerate(PANELS):
        finite = frame[column].to_numpy(float)
        finite = finite[np.isfinite(finite)]
        lo, hi = (finite.min(), finite.max()) if finite.size else (0.0, 1.0)
        if hi == lo:
            lo, hi = lo - 0.5, hi + 0.5
        for i, delay in enumerate(delays):
            ax = axes[i, j]
            rows = frame[frame["delay"] == delay]
            qs, rs, values = grid_of(rows, column)
            image = ax.imshow(
                np.ma.masked_invalid(values),
                origin="lower",
                cmap="viridis",
                vmin=lo,
                vmax=hi,
                aspect="auto",
            )
            for a in range(qs.size):
                for b in range(rs.size):
                    v = values[a, b]
                    dark = np.isfinite(v) and (v - lo) / (hi - lo) < 0.6
                    ax.text(
                        b,
                        a,
                        "–" if not np.isfinite(v) else fmt.format(v),
                        ha="center",
                        va="center",
                        fontsize=7,
                        color="white" if dark else "black",
                    )
            if 1.0 in qs and 1.0 in rs:
                ax.add_patch(
                    Rectangle(
                        (np.searchsorted(rs, 1.0) - 0.5, np.searchsorted(qs, 1.0) - 0.5),
                        1,
                        1,
                        fill=False,
                        edgecolor="red",
                        linewidth=2.2,
                    )
                )
            ax.set_xticks(range(rs.size), [f"{v:g}" for v in rs], fontsize=7, rotation=45)
            ax.set_yticks(range(qs.size), [f"{v:g}" for v in qs], fontsize=7)
            ax.set_xlabel("R scale")
            label = _delay_label(rows.iloc[0])
            if narrow:
                # two panels side by side in 3.5 in: titles of at most 22 characters a line
                ax.set_title(textwrap.fill(f"{title}", 22) + f"\n{label}", fontsize=8)
                if i == 0:
                    ax.set_ylabel("Q scale")
            else:
                if j == 0:
                    ax.set_ylabel(f"{label}\nQ scale")
                if i == 0:
                    ax.set_title(title, fontsize=10)
            if i == len(delays) - 1:
                fig.colorbar(image, ax=axes[:, j], shrink=0.8)
    fig.suptitle("Weight landscape: Q x q_scale, R x r_scale (red: the base weights)")
    return figure_style.save(fig, path, dpi=110)


def _delay_label(row: pd.Series) -> str:
    return Delay(float(row["delay_ms"]), bool(row["compensated"])).label


def _setting(row: pd.Series) -> str:
    return f"(Q x {row['q_scale']:g}, R x {row['r_scale']:g})"


def reading(frame: pd.DataFrame) -> str:
    """A few sentences per delay setting, written from the numbers: the base weights' numbers
    and their rank, the largest area and the plateau within 10 % of it, the sustained-push
    limit's range, the most frugal setting among those that recover at least the base's area
    (energy_vs_study), and how far settings with equal Q/R ratio differ (the unconstrained
    controller depends on the ratio only)."""
    lines = []
    for delay in dict.fromkeys(frame["delay"]):
        rows = frame[frame["delay"] == delay].reset_index(drop=True)
        label = _delay_label(rows.iloc[0])
        best = rows["area"].max()
        text = [f"{label} ({len(rows)} settings):"]
        base = rows[rows["study"].astype(bool)]
        if len(base):
            b = base.iloc[0]
            rank = int((rows["area"] > b["area"]).sum()) + 1
            text.append(
                f"the base weights recover {b['area']:.4g} N s (rank {rank} of "
                f"{len(rows)} by area), hold {b['sustained_push_limit']:g} N and "
                f"spend {b['mean_recovery_energy']:.3g} J per recovery."
            )
        if not best > 0:
            text.append("no setting recovers any push.")
            lines.append(" ".join(text))
            continue
        top = rows[rows["area"] == best]
        plateau = rows[rows["area"] >= 0.9 * best]
        text.append(
            f"Largest area {best:.4g} N s at "
            + ", ".join(_setting(r) for _, r in top.iterrows())
            + f"; {len(plateau)} settings within 10 % of it, "
            + f"{int((rows['area'] == 0).sum())} recover nothing."
        )
        limits = rows["sustained_push_limit"]
        if limits.notna().any():
            text.append(
                f"Sustained-push limit from {limits.min():g} to {limits.max():g} N "
                f"(largest at {_setting(rows.loc[limits.idxmax()])})."
            )
        if len(base):
            robust = rows[(rows["area"] >= base.iloc[0]["area"]) & rows["energy_vs_study"].notna()]
            if len(robust):
                f = robust.loc[robust["energy_vs_study"].idxmin()]
                text.append(
                    f"Most frugal of the {len(robust)} settings recovering at least the "
                    f"base's area: {_setting(f)}, {f['energy_vs_study']:.2f} x the base "
                    f"weights' energy on the {int(f['paired_cells'])} pushes both "
                    "recover."
                )
        ratio = np.round(np.log10(rows["q_scale"] / rows["r_scale"]), 6)
        spread = rows.groupby(ratio)["area"].agg(lambda a: a.max() - a.min())
        multi = rows.groupby(ratio)["area"].size() > 1
        if multi.any():
            text.append(
                f"Settings with the same Q/R ratio differ in area by at most "
                f"{spread[multi].max():.3g} N s."
            )
        lines.append(" ".join(text))
    return "\n".join(lines)
