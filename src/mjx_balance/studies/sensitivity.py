"""Sensitivity of the reproduction table to the reading of the study (``mjx-balance
sensitivity``): the same robustness table (max acting time per force, the energies of its
runs, the sustained-push limit) under every reading the package supports, and the spread.

Readings: the convention (``paper``: the study's absolute tilts and generalised torques;
``joint``: joint angles and motor torques) x the controller (the study's ``plain`` MPC or the
``offset-free`` MPC, docs/model.md), four tables; each reports both energies, the study's own
(eq. 20, ``study_energy_*``) and the motors' (``energy_*``). Each reading's table lives in its
own resumable folder OUT/<reading>/ (as ``mjx-balance table`` writes one), then:

- ``sensitivity.csv``: one row per force: each reading's max acting time and energies (both
  definitions, of the longest recovered push and of the 0.1-s push: :data:`ENERGIES`), and
  across readings the min, max and max/min of the max acting time and the min and max of
  each energy;
- ``sensitivity.png``: max acting time, its max/min across readings, and both energies of
  both pushes against force, one line per reading;
- ``sensitivity.txt``: which conclusions hold under every reading and which depend on it,
  written from the numbers (:func:`reading_text`).

The report runs the same as its last stage (``studies.experiments.run_sensitivity_stage``: the
plan's table forces, :func:`write_sensitivity` on the readings' tables) into DIR/sensitivity/.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from ..model.params import Config, ParameterError
from ..runs.grid import parse_grid
from ..store.files import TABLE, write_csv, write_text
from ..runs.acting_time import table_scenarios
from ..runs.chunks import PlanHook, PlannedWork
from ..runs.folders import check_float32_grid, run_table_folder
from ..store.folder import folder_lock
from .defaults import DEFAULT_FORCES, READINGS
from ..figures import style as figure_style

# sensitivity.csv's energy columns -> table.csv's: of the longest recovered push (energy_<def>_*)
# and of the 0.1-s push at the same force (energy_<def>_01_*; NaN where that push is not
# recovered), each in both definitions: the study's eq. 20 and the motors'
ENERGIES = {
    "study": "study_energy_total_max",
    "motors": "energy_total_max",
    "study_01": "study_energy_total_01",
    "motors_01": "energy_total_01",
}
SENSITIVITY_CSV, SENSITIVITY_PNG, SENSITIVITY_TXT = (
    "sensitivity.csv",
    "sensitivity.png",
    "sensitivity.txt",
)

# the report's folder of this analysis (studies/experiments.py, report/extra.py)
REPORT_DIR = "sensitivity"


def reading_convention(key: str) -> str:
    """The controller convention of a reading (``paper`` or ``joint``)."""
    changes: dict[str, dict[str, Any]] = READINGS[key][1]  # (str and bool values)
    return changes["controller"]["convention"]


def reading_configs(base: Config, readings: Any = None) -> dict[str, Config]:
    """key -> configuration of each reading (``readings``: keys, default all), on ``base``."""
    keys = list(READINGS) if readings is None else list(readings)
    unknown = [k for k in keys if k not in READINGS]
    if unknown or not keys:
        raise ParameterError(
            f"unknown reading(s) {', '.join(unknown) or '(none)'}; known: {', '.join(READINGS)}"
        )
    configs = {}
    for key in keys:
        changes = READINGS[key][1]
        try:
            configs[key] = base.replace(controller={**changes["controller"]})
        except ParameterError as exc:
            raise ParameterError(f"reading {key!r}: {exc}") from None
    return configs


def run_sensitivity(
    out: str | os.PathLike[str],
    base: Config,
    forces: Any = DEFAULT_FORCES,
    *,
    readings: Any = None,
    progress: bool = False,
    say: Callable[[str], None] = print,
    run_batches: dict[str, Any] | None = None,
    plan: PlanHook | None = None,
    wait: bool = False,
    **engine: Any,
) -> pd.DataFrame:
    """Every reading's table in OUT/<key>/, then sensitivity.csv, .png and .txt (module
    docstring); returns sensitivity.csv's frame. Every input is checked first; then ``plan``
    (if given) hears the planned work (``runs.chunks.PlannedWork``) and the work runs under
    ``out``'s lock (``wait``: for another run that holds it). engine:
    ``runs.folders.run_table_folder``'s options (slots, full_length, physics, cluster);
    run_batches: a batch function per key (tests)."""
    out = Path(out)
    forces = parse_grid(forces, "forces")
    check_float32_grid(forces, "forces")
    configs = reading_configs(base, readings)  # every configuration checked before any work
    if plan is not None:
        plan(
            PlannedWork(
                base, len(configs) * table_scenarios(base, forces.size), "scenarios (estimated)"
            )
        )
    with folder_lock(out, wait=wait):
        return _sensitivity(out, configs, forces, progress, say, run_batches, engine)


def _sensitivity(
    out: Path,
    configs: dict[str, Config],
    forces: np.ndarray,
    progress: bool,
    say: Callable[[str], None],
    run_batches: dict[str, Any] | None,
    engine: dict[str, Any],
) -> pd.DataFrame:
    """:func:`run_sensitivity`'s work, its inputs checked and the folder locked."""
    tables = {}
    for key, config in configs.items():
        folder = out / key
        say(f"sensitivity: {READINGS[key][0]} -> {folder}")
        run_table_folder(
            folder,
            config,
            forces,
            run_batch=(run_batches or {}).get(key),
            progress=progress,
            **engine,
        )
        tables[key] = pd.read_csv(folder / TABLE)
    return write_sensitivity(out, tables, say=say)


