"""One cell's run for the explore page: the request checked, the run computed or read back.

A request names a map (by its key), a force and a duration. Both are checked as the command
line checks ``--force`` and ``--duration``: one finite number each, the duration within
[0, scenario.t_end] on whole physics steps (``runs.grid.check_durations``, snapped to them); then
the pair must be a cell of the map or one of its table's max-acting-time points, so that a
request can only compute what the page shows. The run is named by the cell's own values, not
the request's spelling (``50.00000000001`` and ``50`` name one cell), so a folder holds at most
one file per point.

The run is the scalar reference's (``reference.loop.simulate_scenario``: MuJoCo C + OSQP) in
the map's own configuration (its config.toml, else its manifest's), kept in the map's folder as
``explore/<force>_<duration>.parquet`` (the values as Python's ``repr`` writes them): the time
series (docs/outputs.md, "Time-series columns") with the summary row, the configuration, the
command that reproduces it and when and how long it took in the file's metadata (pandas
``attrs``), written atomically (``store.files.write_parquet``). A kept run is used when its
configuration is the map's; otherwise it is computed again. Runs of different cells are
computed side by side, up to one a core (``RUN_SLOTS``; a click on a short run is not queued
behind a long one); a second request for the same cell waits for the first, then reads its
file.
"""

from __future__ import annotations

import math
import os
import shlex
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from ...figures.animation import ARROW_M_PER_N, segment_points
from ...figures.timeseries import BOUND_COLOUR, bounds
from ...measures.strategy import with_strategy
from ...model.params import Config, ParameterError, finite_number
from ...reference import loop as reference
from ...runs.grid import check_durations
from ...runtime.version import __version__
from ...store.files import write_parquet
from ...store.folder import config_dict
from ...store.provenance import now
from .folder import EXPLORE, Folder, MapFolder, column_info, map_config, plain, table_points

MAX_POINTS = 1200  # samples per series sent to the page (the last sample always among them)
FRAME_DT = 0.02  # s between the stick figure's frames (50 per second)

# The page's panels: (title, columns); each column's unit from measures.units, its bound (the
# MPC's) from figures.timeseries.bounds; the foot's pitch with the fall rule's limit.
PANELS = (
    ("Joint angles", ("q_a", "q_h")),
    ("Joint rates", ("dq_a", "dq_h")),
    ("States x1, x2 (controller)", ("x1", "x2")),
    ("Inputs u1, u2", ("u1", "u2")),
    ("Motor torques", ("tau_ankle", "tau_hip")),
    ("CoP, CoM, XCoM", ("cop", "com", "xcom")),
    ("Margin of stability", ("mos",)),
    ("Foot pitch", ("foot_pitch",)),
    ("Energy over time", ("energy_total", "study_energy_total")),
)


# The run's summary values the page lists (units from measures.units).
SHOWN = (
    "outcome",
    "fall_cause",
    "fall_time",
    "settle_time",
    "first_infeasible_time",
    "energy_total",
    "study_energy_total",
    "hip_share",
    "strategy",
    "mos_min",
    "mos_min_time",
    "steps_needed",
    "capture_margin",
    "decision_time",
    "peak_ankle",
    "peak_hip",
    "peak_foot_pitch",
    "cop_min",
    "cop_max",
    "com_min",
    "com_max",
    "ankle_saturation_fraction",
    "hip_saturation_fraction",
    "nonconverged_solves",
)


def one_number(query: dict[str, list[str]], name: str) -> float:
    """The request's one value of ``name`` as a finite number (ParameterError otherwise)."""
    values = query.get(name, [])
    if len(values) != 1:
        raise ParameterError(f"{name}: give one value (got {len(values)})")
    return finite_number(values[0], name) + 0.0  # -0.0 is 0.0


def check_cell(
    query: dict[str, list[str]],
    config: Config,
    found: MapFolder,
    grid: tuple[np.ndarray, np.ndarray],
) -> tuple[float, float]:
    """(force, duration) of a request, checked (module docstring)."""
    force = one_number(query, "force")
    duration = one_number(query, "duration")
    sc = config.scenario
    duration = float(check_durations([duration], sc.t_end, "duration", physics_dt=sc.physics_dt)[0])
    forces, durations = grid
    tol = 1e-9 * max(1.0, abs(force))
    # The cell's own values, not the request's spelling: 50.00000000001 and 50 name one cell,
    # so they share one kept run (explore/F_T.parquet) rather than a run each.
    near_force = np.flatnonzero(np.abs(forces - force) <= tol)
    near_duration = np.flatnonzero(np.abs(durations - duration) <= 1e-9)
    if near_force.size and near_duration.size:
        return float(forces[near_force[0]]) + 0.0, float(durations[near_duration[0]])
    for point in table_points(found):
        if abs(point["force"] - force) <= tol and abs(point["max_acting_time"] - duration) <= 1e-9:
            return point["force"] + 0.0, point["max_acting_time"]
    raise ParameterError(
        f"({force:g} N, {duration:g} s) is not a cell of this map nor a "
        "max-acting-time point of its table: the page opens the runs it "
        "shows"
    )


