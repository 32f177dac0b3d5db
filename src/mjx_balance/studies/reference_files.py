"""Reference files: a published (or a lab's) table or a set of pushes, read and checked for
the scorecard (``scorecard.py`` scores them) and the region map's points.

A reference file is a CSV; its kind is told by its columns (docs/outputs.md, "Reference files"):

points   ``force``, ``duration`` (optional ``label``): pushes drawn over the region map, as
         before; nothing is scored.
table    ``force`` and any of the measures of :data:`MEASURES` (the max acting time and the
         energies at T = 0.1 s, ``_01``, and at the max acting time, ``_max``; the header names
         which energy: ``study_energy_*`` is the study's eq. 20, ``energy_*`` the motors'
         absolute work), and/or ``duration`` with ``recovered`` (1/0, true/false, yes/no):
         whether the push (force, duration) recovered. Optional: ``source`` (the citation),
         ``reason`` (why a row differs, written by whoever measured it: the scorecard never
         infers one), ``label`` (the file's name in the outputs; default: its stem),
         ``resolution`` (the stated resolution of the row's values; default: the printed
         decimals, so "0.45" stands for 0.445..0.455) and ``tolerance`` (an absolute
         tolerance for the row, replacing the derived one).
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..model.params import ParameterError
from ..runs.acting_time import MOTOR_ENERGY_COLUMNS, STUDY_ENERGY_COLUMNS
from . import references

MEASURES = ["max_acting_time", *STUDY_ENERGY_COLUMNS, *MOTOR_ENERGY_COLUMNS]
OPTIONAL = ("duration", "label", "source", "reason", "resolution", "tolerance")
TRUE = {"1", "true", "yes", "y", "recovered"}
FALSE = {"0", "false", "no", "n", "fell", "not_recovered"}
# Two forces are one force within this tolerance (numpy.isclose's, relative to our table's
# force): 20.0001 N is our 20 N row. The same rule adds a reference's forces to the table run
# (reference_forces) and matches its rows to our table's, region map's and runs' rows.
FORCE_RTOL = 1e-5
FORCE_ATOL = 1e-8  # N
MAX_ROWS = 1_000_000  # rows of one reference file (read and scored in seconds)


@dataclass
class Reference:
    """One reference file: its label, kind ('points' or 'table'), rows (columns as read,
    lower case) and the printed text of each value (for the stated resolution)."""

    path: Path
    label: str
    kind: str
    frame: pd.DataFrame
    text: pd.DataFrame

    @property
    def measures(self) -> list[str]:
        return [m for m in MEASURES if m in self.frame]

    @property
    def forces(self) -> list[float]:
        """The forces whose table rows this reference scores (none for points)."""
        if self.kind != "table":
            return []
        return sorted({float(f) for f in self.frame["force"]})

    def points(self) -> pd.DataFrame | None:
        """Its (force, duration) pushes to draw over a region map (None without durations)."""
        if "duration" not in self.frame:
            return None
        rows = self.frame.dropna(subset=["duration"])
        return rows[["force", "duration"]].assign(label=self.label) if len(rows) else None


def read_reference(path: str | os.PathLike[str]) -> Reference:
    """Read and check one reference file, or a shipped reference by name (``"study"``:
    :mod:`studies.references`); ParameterError naming the file, its line and column, and the
    value. Refused: a row with more fields than the header (a trailing comma would shift every
    column), a value that is not a finite number, two different values of one measure for one
    force (or two outcomes of one push), a header without ``force`` (with the columns found and,
    for a file separated by ``;`` or tabs, that the separator must be a comma), more than
    :data:`MAX_ROWS` rows. An identical repeated row is scored once."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(
            f"reference: expected a CSV path or the name of a shipped reference "
            f"({', '.join(references.SHIPPED)}); got {type(path).__name__} "
            f"{path!r}"
        )
    path = references.resolve(path)
    if path.is_dir():
        raise ParameterError(f"{path}: is a folder, not a reference file (a CSV)")
    try:
        references.check_size(path)
    except ValueError as exc:
        raise ParameterError(str(exc)) from None
    raw = _read_fields(path)
    header = [str(c).strip().lower() for c in raw.iloc[0]] if len(raw) else []
    text = raw.iloc[1:].apply(lambda column: column.str.strip())
    text = text[(text != "").any(axis=1)].reset_index(drop=True)  # empty fields: no row
    lines = _Lines(path)
    header, text = _checked_header(path, header, text, lines)
    if "force" not in text.columns or len(text) == 0:
        raise ParameterError(
            f"{path}: a reference file needs a column force and at least one "
            f"row{_found(header)} (docs/outputs.md, 'Reference files')"
        )
    if len(text) > MAX_ROWS:
        raise ParameterError(
            f"{path}: {len(text)} rows; a reference file holds at most "
            f"{MAX_ROWS:,} (a published table has tens, a lab's trials "
            "thousands): split it, or give the pushes as a region map"
        )
    unknown = [c for c in text.columns if c not in {"force", "recovered", *MEASURES, *OPTIONAL}]
    if unknown:
        raise ParameterError(
            f"{path}: unknown column(s) {', '.join(unknown)}; known: force, "
            f"duration, recovered, {', '.join(MEASURES)}, "
            f"{', '.join(OPTIONAL[1:])}"
        )
    frame = text.copy()
    numeric = [c for c in ("force", "duration", "resolution", "tolerance", *MEASURES) if c in text]
    for column in numeric:
        frame[column] = _numbers(path, text, column, lines)
    if "recovered" in text:
        _read_recovered(path, text, frame, lines)
    kind = "table" if ("recovered" in frame or any(m in frame for m in MEASURES)) else "points"
    if kind == "points" and "duration" not in frame:
        raise ParameterError(
            f"{path}: needs either duration (points to draw) or a measure "
            f"column ({', '.join(MEASURES[:3])}, ...) or recovered"
        )
    if kind == "table":
        _one_value_each(path, frame, lines)
    label = (
        str(frame["label"].iloc[0]) if "label" in frame and frame["label"].iloc[0] else path.stem
    )
    return Reference(path, label, kind, frame, text)