def write_sensitivity(
    out: str | Path, tables: dict[str, pd.DataFrame], *, say: Callable[[str], None] = print
) -> pd.DataFrame:
    """sensitivity.csv, .png and .txt in ``out`` from the readings' tables (key -> table.csv
    frame, keys of :data:`READINGS`); returns sensitivity.csv's frame."""
    out = Path(out)
    unknown = [k for k in tables if k not in READINGS]
    if unknown or not tables:
        raise ParameterError(
            f"unknown reading(s) {', '.join(unknown) or '(none)'}; known: {', '.join(READINGS)}"
        )
    frame = spread(tables)
    if frame.empty:
        raise ParameterError("the readings' tables share no force")
    write_csv(frame, out / SENSITIVITY_CSV)
    text = reading_text(frame, tables)
    write_text(text + "\n", out / SENSITIVITY_TXT)
    figure = plot_sensitivity(frame, tables, out / SENSITIVITY_PNG)  # in the figure style
    say(text)
    say(f"wrote {out / SENSITIVITY_CSV}, {figure} and {out / SENSITIVITY_TXT}")
    return frame


def spread(tables: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """One row per force: each reading's max acting time and energies, and their spread."""
    forces = sorted(set.intersection(*(set(t["force"]) for t in tables.values())))
    rows = []
    for force in forces:
        row: dict[str, float] = {"force": float(force)}
        energies: dict[str, list[float]]
        times, energies = [], {name: [] for name in ENERGIES}
        for key, table in tables.items():
            r = table[table["force"] == force].iloc[0]
            row[f"max_acting_time_{key}"] = float(r["max_acting_time"])
            times.append(float(r["max_acting_time"]))
            for name, column in ENERGIES.items():
                value = float(r[column]) if column in r else float("nan")
                row[f"energy_{name}_{key}"] = value
                energies[name].append(value)
        row["max_acting_time_min"], row["max_acting_time_max"] = min(times), max(times)
        row["max_acting_time_ratio"] = (
            max(times) / min(times)
            if min(times) > 0
            else float("inf")
            if max(times) > 0
            else float("nan")
        )
        for name, values in energies.items():
            finite = [v for v in values if np.isfinite(v)]  # 0.1-s pushes: the recovered
            row[f"energy_{name}_min"] = min(finite) if finite else float("nan")
            row[f"energy_{name}_max"] = max(finite) if finite else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)


def _monotone(values: np.ndarray, falling: bool) -> bool:
    """Whether the finite values (at least two) fall (or stay), or rise (or stay), in order."""
    finite = values[np.isfinite(values)]
    steps = np.diff(finite)
    return finite.size >= 2 and bool((steps <= 0).all() if falling else (steps >= 0).all())


def conclusions(frame: pd.DataFrame, keys: list[str]) -> list[tuple[str, list[str]]]:
    """(conclusion, the readings under which it holds) for each conclusion checked."""
    out = []

    def holds(test: Callable[..., bool]) -> list[str]:  # (...: lambdas with a bound default)
        return [k for k in keys if test(k)]

    out.append(
        (
            "the max acting time falls (or stays) as the force grows",
            holds(lambda k: _monotone(frame[f"max_acting_time_{k}"].to_numpy(), True)),
        )
    )
    for name, what in (("study", "the study's energy (eq. 20)"), ("motors", "the motors' energy")):
        out.append(
            (
                f"{what} of the longest recovered push rises with the force",
                holds(lambda k, n=name: _monotone(frame[f"energy_{n}_{k}"].to_numpy(), False)),
            )
        )
        out.append(
            (
                f"{what} of the 0.1-s push rises with the force (where it recovers)",
                holds(lambda k, n=name: _monotone(frame[f"energy_{n}_01_{k}"].to_numpy(), False)),
            )
        )

    def below(k: str) -> bool:
        pairs = [
            (frame[f"energy_study{s}_{k}"], frame[f"energy_motors{s}_{k}"]) for s in ("", "_01")
        ]
        known = [(a[a.notna() & b.notna()], b[a.notna() & b.notna()]) for a, b in pairs]
        return sum(len(a) for a, _ in known) > 0 and all((a <= b).all() for a, b in known)

    out.append(
        ("the study's energy is at most the motors' (every force, both pushes)", holds(below))
    )
    pairs = [
        (k, k.replace("offset_free", "plain"))
        for k in keys
        if k.endswith("offset_free") and k.replace("offset_free", "plain") in keys
    ]
    if pairs:
        out.append(
            (
                "the offset-free MPC's max acting time is at least the plain MPC's at every "
                "force (same convention)",
                [
                    k
                    for k, p in pairs
                    if (frame[f"max_acting_time_{k}"] >= frame[f"max_acting_time_{p}"]).all()
                ],
            )
        )
    return out


