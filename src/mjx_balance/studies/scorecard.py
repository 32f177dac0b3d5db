"""The reproduction scorecard: a published (or a lab's) table beside ours, row by row.

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

Each reference row and measure gives one scorecard row (:data:`SCORECARD_COLUMNS`): the
reference's value, ours, our uncertainty, the absolute and relative difference, the tolerance
and what it was derived from, and whether the difference is within it. The default tolerance is
the reference's half resolution plus our uncertainty: for the max acting time the bisection step
(``RESOLUTION`` = 0.01 s: the true limit lies between our value and one step above it); for an
energy at the max acting time the change of that energy over one bisection step, measured from
the two longest recovered runs of that force (table_runs.parquet); for an energy at 0.1 s
nothing (the push is the same push), so the reference's resolution alone. Never today's
agreement. An energy is compared only where our push recovered: the energy of a fall is not a
recovery cost (our table leaves it empty; the row says "not comparable").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from ..figures.scorecard import plot_scorecard
from ..model.params import ParameterError
from ..runs.acting_time import MOTOR_ENERGY_COLUMNS, STUDY_ENERGY_COLUMNS
from ..store.files import REGION, TABLE, TABLE_RUNS, write_csv
from . import references

RESOLUTION = 0.01  # s: the table's bisection step (runs.acting_time)
MEASURES = ["max_acting_time", *STUDY_ENERGY_COLUMNS, *MOTOR_ENERGY_COLUMNS]
UNITS = {"max_acting_time": "s", "recovered": "", **{m: "J" for m in MEASURES[1:]}}
OPTIONAL = ("duration", "label", "source", "reason", "resolution", "tolerance")
SCORECARD_COLUMNS = [
    "source", "force", "duration", "measure", "unit", "reference", "ours", "our_uncertainty",
    "abs_diff", "rel_diff", "tolerance", "tolerance_basis", "within", "status", "reason",
    "citation",
]
TRUE = {"1", "true", "yes", "y", "recovered"}
FALSE = {"0", "false", "no", "n", "fell", "not_recovered"}


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


def read_reference(path: str | Path) -> Reference:
    """Read and check one reference file, or a shipped reference by name (``"study"``:
    :mod:`studies.references`); ParameterError naming the file, row and column."""
    path = references.resolve(path)
    try:
        text = pd.read_csv(path, dtype=str, keep_default_na=False, comment="#")
    except FileNotFoundError:
        raise ParameterError(f"reference file not found: {path} (the shipped references: "
                             f"{', '.join(references.SHIPPED)})") from None
    except Exception as exc:  # noqa: BLE001 - any parse failure is the file's
        raise ParameterError(f"{path}: not a readable CSV ({exc})") from None
    text.columns = [str(c).strip().lower() for c in text.columns]
    text = text.apply(lambda column: column.str.strip())
    if "force" not in text or len(text) == 0:
        raise ParameterError(f"{path}: a reference file needs a column force and at least one "
                             "row (docs/outputs.md, 'Reference files')")
    unknown = [c for c in text.columns if c not in {"force", "recovered", *MEASURES, *OPTIONAL}]
    if unknown:
        raise ParameterError(f"{path}: unknown column(s) {', '.join(unknown)}; known: force, "
                             f"duration, recovered, {', '.join(MEASURES)}, "
                             f"{', '.join(OPTIONAL[1:])}")
    frame = text.copy()
    numeric = [c for c in ("force", "duration", "resolution", "tolerance", *MEASURES)
               if c in text]
    for column in numeric:
        values = pd.to_numeric(text[column].replace("", np.nan), errors="coerce")
        bad = values.isna() & (text[column] != "")
        if bad.any() or (column in ("force",) and values.isna().any()):
            row = int(np.flatnonzero(bad | (values.isna() if column == "force" else bad))[0])
            raise ParameterError(f"{path}, row {row + 2}: {column} must be a number, got "
                                 f"{text[column].iloc[row]!r}")
        if column != "force" and (values < 0).any():
            raise ParameterError(f"{path}: {column} must not be negative")
        frame[column] = values
    if "recovered" in text:
        _read_recovered(path, text, frame)
    kind = "table" if ("recovered" in frame or any(m in frame for m in MEASURES)) else "points"
    if kind == "points" and "duration" not in frame:
        raise ParameterError(f"{path}: needs either duration (points to draw) or a measure "
                             f"column ({', '.join(MEASURES[:3])}, ...) or recovered")
    label = (str(frame["label"].iloc[0]) if "label" in frame and frame["label"].iloc[0]
             else path.stem)
    return Reference(path, label, kind, frame, text)


def _read_recovered(path: Path, text: pd.DataFrame, frame: pd.DataFrame) -> None:
    """The ``recovered`` column as 1.0 / 0.0 / NaN (empty), checked; it needs durations."""
    words = text["recovered"].str.lower()
    bad = ~words.isin(TRUE | FALSE | {""})
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ParameterError(f"{path}, row {row + 2}: recovered must be 1/0, true/false or "
                             f"yes/no, got {text['recovered'].iloc[row]!r}")
    frame["recovered"] = np.where(words.isin(TRUE), 1.0, np.where(words.isin(FALSE), 0.0,
                                                                  np.nan))
    if "duration" not in frame or frame.loc[frame["recovered"].notna(), "duration"].isna().any():
        raise ParameterError(f"{path}: a recovered value needs the push's duration")


def read_references(paths: Sequence[str | Path] | str | Path | None) -> list[Reference]:
    """Every reference file (labels made unique by a suffix)."""
    if paths is None:
        return []
    if isinstance(paths, (str, Path)):
        paths = [paths]
    refs = [read_reference(p) for p in paths]
    seen: dict[str, int] = {}
    for ref in refs:
        count = seen.get(ref.label, 0)
        seen[ref.label] = count + 1
        if count:
            ref.label = f"{ref.label}_{count + 1}"
    return refs


def reference_forces(refs: Sequence[Reference]) -> list[float]:
    """The forces the references' tables score (for a table run that covers them)."""
    return sorted({f for ref in refs for f in ref.forces})