def run_path(found: MapFolder, force: float, duration: float) -> Path:
    return found.path / EXPLORE / f"{float(force)!r}_{float(duration)!r}.parquet"


def commands(folder: Folder, found: MapFolder, force: float, duration: float) -> dict[str, str]:
    """The command lines that reproduce the run (simulate: the same series and summary),
    replay it in MuJoCo's viewer and draw its GIF."""
    config = folder.shown_path(found, "config.toml")
    has_file = (found.path / "config.toml").is_file()
    base = ["--config", config] if has_file else []
    q = shlex.join
    return {
        "simulate": q(
            [
                "mjx-balance",
                "simulate",
                *base,
                "--pairs",
                f"{force!r}:{duration!r}",
                "--out",
                "explore-run",
            ]
        ),
        "view": q(
            ["mjx-balance", "view", *base, "--force", repr(force), "--duration", repr(duration)]
        ),
        "animate": q(
            [
                "mjx-balance",
                "animate",
                *base,
                "--force",
                repr(force),
                "--duration",
                repr(duration),
                "--out",
                "push.gif",
            ]
        ),
    }


def summary_row(summary: dict[str, Any]) -> dict[str, Any]:
    """The summary row with the hip's share and strategy, as JSON values."""
    row = with_strategy(pd.DataFrame([summary])).iloc[0].to_dict()
    return {k: plain(v) for k, v in row.items()}


def read_kept(path: Path, config: Config) -> pd.DataFrame | None:
    """The kept run at ``path`` if it is whole and of ``config``, else None."""
    if not path.is_file():
        return None
    try:
        frame = pd.read_parquet(path)
    except Exception:
        return None
    if frame.attrs.get("config") != config_dict(config) or "summary" not in frame.attrs:
        return None
    return frame


class Stopping(RuntimeError):
    """The server is stopping: no run starts (the server answers 503)."""


RUN_SLOTS = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


@dataclass
class Runs:
    """Runs of a folder's cells, one cell's at a time, up to ``RUN_SLOTS`` cells side by side;
    ``closed`` once the server stops (no run starts and no file is written after that)."""

    folder: Folder
    write: threading.Lock = field(default_factory=threading.Lock)
    closed: bool = False
    simulate: Callable[..., Any] | None = None  # the reference (tests put a stand-in)
    slots: threading.BoundedSemaphore = field(
        default_factory=lambda: threading.BoundedSemaphore(RUN_SLOTS or 1)
    )
    cells: dict[Path, threading.Lock] = field(default_factory=dict)  # one lock per cell's file
    guard: threading.Lock = field(default_factory=threading.Lock)  # of ``cells``

    def cell(self, path: Path) -> threading.Lock:
        with self.guard:
            return self.cells.setdefault(path, threading.Lock())

    def close(self, timeout: float = 5.0) -> None:
        """No more writes, no new run; waits (up to ``timeout``) for a write under way to
        finish."""
        got = self.write.acquire(timeout=timeout)
        self.closed = True
        if got:
            self.write.release()

    def get(
        self, found: MapFolder, query: dict[str, list[str]], grid: tuple[np.ndarray, np.ndarray]
    ) -> dict[str, Any]:
        """The run a request asks for, as the page's JSON (kept, or computed and kept)."""
        config = map_config(found)
        force, duration = check_cell(query, config, found, grid)
        path = run_path(found, force, duration)
        frame = read_kept(path, config)
        cached, note = frame is not None, None
        if frame is None:
            with self.cell(path), self.slots:
                if self.closed:  # a request that waited while the server began to stop
                    raise Stopping("the server is stopping")
                frame = read_kept(path, config)  # computed meanwhile by another request
                cached = frame is not None
                if frame is None:
                    frame, note = self._compute(found, config, force, duration)
        return run_json(frame, config, found=found, folder=self.folder, cached=cached, note=note)

    def _compute(
        self, found: MapFolder, config: Config, force: float, duration: float
    ) -> tuple[pd.DataFrame, str | None]:
        simulate = self.simulate or reference.simulate_scenario
        started = time.perf_counter()
        summary, frame = simulate(config, force, duration, record=True)
        assert frame is not None  # (record=True)
        frame = frame.reset_index(drop=True)
        frame.attrs = {
            "summary": summary_row(summary),
            "config": config_dict(config),
            "computed": {
                "at": now(),
                "seconds": time.perf_counter() - started,
                "by": "the scalar reference (MuJoCo C + OSQP)",
                "version": __version__,
            },
            "commands": commands(self.folder, found, force, duration),
        }
        path = run_path(found, force, duration)
        try:
            with self.write:
                if self.closed:
                    return frame, "the server is stopping: this run was not kept"
                path.parent.mkdir(exist_ok=True)
                write_parquet(frame, path)
        except OSError as exc:
            return frame, f"not kept in the folder: {exc.strerror or exc} ({path})"
        return frame, None


