"""Grids of forces and durations: parsing, checks, and the cells of a force x duration grid."""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..params import ParameterError

GRID_TOL = 1e-9  # how far a value may sit beyond a limit (float error) and still count


def parse_grid(spec: str | float | Sequence[float], name: str = "grid") -> np.ndarray:
    """Values of a grid: ``"start:stop:step"`` (stop included when it lands on the grid, up to
    float error), a comma list ``"a,b,c"``, a number or a list of numbers.

    Returns the values sorted ascending (float64). Raises ParameterError for an empty grid, a
    non-finite value, a step <= 0, a repeated value or text that is not a number.
    """
    if isinstance(spec, str):
        text = spec.strip()
        if not text:
            raise ParameterError(f"{name}: empty grid")
        if ":" in text:
            values = _parse_range(text, name)
        else:
            values = [_number(item, name) for item in text.split(",") if item.strip()]
    elif isinstance(spec, (int, float)) and not isinstance(spec, bool):
        values = [float(spec)]
    elif isinstance(spec, (list, tuple, np.ndarray)):
        values = [_number(item, name) for item in spec]
    else:
        raise ParameterError(f"{name} = {spec!r}: must be 'start:stop:step', a comma list or numbers")
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        raise ParameterError(f"{name}: empty grid")
    if not np.all(np.isfinite(values)):
        raise ParameterError(f"{name}: every value must be finite, got {values[~np.isfinite(values)][:3]}")
    values = np.sort(values)
    repeated = values[1:][np.diff(values) == 0]
    if repeated.size:
        raise ParameterError(f"{name}: value {repeated[0]:g} appears more than once")
    return values


def _number(item: Any, name: str) -> float:
    if isinstance(item, bool):
        raise ParameterError(f"{name}: {item!r} is not a number")
    try:
        return float(item.strip() if isinstance(item, str) else item)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}: {item!r} is not a number") from None


def _parse_range(text: str, name: str) -> list[float]:
    parts = text.split(":")
    if len(parts) != 3:
        raise ParameterError(f"{name} = {text!r}: a range is start:stop:step")
    start, stop, step = (_number(p, name) for p in parts)
    if not all(math.isfinite(v) for v in (start, stop, step)):
        raise ParameterError(f"{name} = {text!r}: start, stop and step must be finite")
    if step <= 0:
        raise ParameterError(f"{name} = {text!r}: step must be > 0")
    if stop < start:
        raise ParameterError(f"{name} = {text!r}: empty grid (stop < start)")
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > 10_000_000:
        raise ParameterError(f"{name} = {text!r}: {count} values is too many")
    values = start + step * np.arange(count)
    # Remove float error (0.1 * 3 = 0.30000000000000004) without moving any real grid value.
    return [float(v) for v in np.round(values, 12)]


def check_durations(durations: np.ndarray, t_end: float, name: str = "durations") -> np.ndarray:
    """Durations must lie in [0, t_end] (t_end = scenario.t_end); returns them unchanged."""
    if np.any(durations < 0):
        raise ParameterError(f"{name}: push durations must be >= 0, got {durations.min():g}")
    if np.any(durations > t_end + GRID_TOL):
        raise ParameterError(
            f"{name}: push durations must not exceed scenario.t_end = {t_end:g} s, "
            f"got {durations.max():g}")
    return durations


def grid_cells(forces: np.ndarray, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All (force, duration) cells, force-major: [F0 d0, F0 d1, ..., F1 d0, ...]."""
    f, d = np.meshgrid(forces, durations, indexing="ij")
    return f.ravel(), d.ravel()


def same_values(a: Sequence[float], b: Sequence[float]) -> bool:
    """Equal length and equal values up to GRID_TOL."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=0, atol=GRID_TOL))


def describe(values: Sequence[float]) -> str:
    values = list(values)
    if len(values) <= 4:
        return ",".join(f"{v:g}" for v in values)
    return f"{values[0]:g}..{values[-1]:g} ({len(values)} values)"