def reference_points(refs: Sequence[Reference]) -> pd.DataFrame | None:
    """Every reference's pushes (force, duration, label) to draw on a region map."""
    frames = [p for p in (ref.points() for ref in refs) if p is not None]
    return pd.concat(frames, ignore_index=True) if frames else None


def stated_resolution(text: str) -> float:
    """The resolution a printed number states: one unit of its last decimal ("0.45": 0.01,
    "120": 1, "1.2e-3": 1e-4)."""
    text = text.strip().lower()
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa.partition(".")[2]) if "." in mantissa else 0
    return 10.0 ** (-decimals + (int(exponent) if exponent else 0))


# -- our side ------------------------------------------------------------------------------------


def _match(frame: pd.DataFrame, force: float) -> pd.DataFrame:
    return frame[np.isclose(frame["force"].to_numpy(float), force, rtol=0, atol=1e-9)]


def energy_step(runs: pd.DataFrame | None, force: float, measure: str,
                max_time: float) -> float:
    """How much an energy at the max acting time moves over one bisection step: the change
    between the two longest recovered runs of that force (one step apart or scaled to one),
    NaN when the runs are not there."""
    if runs is None or not len(runs) or not np.isfinite(max_time):
        return float("nan")
    column = measure[:-len("_max")]
    if column not in runs:
        return float("nan")
    rec = _match(runs, force)
    rec = rec[(rec["outcome"] == "recovered") & (rec["duration"] <= max_time + 1e-9)]
    rec = rec.drop_duplicates("duration").sort_values("duration")
    if len(rec) < 2:
        return float("nan")
    (d0, e0), (d1, e1) = rec[["duration", column]].to_numpy(float)[-2:]
    return float(abs(e1 - e0) / max(d1 - d0, RESOLUTION) * RESOLUTION)