class _Lines:
    """A data row's line in its file (only worked out for a message: comments, blank lines and
    the header are not rows)."""

    def __init__(self, path: Path):
        self.path = path
        self._lines: list[int] | None = None

    def __call__(self, row: int) -> str:
        if self._lines is None:
            text = self.path.read_text(encoding="utf-8-sig", errors="replace")
            self._lines = [
                i + 1
                for i, line in enumerate(text.splitlines())
                if line.strip()
                and not line.lstrip().startswith("#")
                and line.replace(",", "").strip()
            ][1:]
        if row < len(self._lines):
            return f"line {self._lines[row]}"
        return f"data row {row + 1}"  # a quoted text over several lines: count rows instead

    def both(self, a: int, b: int) -> str:
        first, second = self(a), self(b)
        if first.startswith("line ") and second.startswith("line "):
            return f"lines {first[5:]} and {second[5:]}"
        return f"{first} and {second}"


def _read_fields(path: Path) -> pd.DataFrame:
    """Every field as text, the header as the first row; ParameterError for a row with more
    fields than the header, an empty file or one that is no CSV."""
    try:
        return pd.read_csv(
            path, header=None, dtype=str, keep_default_na=False, comment="#", encoding="utf-8-sig"
        )
    except FileNotFoundError:
        raise ParameterError(
            f"reference file not found: {path} (the shipped references: "
            f"{', '.join(references.SHIPPED)})"
        ) from None
    except pd.errors.EmptyDataError:
        raise ParameterError(
            f"{path}: empty; a reference file needs a header line (force, "
            "...) and at least one row (docs/outputs.md, 'Reference files')"
        ) from None
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: not UTF-8 text") from None
    except pd.errors.ParserError as exc:
        extra = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        first = _first_line(path)
        if extra and _separated_otherwise(first):
            raise ParameterError(
                f"{path}: the header {first!r} is one column: the separator must be a comma"
            ) from None
        if extra:
            raise ParameterError(
                f"{path}, line {extra[2]}: {extra[3]} fields where the header has {extra[1]} "
                "(a trailing comma, or a comma in an unquoted text: quote it)"
            ) from None
        raise ParameterError(f"{path}: not a readable CSV ({exc})") from None
    except Exception as exc:
        raise ParameterError(f"{path}: not a readable CSV ({exc})") from None


def _first_line(path: Path) -> str:
    """The file's first line that is neither blank nor a comment (its header)."""
    with open(path, encoding="utf-8-sig", errors="replace") as file:
        for line in file:
            if line.strip() and not line.lstrip().startswith("#"):
                return line.strip()
    return ""


def _separated_otherwise(header: str) -> bool:
    return "," not in header and any(sep in header for sep in (";", "\t", "|"))


def _found(header: list[str]) -> str:
    """``; found column(s) ...`` and, for a header separated otherwise, the separator rule."""
    if not header:
        return ""
    found = f"; found column(s) {', '.join(repr(c) for c in header)}"
    if len(header) == 1 and _separated_otherwise(header[0]):
        found += ": the separator must be a comma"
    return found