def reading_text(frame: pd.DataFrame, tables: dict[str, pd.DataFrame]) -> str:
    """A paragraph from the numbers: the spread per force, what holds under every reading and
    what depends on it."""
    keys = list(tables)
    parts = []
    ratios = frame["max_acting_time_ratio"].to_numpy()
    parts.append(
        f"Under the {len(keys)} readings ({'; '.join(READINGS[k][0] for k in keys)}), the max "
        "acting time at "
        + ", ".join(
            f"{f:g} N ranges {lo:.2f}-{hi:.2f} s (x{r:.2f})"
            for f, lo, hi, r in zip(
                frame.force, frame.max_acting_time_min, frame.max_acting_time_max, ratios
            )
        )
        + "."
    )
    limits = {
        k: float(t["sustained_push_limit"].iloc[0])
        for k, t in tables.items()
        if "sustained_push_limit" in t and np.isfinite(t["sustained_push_limit"].iloc[0])
    }
    for name, what in (("study", "the study's energy (eq. 20)"), ("motors", "the motors' energy")):
        for suffix, push in (("", "longest recovered push"), ("_01", "0.1-s push")):
            lo, hi = frame[f"energy_{name}{suffix}_min"], frame[f"energy_{name}{suffix}_max"]
            if lo.notna().any():
                ratio = (hi / lo)[lo > 0]
                parts.append(
                    f"{what[0].upper()}{what[1:]} of the {push} spans "
                    f"{lo.min():.3g}-{hi.max():.3g} J across readings and forces"
                    + (
                        f" (at most x{ratio.max():.1f} between readings at one force)"
                        if ratio.notna().any()
                        else ""
                    )
                    + "."
                )
    if limits:
        parts.append(
            "The sustained-push limit is "
            + "; ".join(f"{v:g} N ({READINGS[k][0]})" for k, v in limits.items())
            + "."
        )
    every, some = [], []
    for text, where in conclusions(frame, keys):
        candidates = (
            [k for k in keys if k.endswith("offset_free")] if "offset-free" in text else keys
        )
        if len(where) == len(candidates):
            every.append(text)
        elif where:
            some.append(f"{text} (only {'; '.join(READINGS[k][0] for k in where)})")
        else:
            some.append(f"not: {text}")
    if every:
        parts.append("Under every reading: " + "; ".join(every) + ".")
    if some:
        parts.append("Depending on the reading: " + "; ".join(some) + ".")
    return " ".join(parts)


def plot_sensitivity(frame: pd.DataFrame, tables: dict[str, pd.DataFrame], path: Path) -> Path:
    """Max acting time (and the max/min ratio across readings) and the two energies, of the
    longest recovered push and of the 0.1-s push, against force, one line per reading."""
    fig, axes = figure_style.subplots(2, 3, figsize=(15, 8.4))
    markers = ["o", "s", "^", "D"]
    panels = {
        (0, 0): "max_acting_time",
        (0, 1): "energy_study",
        (0, 2): "energy_motors",
        (1, 1): "energy_study_01",
        (1, 2): "energy_motors_01",
    }
    for i, key in enumerate(tables):
        colour = figure_style.SERIES[i % len(figure_style.SERIES)]
        style = dict(
            marker=markers[i % 4],
            color=colour,
            label=READINGS[key][0],
            ls="-" if key.endswith("plain") else "--",
        )
        for (row, col), prefix in panels.items():
            axes[row, col].plot(frame.force, frame[f"{prefix}_{key}"], **style)
    axes[0, 0].fill_between(
        frame.force,
        frame.max_acting_time_min,
        frame.max_acting_time_max,
        color="0.85",
        zorder=0,
        label="spread",
    )
    axes[1, 0].plot(frame.force, frame.max_acting_time_ratio, "k-o")
    titles = {
        (0, 0): "max acting time [s]",
        (0, 1): "study's energy (eq. 20), longest recovered push [J]",
        (0, 2): "motors' energy, longest recovered push [J]",
        (1, 0): "max acting time: largest / smallest reading",
        (1, 1): "study's energy (eq. 20), 0.1-s push [J]",
        (1, 2): "motors' energy, 0.1-s push [J]",
    }
    for (row, col), title in titles.items():
        ax = axes[row, col]
        ax.set_xlabel("push force F [N]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0, 0].set_yscale("log")
    axes[1, 0].set_ylim(bottom=0)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("The reproduction table under every reading of the study")
    return figure_style.save(fig, path, dpi=110)
