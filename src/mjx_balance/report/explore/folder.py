"""What an output folder holds, for the explore page: its kind, its maps and each map's cells.

A folder is one of:

- a **sweep** folder (``mjx-balance sweep``): one map, the folder itself;
- a **cohort** folder (``manifest.json`` with ``kind: "cohort"``, or a ``subjects/`` folder):
  one map per subject, ``subjects/<id>/``, and the share of subjects that recover in each cell
  (when the subjects share a grid);
- a **compare** folder: one map per variant, each sub-folder that is a sweep folder.

A map folder is a folder with ``region.parquet``, or a ``manifest.json`` that records a region
grid, or ``chunks/``. Everything is read as it stands: while a sweep is under way its cells
come from the chunk files written so far (each written atomically, so whole) on the grid of
its manifest, and the cells not computed yet are sent as missing. Each map's JSON is kept in
memory against a stamp of its files (sizes and times), so a page that polls rereads nothing
until a file changes.

Map folders are found by listing the folder; a key (``""``, ``"<variant>"``,
``"subjects/<id>"``) names one, and a request names a map by its key only (never a path). A
sub-folder that resolves outside the folder (a symbolic link) is not a map.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import pandas as pd

from ...figures.region import cell_bounds, log_durations, recovery_boundary
from ...figures.style import OUTCOME_COLOURS, OUTCOME_HATCHES, SERIES
from ...measures.outcomes import OUTCOMES, RECOVERED
from ...measures.strategy import HIP_SHARE_THRESHOLD
from ...measures.units import describe
from ...model.params import Config, ParameterError
from ...model.config_files import config_from_dict, load_config
from ...runtime.version import __version__
from ...store.files import CONFIG, MANIFEST, REGION, TABLE
from ...studies.cohort import BASE
from ...studies.probability import BELOW, LEVELS, at_level, wilson

EXPLORE = "explore"  # a map folder's computed runs: explore/<force>_<duration>.parquet
CHUNKS = "chunks"
SUBJECTS = "subjects"
FIGURE_SUFFIXES = (".png", ".svg", ".pdf", ".gif")
RECOVERED_TEXT = OUTCOMES[RECOVERED]

# steps_needed's inf on the page (JSON has no infinity): two steps do not capture
NOT_WITHIN = "more than 2"

# The values a cell shows on hover, in order (units and meanings from measures.units).
HOVER = (
    "force",
    "duration",
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
    "steps_needed",
    "capture_margin",
)
LABELS = {
    "force": "force",
    "duration": "duration",
    "outcome": "outcome",
    "fall_cause": "fall cause",
    "fall_time": "fall time",
    "settle_time": "settle time",
    "first_infeasible_time": "first infeasible QP",
    "energy_total": "energy, motors' work",
    "study_energy_total": "energy, the study's (eq. 20)",
    "hip_share": "hip share",
    "strategy": "strategy",
    "mos_min": "min. margin of stability",
    "mos_min_time": "time of the min. margin",
    "peak_ankle": "peak |ankle angle|",
    "peak_hip": "peak |hip angle|",
    "peak_foot_pitch": "peak |foot pitch|",
    "cop_min": "CoP, smallest",
    "cop_max": "CoP, largest",
    "com_min": "CoM, smallest",
    "com_max": "CoM, largest",
    "ankle_saturation_fraction": "ankle input at its bound",
    "hip_saturation_fraction": "hip input at its bound",
    "nonconverged_solves": "QP solves not converged",
    "steps_needed": "steps needed (capturability)",
    "capture_margin": "one-step capture margin",
    "decision_time": "decision to step",
}
# The map's layers: (column, label, scale, recovered cells only)
LAYERS = (
    ("outcome", "outcome", "outcome", False),
    ("settle_time", "settle time", "linear", True),
    ("energy_total", "energy, motors' work", "log", True),
    ("study_energy_total", "energy, the study's (eq. 20)", "log", True),
    ("hip_share", "hip share of the work", "linear", True),
    ("mos_min", "min. margin of stability", "linear", False),
    ("first_infeasible_time", "first infeasible QP", "linear", False),
)


def column_info(column: str) -> dict[str, str]:
    """A column's label, unit and meaning (measures.units)."""
    unit, meaning = describe(column) or ("", "")
    return {"column": column, "label": LABELS.get(column, column), "unit": unit, "meaning": meaning}