def _checked_header(
    path: Path, header: list[str], text: pd.DataFrame, lines: _Lines
) -> tuple[list[str], pd.DataFrame]:
    """The data under their column names; a column without a name is dropped when it is
    empty (a trailing comma on every line), refused when it holds values; a name given twice
    is refused."""
    keep = []
    for i, name in enumerate(header):
        if name:
            keep.append(i)
            continue
        values = text.iloc[:, i]
        if (values != "").any():
            row = int(np.flatnonzero((values != "").to_numpy())[0])
            raise ParameterError(
                f"{path}: column {i + 1} has no name in the header but "
                f"holds {values.iloc[row]!r} ({lines(row)})"
            )
    text = text.iloc[:, keep]
    names = [header[i] for i in keep]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ParameterError(
            f"{path}: column(s) {', '.join(twice)} given more than once in the header"
        )
    text.columns = names
    return names, text


def _numbers(path: Path, text: pd.DataFrame, column: str, lines: _Lines) -> pd.Series:
    """A numeric column as floats (NaN where empty; force is never empty), checked: every
    given value a finite number, none but force negative."""
    given = text[column] != ""
    values = pd.to_numeric(text[column].where(given, "nan"), errors="coerce")
    number = values.to_numpy(float)
    bad = given.to_numpy() & ~np.isfinite(number)
    if column == "force":
        bad |= ~given.to_numpy()
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ParameterError(
            f"{path}, {lines(row)}: {column} must be a finite number, got "
            f"{text[column].iloc[row]!r}"
        )
    if column != "force" and (number < 0).any():
        row = int(np.flatnonzero(number < 0)[0])
        raise ParameterError(
            f"{path}, {lines(row)}: {column} must not be negative, got {text[column].iloc[row]!r}"
        )
    return pd.Series(number, index=text.index)


def _read_recovered(path: Path, text: pd.DataFrame, frame: pd.DataFrame, lines: _Lines) -> None:
    """The ``recovered`` column as 1.0 / 0.0 / NaN (empty), checked; it needs durations."""
    words = text["recovered"].str.lower()
    bad = ~words.isin(TRUE | FALSE | {""})
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ParameterError(
            f"{path}, {lines(row)}: recovered must be 1/0, true/false or "
            f"yes/no, got {text['recovered'].iloc[row]!r}"
        )
    frame["recovered"] = np.where(words.isin(TRUE), 1.0, np.where(words.isin(FALSE), 0.0, np.nan))
    if "duration" not in frame:
        raise ParameterError(
            f"{path}: a recovered value needs the push's duration (a column duration)"
        )
    missing = frame["recovered"].notna() & frame["duration"].isna()
    if missing.any():
        row = int(np.flatnonzero(missing)[0])
        raise ParameterError(f"{path}, {lines(row)}: a recovered value needs the push's duration")


def _one_value_each(path: Path, frame: pd.DataFrame, lines: _Lines) -> None:
    """Refuse two different values of one measure for one force, or two outcomes of one push
    (force, duration); a repeated equal value is kept once (the later one emptied, so that it
    is scored once). The same force: the same number (20 and 20.0 are one; 20 and 20.0001 are
    two rows, each scored against our table's nearest same force)."""
    force = pd.factorize(frame["force"])[0]
    keys: list[tuple[str, np.ndarray]] = [(m, force) for m in MEASURES if m in frame]
    if "recovered" in frame:
        keys.append(
            (
                "recovered",
                pd.MultiIndex.from_arrays(
                    [frame["force"], frame["duration"].fillna(-1.0)]
                ).factorize()[0],
            )
        )
    for column, key in keys:
        values = frame[column].to_numpy(float)
        given = np.flatnonzero(np.isfinite(values))
        if given.size < 2:
            continue
        groups = pd.DataFrame({"key": key[given], "value": values[given], "row": given})
        first = groups.groupby("key", sort=False)[["value", "row"]].transform("first")
        repeated = groups["row"].to_numpy() != first["row"].to_numpy()
        differs = repeated & (groups["value"].to_numpy() != first["value"].to_numpy())
        if differs.any():
            i = int(np.flatnonzero(differs)[0])
            a, b = int(first["row"].iloc[i]), int(groups["row"].iloc[i])
            what = (
                f"push {frame['force'].iloc[a]:g} N x {frame['duration'].iloc[a]:g} s"
                if column == "recovered"
                else f"force {frame['force'].iloc[a]:g} N"
            )
            raise ParameterError(
                f"{path}, {lines.both(a, b)}: two different {column} for the {what} "
                f"({frame[column].iloc[a]:.12g} and {frame[column].iloc[b]:.12g}); keep the one "
                "you mean"
            )
        if repeated.any():  # the same value again: scored once
            frame.loc[groups["row"].to_numpy()[repeated], column] = np.nan