def our_value(measure: str, force: float, table: pd.DataFrame | None,
              runs: pd.DataFrame | None) -> tuple[float, float, str, str]:
    """(ours, our uncertainty, its basis, status) of a table measure at ``force``; status is
    '' when there is a value to compare, else why not."""
    row = None if table is None else _match(table, force)
    if row is None or not len(row):
        return math.nan, math.nan, "", "not computed: force not in our table"
    row = row.iloc[0]
    if measure not in row.index:
        return math.nan, math.nan, "", f"not computed: our table has no {measure}"
    value = float(row[measure])
    if measure == "max_acting_time":
        return value, RESOLUTION, f"our bisection step {RESOLUTION:g} s", ""
    if not np.isfinite(value):
        what = "0.1-s push" if measure.endswith("_01") else "push"
        return math.nan, math.nan, "", (f"not comparable: our {what} at this force did not "
                                        "recover (the energy of a fall is not a recovery cost)")
    if measure.endswith("_01"):
        return value, 0.0, "the same push (T = 0.1 s)", ""
    step = energy_step(runs, force, measure, float(row["max_acting_time"]))
    basis = (f"its change over one bisection step ({step:.3g} J)" if np.isfinite(step)
             else "our uncertainty unknown (no neighbouring recovered run)")
    return value, step, basis, ""


def our_recovered(force: float, duration: float, table: pd.DataFrame | None,
                  region: pd.DataFrame | None) -> tuple[float, str, str]:
    """(1.0 / 0.0 / NaN, how we know it, status) of the push (force, duration)."""
    if region is not None and len(region):
        cell = _match(region, force)
        cell = cell[np.isclose(cell["duration"].to_numpy(float), duration, rtol=0, atol=1e-9)]
        if len(cell):
            return float(cell["outcome"].iloc[0] == "recovered"), "our region map's cell", ""
    row = None if table is None else _match(table, force)
    if row is None or not len(row):
        return math.nan, "", "not computed: (force, duration) in neither our map nor our table"
    row = row.iloc[0]
    limit = float(row["max_acting_time"])
    if not bool(row.get("monotone", True)):
        return math.nan, "", "not computed: recovery is not monotone in duration at this force"
    if limit < duration < limit + RESOLUTION:
        return math.nan, "", (f"uncertain: within one bisection step of our max acting time "
                              f"{limit:g} s")
    return float(duration <= limit), f"our max acting time {limit:g} s", ""


# -- the scorecard ---------------------------------------------------------------------------------


def _tolerance(ref: Reference, i: int, column: str, ours_unc: float,
               ours_basis: str) -> tuple[float, str]:
    unit = UNITS.get(column, "")
    if "tolerance" in ref.frame and np.isfinite(ref.frame["tolerance"].iloc[i]):
        return float(ref.frame["tolerance"].iloc[i]), "the reference file's tolerance"
    if "resolution" in ref.frame and np.isfinite(ref.frame["resolution"].iloc[i]):
        res, said = float(ref.frame["resolution"].iloc[i]), "stated"
    else:
        res, said = stated_resolution(ref.text[column].iloc[i]), "printed"
    unc = ours_unc if np.isfinite(ours_unc) else 0.0
    basis = f"half the reference's {said} resolution {res:g} {unit}".rstrip()
    return res / 2 + unc, f"{basis} + {ours_basis}" if ours_basis else basis


def score(ref: Reference, table: pd.DataFrame | None, *, runs: pd.DataFrame | None = None,
          region: pd.DataFrame | None = None) -> pd.DataFrame:
    """The scorecard rows of one reference (empty for a points file)."""
    rows = []
    if ref.kind != "table":
        return pd.DataFrame(columns=SCORECARD_COLUMNS)
    f = ref.frame
    for i in range(len(f)):
        force = float(f["force"].iloc[i])
        common = {"source": ref.label, "force": force,
                  "reason": f["reason"].iloc[i] if "reason" in f else "",
                  "citation": f["source"].iloc[i] if "source" in f else ""}
        for measure in ref.measures:
            reference = float(f[measure].iloc[i])
            if not np.isfinite(reference):
                continue
            ours, unc, basis, status = our_value(measure, force, table, runs)
            tol, tol_basis = _tolerance(ref, i, measure, unc, basis)
            rows.append(_row(common, measure, np.nan, reference, ours, unc, tol=tol,
                             tol_basis=tol_basis, status=status))
        if "recovered" in f and np.isfinite(f["recovered"].iloc[i]):
            duration = float(f["duration"].iloc[i])
            ours, how, status = our_recovered(force, duration, table, region)
            rows.append(_row(common, "recovered", duration, float(f["recovered"].iloc[i]),
                             ours, 0.0, tol=0.0, tol_basis=f"exact: {how}" if how else "",
                             status=status))
    return pd.DataFrame(rows, columns=SCORECARD_COLUMNS)


