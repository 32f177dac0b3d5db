"""Grids of forces and durations: parsing, checks, and the cells of a force x duration grid."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import Any, Sequence, Union

import numpy as np
import pandas as pd

from ..model.params import Config, ParameterError, read_number
from ..store.folder import GRID_TOL, same_values


def parse_grid(spec: str | float | Sequence[float] | np.ndarray, name: str = "grid") -> np.ndarray:
    """Values of a grid: ``"start:stop:step"`` (stop included when it lands on the grid, up to
    float error), a comma list ``"a,b,c"``, a number or a list of numbers.

    Returns the values sorted ascending (float64). Raises ParameterError for an empty grid, a
    non-finite value, a step <= 0, a repeated value or text that is not a number.
    """
    values: list[float] | np.ndarray
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
        raise ParameterError(
            f"{name} = {spec!r}: must be 'start:stop:step', a comma list or numbers"
        )
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        raise ParameterError(f"{name}: empty grid")
    if not np.all(np.isfinite(values)):
        raise ParameterError(
            f"{name}: every value must be finite, got {values[~np.isfinite(values)][:3]}"
        )
    values = np.sort(values)
    repeated = values[1:][np.diff(values) == 0]
    if repeated.size:
        raise ParameterError(f"{name}: value {repeated[0]:g} appears more than once")
    return values


def _number(item: Any, name: str) -> float:
    if isinstance(item, bool):
        raise ParameterError(f"{name}: {item!r} is not a number")
    if isinstance(item, str):
        return read_number(item, name)  # one reading of a number (model.params.NUMBER)
    try:
        return float(item)
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
    d_start, d_stop, d_step = (Decimal(p.strip()) for p in parts)
    count = math.floor((d_stop - d_start) / d_step + Decimal("1e-9")) + 1
    if count > 10_000_000:
        raise ParameterError(f"{name} = {text!r}: {count} values is too many")
    return exact_range(d_start, d_step, count)


def exact_range(start: Decimal, step: Decimal, count: int) -> list[float]:
    """``start + k step`` for k = 0..count-1, each the float nearest the decimal value as
    written (``0.05:1.5:0.05`` gives 0.3, not 0.30000000000000004 nor 0.15000000000000002).

    With d the decimals of start and step, every value is the whole number start 10^d + k
    step 10^d over 10^d; while both are exact in float64 (the whole numbers below 2^53, d <= 22)
    one IEEE division rounds the exact quotient to its nearest float, the same number as
    ``float(Decimal(...))``; otherwise each value goes through Decimal."""
    decimals = max(0, -start.as_tuple().exponent, -step.as_tuple().exponent)  # type: ignore[operator]  # finite Decimals: the exponents are ints
    scale = 10**decimals
    first, stride = int(start * scale), int(step * scale)
    last = abs(first) + stride * max(count - 1, 0)
    if decimals <= 22 and last < 2**53:
        whole = first + stride * np.arange(count, dtype=np.int64)
        return (whole.astype(np.float64) / float(scale)).tolist()
    return [float(start + k * step) for k in range(count)]


STEP_TOL = 1e-6  # how far from a whole number of physics steps a duration may sit (in steps)


def check_whole_steps(
    durations: Sequence[float] | np.ndarray,
    physics_dt: float,
    name: str = "durations",
    *,
    unique: bool = True,
) -> np.ndarray:
    """Durations must be whole numbers of physics steps (the push acts for whole steps, so any
    other value would be rounded silently), up to float error (STEP_TOL steps); returns them
    snapped to the whole steps (0.10000000001 -> 0.1 at 0.002 s), sorted as given.

    Raises ParameterError naming the first offending value and its two nearest valid values, or
    (``unique``: a grid's durations) a value that appears twice once snapped.
    """
    durations = np.asarray(durations, dtype=np.float64)
    steps = durations / physics_dt
    off = np.abs(steps - np.round(steps)) > STEP_TOL
    if np.any(off):
        bad = float(durations[off][0])
        below = math.floor(bad / physics_dt) * physics_dt
        raise ParameterError(
            f"{name}: push duration {bad!r} s is not a whole number of physics steps "
            f"(scenario.physics_dt = {physics_dt:g} s); nearest valid values: "
            f"{round(below, 12):g} or {round(below + physics_dt, 12):g} s"
        )
    snapped = np.round(np.round(steps) * physics_dt, 12)
    values, counts = np.unique(snapped, return_counts=True)
    if unique and np.any(counts > 1):
        raise ParameterError(
            f"{name}: push duration {values[counts > 1][0]:g} s appears more "
            "than once (up to float error)"
        )
    return snapped


def check_durations(
    durations: Sequence[float] | np.ndarray,
    t_end: float,
    name: str = "durations",
    physics_dt: float | None = None,
    *,
    unique: bool = True,
) -> np.ndarray:
    """Durations must lie in [0, t_end] (t_end = scenario.t_end) and, given physics_dt, be whole
    physics steps (check_whole_steps: then returned snapped to them; ``unique``: each once, as
    a grid's; given pairs may share a duration); returns them."""
    durations = np.asarray(durations, dtype=np.float64)
    # the range first: a duration far beyond t_end would overflow the whole-steps check
    if np.any(durations < 0):
        raise ParameterError(f"{name}: push durations must be >= 0, got {durations.min():g}")
    if np.any(durations > t_end + GRID_TOL):
        raise ParameterError(
            f"{name}: push durations must not exceed scenario.t_end = {t_end:g} s, "
            f"got {durations.max():g}"
        )
    if physics_dt is not None:
        durations = check_whole_steps(durations, physics_dt, name, unique=unique)
    return durations


MAX_CELLS = 100_000_000  # cells of one grid, even with --yes: its cell arrays alone are 1.6 GB


def check_cell_count(n_forces: int, n_durations: int) -> int:
    """The number of cells of a grid, refused (ParameterError) above MAX_CELLS before any array
    of cells is built."""
    n_cells = int(n_forces) * int(n_durations)
    if n_cells > MAX_CELLS:
        raise ParameterError(
            f"{n_forces:,} forces x {n_durations:,} durations = {n_cells:,} cells is more than "
            f"one grid may hold ({MAX_CELLS:,}); use coarser steps"
        )
    return n_cells


def grid_cells(forces: np.ndarray, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All (force, duration) cells, force-major: [F0 d0, F0 d1, ..., F1 d0, ...]."""
    check_cell_count(np.size(forces), np.size(durations))
    f, d = np.meshgrid(forces, durations, indexing="ij")
    return f.ravel(), d.ravel()


def describe(values: Sequence[float]) -> str:
    values = list(values)
    if len(values) <= 4:
        return ",".join(f"{v:g}" for v in values)
    return f"{values[0]:g}..{values[-1]:g} ({len(values)} values)"


def parse_pairs(spec: Any, name: str = "pairs") -> tuple[np.ndarray, np.ndarray]:
    """Given (force, duration) pairs, in the order given (not their cross product):
    ``"20:0.7,30:0.45"``, a CSV file with columns force and duration (the path of an existing
    file), or a sequence of (force, duration). Returns (forces, durations); ParameterError
    naming ``name`` and the bad item."""
    if isinstance(spec, (str, Path)) and Path(spec).is_file():
        return _pairs_file(Path(spec), name)
    if isinstance(spec, pd.DataFrame):  # columns force and duration, as a pairs file's
        return _pairs_frame(spec, name)
    if isinstance(spec, str):
        items = [item.strip() for item in spec.split(",") if item.strip()]
        pairs = []
        for item in items:
            force, sep, duration = item.partition(":")
            if not sep or ":" in duration:
                raise ParameterError(
                    f"{name}: {item!r} is not FORCE:DURATION (e.g. 20:0.7), and no such file"
                )
            pairs.append((force, duration))
    else:
        try:
            pairs = [tuple(p) for p in spec]
        except TypeError:
            raise ParameterError(f"{name}: give (force, duration) pairs") from None
        if any(len(p) != 2 for p in pairs):
            raise ParameterError(f"{name}: every pair needs a force and a duration")
    if not pairs:
        raise ParameterError(f"{name}: give at least one (force, duration) pair")
    forces = np.array([_number(f, name) for f, _ in pairs])
    durations = np.array([_number(d, name) for _, d in pairs])
    if not (np.isfinite(forces).all() and np.isfinite(durations).all()):
        raise ParameterError(f"{name}: forces and durations must be finite numbers")
    return forces, durations


def _pairs_file(path: Any, name: str) -> tuple[np.ndarray, np.ndarray]:
    try:
        frame = pd.read_csv(path, comment="#")
    except Exception as exc:
        raise ParameterError(f"{name}: {path} is not a readable CSV ({exc})") from None
    return _pairs_frame(frame, f"{name} ({path})")


def _pairs_frame(frame: pd.DataFrame, name: str) -> tuple[np.ndarray, np.ndarray]:
    frame = frame.rename(columns=lambda c: str(c).strip().lower())
    if "force" not in frame or "duration" not in frame or not len(frame):
        raise ParameterError(
            f"{name}: needs columns force and duration and a row; got "
            f"columns {', '.join(map(str, frame.columns)) or 'none'}"
        )
    return parse_pairs(list(zip(frame["force"], frame["duration"])), name)


# -- a request's grid, checked once ----------------------------------------------------------

Values = Union[str, float, Sequence[float], "np.ndarray"]


def is_bool(value: Any) -> bool:
    return isinstance(value, bool) or type(value).__name__ == "bool_"


def grid_values(values: Values | None, name: str) -> np.ndarray:
    """Forces or durations as a request gives them (the command line's text, the API's
    numbers): sorted, each value once. ``values``: a grid string (``"0:150:10"``,
    ``"20,50,80"``), a number or a sequence of numbers (NumPy's too); a bool, a string inside
    a list or anything else is refused (ParameterError, a ValueError naming ``name``)."""
    if isinstance(values, str):
        return parse_grid(values, name)
    expected = "a number, a sequence of numbers or a grid string such as '0:150:10' or '20,50,80'"
    if is_bool(values):
        raise ParameterError(f"{name}: expected {expected}; got a bool ({values!r})")
    if isinstance(values, numbers.Real):
        values = [values]
    try:
        items = list(values)  # type: ignore[arg-type]  # mypy: a float is no numbers.Real (wrapped above); None: TypeError below
    except TypeError:
        raise ParameterError(
            f"{name}: expected {expected}; got {type(values).__name__} ({values!r})"
        ) from None
    for item in items:
        if is_bool(item) or not isinstance(item, numbers.Real):
            raise ParameterError(
                f"{name}: expected {expected}; got {item!r} ({type(item).__name__}) in the list"
            )
    return parse_grid([float(v) for v in items], name)


def duration_values(values: Values | None, config: Config, name: str = "durations") -> np.ndarray:
    """Durations as a request gives them, checked for ``config``'s window: sorted, each once,
    in [0, t_end] and whole physics steps (snapped to them)."""
    return check_durations(
        grid_values(values, name),
        config.scenario.t_end,
        name,
        physics_dt=config.scenario.physics_dt,
    )


@dataclass(frozen=True, eq=False)
class Grid:
    """A force x duration grid, parsed and checked once where a request enters (the command
    line or an API function: :meth:`of`) and carried down: every floor below takes a Grid and
    checks nothing again.

    ``forces`` sorted, each once; ``durations`` sorted, each once, whole physics steps in
    [0, t_end] of the configuration it was checked against (``t_end``, ``physics_dt``: the
    scenario's window); ``cells``: every (force, duration), force-major, built once."""

    forces: np.ndarray
    durations: np.ndarray
    t_end: float
    physics_dt: float
    _cells: list = field(default_factory=list, repr=False)

    @classmethod
    def of(cls, forces: Values, durations: Values, config: Config) -> "Grid":
        """The grid of ``forces`` and ``durations`` (grid strings or numbers) for ``config``'s
        scenario; ParameterError naming the value and the rule, before any work."""
        if isinstance(forces, Grid):
            raise TypeError("Grid.of: forces is already a Grid")
        f = grid_values(forces, "forces")
        sc = config.scenario
        d = duration_values(durations, config)
        check_cell_count(f.size, d.size)
        for values in (f, d):
            values.setflags(write=False)
        return cls(f, d, float(sc.t_end), float(sc.physics_dt))

    def fits(self, config: Config) -> None:
        """Refuse (ValueError) a configuration whose window is not the one this grid was
        checked against (a programming error: the grid is made for its configuration)."""
        sc = config.scenario
        if (float(sc.t_end), float(sc.physics_dt)) != (self.t_end, self.physics_dt):
            raise ValueError(
                f"a grid checked for t_end {self.t_end:g} s, physics_dt "
                f"{self.physics_dt:g} s, run with t_end {sc.t_end:g} s, "
                f"physics_dt {sc.physics_dt:g} s: make it with Grid.of(..., config)"
            )

    @property
    def cells(self) -> tuple[np.ndarray, np.ndarray]:
        """(forces, durations) of every cell, force-major (:func:`grid_cells`), built once."""
        if not self._cells:
            self._cells.extend(grid_cells(self.forces, self.durations))
        return self._cells[0], self._cells[1]

    @property
    def n_cells(self) -> int:
        return int(self.forces.size * self.durations.size)

    def record(self) -> dict:
        """What a manifest records of the grid (and :meth:`matches` compares)."""
        return {"forces": self.forces.tolist(), "durations": self.durations.tolist()}

    def matches(self, recorded: dict) -> bool:
        """Whether a manifest's record holds this grid (up to the store's float tolerance)."""
        return same_values(recorded["forces"], self.forces) and same_values(
            recorded["durations"], self.durations
        )

    def describe(self) -> str:
        return f"{self.forces.size} forces x {self.durations.size} durations = {self.n_cells} cells"