def thin(n: int, limit: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most about ``limit`` of ``n`` samples, evenly, the last one included."""
    step = max(1, math.ceil(n / limit))
    return np.unique(np.append(np.arange(0, n, step), n - 1)) if n else np.arange(0)


def rounded(values: np.ndarray) -> list:
    """Six significant digits, None for NaN (the page's JSON stays small)."""
    return [None if not math.isfinite(v) else float(f"{v:.6g}") for v in values.tolist()]


def panels(config: Config, convention: str) -> list[dict[str, Any]]:
    out = []
    for title, columns in PANELS:
        limits: list[dict[str, Any]] = []
        for column in columns:
            limit = bounds(config, convention, column)
            if limit is not None and limit not in [tuple(b["values"]) for b in limits]:
                limits.append({"values": limit, "label": f"MPC bound of {column}"})
        if columns == ("foot_pitch",):
            lim = config.scenario.foot_pitch_limit
            limits.append({"values": (-lim, lim), "label": "fall rule: |foot pitch| limit"})
        if columns == ("mos",):
            limits.append({"values": (0.0,), "label": "0: XCoM at the foot's edge"})
        unit = column_info(columns[0])["unit"]
        out.append(
            {
                "title": title,
                "unit": unit,
                "columns": [column_info(c) for c in columns],
                "bounds": limits,
                "bound_colour": BOUND_COLOUR,
            }
        )
    return out


def stick_frames(frame: pd.DataFrame, config: Config) -> dict[str, Any]:
    """The stick figure's points (figures.animation.segment_points) every FRAME_DT, with the
    CoP and the CoM on the floor."""
    t = frame["time"].to_numpy(float)
    at = np.unique(np.searchsorted(t, np.arange(0.0, t[-1] + 1e-9, FRAME_DT)).clip(0, t.size - 1))
    at = np.unique(np.append(at, t.size - 1))
    rows = frame.iloc[at]
    pts = segment_points(
        config.body,
        *(rows[c].to_numpy(float) for c in ("foot_x", "foot_z", "foot_pitch", "q_a", "q_h")),
    )
    out = {name: [rounded(p[:, 0]), rounded(p[:, 1])] for name, p in pts.items()}
    return {
        "time": rounded(t[at]),
        "points": out,
        "cop": rounded(rows["cop"].to_numpy(float)),
        "com": rounded(rows["com"].to_numpy(float)),
        "arrow_m_per_n": ARROW_M_PER_N,
    }


def run_json(
    frame: pd.DataFrame,
    config: Config,
    *,
    found: MapFolder,
    folder: Folder,
    cached: bool,
    note: str | None,
) -> dict[str, Any]:
    """A run as the page draws it (docs/explore.md, "mjx-balance explore")."""
    summary = frame.attrs["summary"]
    force, duration = float(summary["force"]), float(summary["duration"])
    at = thin(len(frame))
    series = {
        c: rounded(frame[c].to_numpy(float)[at])
        for _, columns in PANELS
        for c in columns
        if c in frame
    }
    series["time"] = rounded(frame["time"].to_numpy(float)[at])
    return {
        "map": found.key,
        "force": force,
        "duration": duration,
        "cached": cached,
        "note": note,
        "file": folder.shown_path(found, EXPLORE, run_path(found, force, duration).name),
        "summary": summary,
        "computed": frame.attrs.get("computed", {}),
        "shown": [column_info(c) for c in SHOWN],
        "commands": commands(folder, found, force, duration),
        "convention": config.controller.convention,
        "t_end": config.scenario.t_end,
        "series": series,
        "panels": panels(config, config.controller.convention),
        "figure": stick_frames(frame, config),
    }