def read_references(
    paths: Sequence[str | os.PathLike[str]] | str | os.PathLike[str] | None,
) -> list[Reference]:
    """Every reference file (labels made unique by a suffix: ``study``, ``study_2``).
    ``paths``: a path, a shipped reference's name or a sequence of them (TypeError for
    anything else, naming what is accepted)."""
    if paths is None:
        return []
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    elif (
        not isinstance(paths, Sequence)
        or isinstance(paths, bytes)
        or not all(isinstance(p, (str, os.PathLike)) for p in paths)
    ):
        bad = (
            paths
            if not isinstance(paths, Sequence) or isinstance(paths, bytes)
            else next(p for p in paths if not isinstance(p, (str, os.PathLike)))
        )
        raise TypeError(
            f"reference: expected a CSV path, the name of a shipped reference "
            f"({', '.join(references.SHIPPED)}) or a list of them; got "
            f"{type(bad).__name__} {bad!r}"
        )
    refs = [read_reference(p) for p in paths]
    seen: set[str] = set()
    for ref in refs:
        label, count = ref.label, 1
        while label in seen:
            count += 1
            label = f"{ref.label}_{count}"
        ref.label = label
        seen.add(label)
    return refs


def reference_forces(
    refs: Sequence[Reference], forces: Sequence[float] | np.ndarray | None = None
) -> list[float]:
    """The forces the references' tables score (for a table run that covers them), each once
    (forces within :data:`FORCE_RTOL` of each other are one force); with ``forces`` (our
    table's), only those it does not already hold within that tolerance: the same rule
    matches a reference row to our table's row."""
    kept: list[float] = []
    for force in sorted({f for ref in refs for f in ref.forces}):
        if not kept or abs(force - kept[-1]) > FORCE_ATOL + FORCE_RTOL * abs(kept[-1]):
            kept.append(force)  # one force per cluster: the smallest (the rest match it)
    wanted = np.asarray(kept, float)
    if forces is not None and wanted.size:
        wanted = wanted[nearest_force(np.asarray(forces, float).ravel(), wanted) < 0]
    return [float(f) for f in wanted]


def same_force(a: float | np.ndarray, b: float | np.ndarray) -> np.ndarray:
    """Whether forces ``a`` and ``b`` are one force: within :data:`FORCE_RTOL` of ``b`` (plus
    :data:`FORCE_ATOL`), the one tolerance of adding reference forces to a table and of
    matching them in it."""
    return np.isclose(a, b, rtol=FORCE_RTOL, atol=FORCE_ATOL)


def nearest_force(known: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """For each of ``wanted``, the index in ``known`` of the nearest force that is the same
    force (:func:`same_force`), -1 where none is."""
    known = np.asarray(known, float)
    wanted = np.asarray(wanted, float)
    result = np.full(wanted.shape, -1, int)
    if not known.size or not wanted.size:
        return result
    order = np.argsort(known, kind="stable")
    ordered = known[order]
    right = np.clip(np.searchsorted(ordered, wanted), 0, len(ordered) - 1)
    left = np.clip(right - 1, 0, len(ordered) - 1)
    with np.errstate(invalid="ignore"):
        pick = np.where(
            np.abs(ordered[left] - wanted) <= np.abs(ordered[right] - wanted), left, right
        )
    near = ordered[pick]
    return np.where(same_force(wanted, near) & np.isfinite(near), order[pick], -1)


def reference_points(refs: Sequence[Reference]) -> pd.DataFrame | None:
    """Every reference's pushes (force, duration, label) to draw on a region map."""
    frames = [p for p in (ref.points() for ref in refs) if p is not None]
    return pd.concat(frames, ignore_index=True) if frames else None


def unused_points(refs: Sequence[Reference], has_map: bool) -> list[str]:
    """One line per points reference (pushes to draw, no table to score) that nothing uses: a
    table without a region map beside it scores only table references."""
    if has_map:
        return []
    return [
        f"reference {ref.path}: its pushes (force, duration) are drawn on a region map, and "
        "this folder has none (sweep --reference draws them); no scorecard from it"
        for ref in refs
        if ref.kind == "points"
    ]


def stated_resolution(text: str) -> float:
    """The resolution a printed number states: one unit of its last decimal ("0.45": 0.01,
    "120": 1, "1.2e-3": 1e-4)."""
    text = text.strip().lower()
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa.partition(".")[2]) if "." in mantissa else 0
    return 10.0 ** (-decimals + (int(exponent) if exponent else 0))


# -- our side ------------------------------------------------------------------------------------