@dataclass(frozen=True)
class MapFolder:
    """One map of a folder: ``key`` names it in requests, ``path`` is its folder (resolved),
    ``label`` what the page calls it."""

    key: str
    path: Path
    label: str


@dataclass(frozen=True)
class Folder:
    """An output folder the page explores: ``root`` (resolved), ``shown`` (as the user gave
    it, for the commands the page prints), ``kind`` and its maps, in order."""

    root: Path
    shown: str
    kind: str
    maps: tuple[MapFolder, ...]

    def map(self, key: str) -> MapFolder:
        for found in self.maps:
            if found.key == key:
                return found
        raise ParameterError(
            f"map: no map {key!r} in this folder (its maps: "
            f"{', '.join(repr(m.key) for m in self.maps[:8]) or 'none'})"
        )

    def shown_path(self, found: MapFolder, *names: str) -> str:
        """A path inside ``found`` as the commands the page prints write it."""
        parts = [p for p in (found.key, *names) if p]
        return os.path.join(self.shown, *parts)


def read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return None


def is_map(path: Path) -> bool:
    """Whether ``path`` holds a region map, finished or under way."""
    if (path / REGION).is_file() or (path / CHUNKS).is_dir():
        return True
    manifest = read_json(path / MANIFEST)
    return isinstance(manifest, dict) and isinstance(manifest.get("region"), dict)


def inside(root: Path, path: Path) -> bool:
    """Whether ``path`` resolves to ``root`` or below it (symbolic links followed)."""
    try:
        return path.resolve().is_relative_to(root)
    except (OSError, RuntimeError):
        return False


def _sub_maps(root: Path, parent: Path, prefix: str, order: list[str]) -> list[MapFolder]:
    if not parent.is_dir():
        return []
    names = sorted(p.name for p in parent.iterdir() if p.is_dir() and not p.name.startswith("."))
    names = [n for n in order if n in names] + [n for n in names if n not in order]
    return [
        MapFolder(prefix + n, (parent / n).resolve(), n)
        for n in names
        if inside(root, parent / n) and is_map(parent / n)
    ]


def open_folder(path: str | os.PathLike[str]) -> Folder:
    """The folder at ``path`` and its maps; ParameterError when it is not a folder or holds no
    region map."""
    shown = os.fspath(path)
    if not shown.strip() or not Path(shown).is_dir():
        raise ParameterError(f"{shown!r} is not a folder")
    root = Path(shown).resolve()
    manifest = read_json(root / MANIFEST)
    manifest = manifest if isinstance(manifest, dict) else {}
    if manifest.get("kind") == "cohort" or (root / SUBJECTS).is_dir():
        subjects = (
            manifest.get("cohort", {}).get("subjects", [])
            if isinstance(manifest.get("cohort"), dict)
            else []
        )
        order = [str(s.get("id")) for s in subjects if isinstance(s, dict)]
        kind, maps = "cohort", _sub_maps(root, root / SUBJECTS, SUBJECTS + "/", order)
    elif is_map(root):
        kind, maps = "sweep", [MapFolder("", root, root.name)]
    else:
        names = []
        table = root / "compare.csv"
        if table.is_file():
            try:
                names = [str(n) for n in pd.read_csv(table)["name"]]
            except Exception:
                names = []
        kind, maps = "compare", _sub_maps(root, root, "", names)
    if not maps and kind != "cohort":
        raise ParameterError(
            f"{shown!r} holds no region map: explore a folder written by `mjx-balance sweep`, "
            "`compare` or `cohort` (region.parquet, or a sweep under way: manifest.json with "
            "its grid)"
        )
    return Folder(root, shown, kind, tuple(maps))


# -- one map's files, cells and configuration ----------------------------------------------------


def _stat(path: Path) -> tuple[int, int] | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size


def map_stamp(found: MapFolder) -> str:
    """Changes when a file the map's JSON reads changes (written, replaced, a chunk added)."""
    names = (REGION, TABLE, MANIFEST, CONFIG, CHUNKS, EXPLORE)
    text = repr([_stat(found.path / n) for n in names])
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def map_config(found: MapFolder) -> Config:
    """The configuration the map was computed in: its config.toml, else its manifest's."""
    path = found.path / CONFIG
    if path.is_file():
        return load_config(path)
    manifest = read_json(found.path / MANIFEST)
    if isinstance(manifest, dict) and isinstance(manifest.get("config"), dict):
        return config_from_dict(manifest["config"])
    raise ParameterError(f"{found.label}: no configuration (config.toml or manifest.json)")