def _row(common: dict, measure: str, duration: float, reference: float, ours: float,
         unc: float, *, tol: float, tol_basis: str, status: str) -> dict:
    diff = ours - reference
    rel = diff / abs(reference) if reference else (0.0 if diff == 0 else math.inf)
    ok = bool(np.isfinite(diff) and abs(diff) <= tol + 1e-12)
    if not status:
        status = "agrees" if ok else "differs"
    return {**common, "duration": duration, "measure": measure, "unit": UNITS.get(measure, ""),
            "reference": reference, "ours": ours, "our_uncertainty": unc,
            "abs_diff": diff, "rel_diff": rel if np.isfinite(diff) else math.nan,
            "tolerance": tol, "tolerance_basis": tol_basis, "within": ok, "status": status}


def scorecard(table: pd.DataFrame | None, refs: Sequence[Reference], *,
              runs: pd.DataFrame | None = None,
              region: pd.DataFrame | None = None) -> pd.DataFrame:
    """Every reference's scorecard rows, one after another (:data:`SCORECARD_COLUMNS`)."""
    parts = [score(ref, table, runs=runs, region=region) for ref in refs]
    parts = [p for p in parts if len(p)]
    if not parts:
        return pd.DataFrame(columns=SCORECARD_COLUMNS)
    return pd.concat(parts, ignore_index=True)


def summary(card: pd.DataFrame) -> pd.DataFrame:
    """Per source: rows compared (a value on both sides), agreeing, differing (with and
    without a reason) and not compared."""
    rows = []
    for source, group in card.groupby("source", sort=False):
        compared = group["status"].isin(["agrees", "differs"])
        differs = group["status"] == "differs"
        reasoned = differs & group["reason"].fillna("").astype(str).str.len().gt(0)
        rows.append({"source": source, "rows": len(group), "compared": int(compared.sum()),
                     "agree": int((group["status"] == "agrees").sum()),
                     "differ": int(differs.sum()), "differ_with_reason": int(reasoned.sum()),
                     "not_compared": int((~compared).sum())})
    return pd.DataFrame(rows, columns=["source", "rows", "compared", "agree", "differ",
                                       "differ_with_reason", "not_compared"])


def summary_text(card: pd.DataFrame) -> str:
    """One line per source: how many rows agree, differ (and have a reason), are not compared."""
    lines = []
    for row in summary(card).itertuples():
        lines.append(f"{row.source}: {row.agree} of {row.compared} compared rows agree within "
                     f"tolerance, {row.differ} differ ({row.differ_with_reason} with a reason "
                     f"from the reference file), {row.not_compared} not compared")
    return "\n".join(lines)


# -- a folder's scorecard ------------------------------------------------------------------------

SCORECARD = "scorecard.csv"
SCORECARD_FIGURE = "scorecard.png"


def folder_results(folder: str | Path) -> dict[str, pd.DataFrame | None]:
    """Our saved results in a sweep or table folder: table.csv, table_runs.parquet and
    region.parquet (None for any that is not there)."""
    folder = Path(folder)
    found: dict[str, pd.DataFrame | None] = {"table": None, "runs": None, "region": None}
    if (folder / TABLE).exists():
        found["table"] = pd.read_csv(folder / TABLE)
    if (folder / TABLE_RUNS).exists():
        found["runs"] = pd.read_parquet(folder / TABLE_RUNS)
    if (folder / REGION).exists():
        found["region"] = pd.read_parquet(folder / REGION)
    return found


def write_scorecard(folder: str | Path, refs: Sequence[Reference], *,
                    figure: bool = True) -> pd.DataFrame | None:
    """scorecard.csv (and scorecard.png) in ``folder`` from its saved results and ``refs``;
    None when no reference is a table. Written atomically."""
    tables = [r for r in refs if r.kind == "table"]
    if not tables:
        return None
    folder = Path(folder)
    found = folder_results(folder)
    card = scorecard(found["table"], tables, runs=found["runs"], region=found["region"])
    write_csv(card, folder / SCORECARD)
    if figure:
        plot_scorecard(card, folder / SCORECARD_FIGURE, table=found["table"])
    return card