def _cells(found: MapFolder) -> pd.DataFrame:
    """The map's computed cells: region.parquet, else the chunk files written so far."""
    region = found.path / REGION
    if region.is_file():
        try:
            return pd.read_parquet(region)
        except Exception:
            pass
    parts = []
    for path in sorted((found.path / CHUNKS).glob("chunk-*.parquet")):
        try:
            parts.append(pd.read_parquet(path))
        except Exception:
            continue
    if not parts:
        return pd.DataFrame(columns=["force", "duration", "outcome"])
    cells = pd.concat(parts, ignore_index=True)
    return cells.drop_duplicates(["force", "duration"], keep="last")


def grid_of(found: MapFolder, cells: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """The map's forces and durations: its manifest's grid, else its cells'."""
    manifest = read_json(found.path / MANIFEST)
    region = manifest.get("region") if isinstance(manifest, dict) else None
    if isinstance(region, dict) and region.get("forces") and region.get("durations"):
        return (
            np.unique(np.asarray(region["forces"], float)),
            np.unique(np.asarray(region["durations"], float)),
        )
    return (np.unique(cells["force"].to_numpy(float)), np.unique(cells["duration"].to_numpy(float)))


def index_on(values: Sequence[float] | np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Each value's index in the sorted ``grid`` (-1 where none lies within float error)."""
    values = np.asarray(values, float)
    if grid.size == 0:
        return np.full(values.shape, -1)
    at = np.clip(np.searchsorted(grid, values), 0, grid.size - 1)
    below = np.clip(at - 1, 0, grid.size - 1)
    at = np.where(np.abs(grid[below] - values) < np.abs(grid[at] - values), below, at)
    near = np.abs(grid[at] - values) <= 1e-9 * np.maximum(1.0, np.abs(values))
    return np.where(near, at, -1)


def plain(value: Any) -> Any:
    """A JSON value: NaN and infinities as null, numpy numbers as Python's."""
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    return value if isinstance(value, (str, int, bool)) else str(value)


def on_grid(cells: pd.DataFrame, forces: np.ndarray, durations: np.ndarray) -> dict[str, list]:
    """The cells' hover columns in grid order (force-major: cell i is force i // n_durations,
    duration i % n_durations), None where a cell is not computed (yet)."""
    fi = index_on(cells["force"].to_numpy(float), forces)
    di = index_on(cells["duration"].to_numpy(float), durations)
    keep = (fi >= 0) & (di >= 0)
    at = fi[keep] * durations.size + di[keep]
    out: dict[str, list] = {}
    for column in HOVER:
        if column in ("force", "duration") or column not in cells:
            continue
        values: list = [None] * (forces.size * durations.size)
        for i, v in zip(at.tolist(), cells[column].to_numpy()[keep].tolist()):
            values[i] = NOT_WITHIN if column == "steps_needed" and v == math.inf else plain(v)
        out[column] = values
    return out


def boundary_lines(
    outcome: list,
    forces: np.ndarray,
    durations: np.ndarray,
    edges: tuple[np.ndarray, np.ndarray],
    steps_needed: list | None = None,
    steps: int | None = None,
) -> list[list[list[float]]]:
    """The recovery boundary on the grid (figures.region.recovery_boundary: the top of each
    force's first recovered range of durations; with ``steps``, recovered with at most that
    many steps, from the cells' ``steps_needed`` hover values) as step polylines of (force,
    duration) points, over the forces whose every cell is computed (a gap where one is not)."""
    fx, dy = edges
    grid = np.asarray(outcome, dtype=object).reshape(forces.size, durations.size)
    complete = np.array([all(v is not None for v in row) for row in grid])
    if not complete.any():
        return []
    frame = pd.DataFrame(
        {
            "force": np.repeat(forces[complete], durations.size),
            "duration": np.tile(durations, int(complete.sum())),
            "outcome": grid[complete].ravel(),
        }
    )
    if steps is not None:
        if steps_needed is None:
            return []
        need = np.asarray(steps_needed, dtype=object).reshape(forces.size, durations.size)
        # NOT_WITHIN (inf) or None (NaN: diverged): never within ``steps``
        frame["steps_needed"] = [
            v if isinstance(v, (int, float)) else math.inf for v in need[complete].ravel()
        ]
    tops = dict(zip(*recovery_boundary(frame, steps)[["force", "boundary"]].to_numpy().T))
    lines: list[list[list[float]]]  # lines of [x, y] points
    line: list[list[float]]
    lines, line = [], []
    for i, force in enumerate(forces):
        if not complete[i]:
            if line:
                lines.append(line)
            line = []
            continue
        j = index_on([tops[force]], durations)[0]
        top = float(dy[j + 1]) if j >= 0 else float(dy[0])
        line += [[float(fx[i]), top], [float(fx[i + 1]), top]]
    if line:
        lines.append(line)
    return lines


def table_points(found: MapFolder) -> list[dict[str, float]]:
    """table.csv's max acting times (finite ones), forces ascending."""
    path = found.path / TABLE
    if not path.is_file():
        return []
    try:
        table = pd.read_csv(path)
        rows = table[["force", "max_acting_time"]].dropna().sort_values("force")
    except Exception:
        return []
    return [
        {"force": float(f), "max_acting_time": float(t)}
        for f, t in rows.to_numpy(float)
        if math.isfinite(f) and math.isfinite(t)
    ]


def explored(found: MapFolder) -> list[list[float]]:
    """The (force, duration) pairs whose runs the folder keeps (explore/F_T.parquet)."""
    pairs = []
    for path in sorted((found.path / EXPLORE).glob("*_*.parquet")):
        try:
            force, duration = (float(p) for p in path.stem.split("_"))
        except ValueError:
            continue
        pairs.append([force, duration])
    return pairs


def provenance_of(found: MapFolder) -> dict[str, Any]:
    """The physics path and the command of the last run that worked on the map (its
    manifest's ``runs``), where recorded."""
    manifest = read_json(found.path / MANIFEST)
    runs = manifest.get("runs") if isinstance(manifest, dict) else None
    last = runs[-1] if isinstance(runs, list) and runs and isinstance(runs[-1], dict) else {}
    return {"physics": last.get("physics"), "command": last.get("command")}


def figures(path: Path) -> list[str]:
    """The figure files of a folder (not hidden), by name."""
    return sorted(
        p.name
        for p in path.iterdir()
        if p.suffix in FIGURE_SUFFIXES and p.is_file() and not p.name.startswith(".")
    )


def map_json(folder: Folder, found: MapFolder) -> dict[str, Any]:
    """One map as the page draws it (docs/explore.md, "mjx-balance explore")."""
    cells = _cells(found)
    forces, durations = grid_of(found, cells)
    log = log_durations(durations)
    edges = (cell_bounds(forces), cell_bounds(durations, log))
    values = on_grid(cells, forces, durations)
    outcome = values.get("outcome", [None] * (forces.size * durations.size))
    done = sum(v is not None for v in outcome)
    counts = {name: sum(v == name for v in outcome) for name in OUTCOMES}
    out = {
        "key": found.key,
        "label": found.label,
        "path": folder.shown_path(found),
        "forces": forces.tolist(),
        "durations": durations.tolist(),
        "force_edges": edges[0].tolist(),
        "duration_edges": edges[1].tolist(),
        "log_durations": log,
        "cells": values,
        "done": done,
        "total": len(outcome),
        "complete": done == len(outcome) and done > 0,
        "counts": counts,
        "boundary": boundary_lines(outcome, forces, durations, edges),
        # with one and with two steps (capturability), where the cells have steps_needed
        "step_boundaries": [
            boundary_lines(outcome, forces, durations, edges, values.get("steps_needed"), n)
            for n in (1, 2)
        ],
        "table": table_points(found),
        "explored": explored(found),
        **provenance_of(found),
        "files": figures(found.path),
    }
    try:
        config = map_config(found)
        out.update(
            convention=config.controller.convention,
            t_end=config.scenario.t_end,
            physics_dt=config.scenario.physics_dt,
        )
    except ParameterError as exc:
        out["error"] = str(exc)
    return out


def probability(maps: list[dict[str, Any]], base: Path | None = None) -> dict[str, Any] | None:
    """Per cell, the share of the subjects whose map recovers it, over the subjects that have
    the cell computed (``counted``), with its 95 % Wilson interval (``low``, ``high``: as
    cohort_probability.csv), the 95/50/5 % boundaries and the base body's (``base``: its
    folder, the cohort's base/), as cohort_probability.png draws them; None unless every map
    has the same grid."""
    if len(maps) < 2:
        return None
    first = maps[0]
    if any(m["forces"] != first["forces"] or m["durations"] != first["durations"] for m in maps):
        return None
    outcomes = np.array(
        [m["cells"].get("outcome", [None] * m["total"]) for m in maps], dtype=object
    )
    counted = (outcomes != None).sum(axis=0)  # noqa: E711 - elementwise on an object array
    recovered = (outcomes == RECOVERED_TEXT).sum(axis=0)
    share = [plain(r / n) if n else None for r, n in zip(recovered, counted)]
    low, high = wilson(recovered, np.maximum(counted, 1))
    forces, durations = np.asarray(first["forces"]), np.asarray(first["durations"])
    edges = (np.asarray(first["force_edges"]), np.asarray(first["duration_edges"]))
    levels = {}
    for percent in LEVELS:  # as the probability figure's lines (studies.probability.at_level)
        at = [
            None if not n else (RECOVERED_TEXT if ok else BELOW)
            for ok, n in zip(at_level(recovered, counted, percent), counted)
        ]
        levels[str(percent)] = boundary_lines(at, forces, durations, edges)
    return {
        "share": share,
        "low": [plain(v) if n else None for v, n in zip(low, counted)],
        "high": [plain(v) if n else None for v, n in zip(high, counted)],
        "counted": [int(n) for n in counted],
        "subjects": len(maps),
        "levels": levels,
        "base": base_boundary(base, forces, durations, edges),
        **{
            k: first[k]
            for k in ("forces", "durations", "force_edges", "duration_edges", "log_durations")
        },
    }


def base_boundary(
    base: Path | None, forces: np.ndarray, durations: np.ndarray, edges: tuple
) -> list[list[list[float]]]:
    """The base body's recovery boundary on the cohort's grid (its map in ``base``, the
    probability figure's reference line); empty where there is none yet."""
    if base is None or not base.is_dir():
        return []
    cells = _cells(MapFolder("base", base, "base"))
    if cells.empty:
        return []
    outcome = on_grid(cells, forces, durations).get("outcome")
    return [] if outcome is None else boundary_lines(outcome, forces, durations, edges)


@dataclass
class MapCache:
    """Each map's JSON against its stamp (thread-safe): a page that polls rereads nothing
    until a file of the map changes."""

    kept: dict[str, tuple[str, dict[str, Any]]] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def get(self, folder: Folder, found: MapFolder) -> dict[str, Any]:
        stamp = map_stamp(found)
        with self.lock:
            hit = self.kept.get(found.key)
        if hit is not None and hit[0] == stamp:
            return hit[1]
        value = {**map_json(folder, found), "stamp": stamp}
        with self.lock:
            self.kept[found.key] = (stamp, value)
        return value


def folder_json(folder: Folder, cache: MapCache) -> dict[str, Any]:
    """The folder as the page first reads it: its kind, its maps (each map's boundary, not its
    cells), the layers and hover values with their units, the palette, the probability map."""
    maps = [cache.get(folder, m) for m in folder.maps]
    stamp = hashlib.sha1(repr([(m["key"], m["stamp"]) for m in maps]).encode()).hexdigest()
    brief = (
        "key",
        "label",
        "path",
        "done",
        "total",
        "complete",
        "boundary",
        "convention",
        "t_end",
        "error",
    )
    return {
        "kind": folder.kind,
        "name": folder.root.name,
        "path": folder.shown,
        "stamp": stamp[:16],
        "version": __version__,
        "maps": [{k: m.get(k) for k in brief} for m in maps],
        "files": figures(folder.root) if folder.kind != "sweep" else [],
        "probability": (probability(maps, folder.root / BASE) if folder.kind == "cohort" else None),
        "hover": [column_info(c) for c in HOVER],
        "layers": [
            {**column_info(c), "label": label, "scale": scale, "recovered_only": only}
            for c, label, scale, only in LAYERS
        ],
        "outcomes": [
            {"name": n, "colour": OUTCOME_COLOURS[n], "hatch": bool(OUTCOME_HATCHES[n])}
            for n in OUTCOMES
        ],
        "series": list(SERIES),
        "hip_share_threshold": HIP_SHARE_THRESHOLD,
    }
