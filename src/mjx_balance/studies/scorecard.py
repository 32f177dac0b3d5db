"""The reproduction scorecard: a published (or a lab's) table beside ours, row by row.

A reference file (its kinds and columns: ``reference_files``; docs/outputs.md, "Reference
files") is read by :mod:`reference_files`; this module scores it.

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
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..figures.scorecard import plot_scorecard
from ..model.params import ParameterError
from ..store.files import REGION, TABLE, TABLE_RUNS, write_csv
from .reference_files import MEASURES, Reference, nearest_force, stated_resolution

RESOLUTION = 0.01  # s: the table's bisection step (runs.acting_time)
UNITS = {"max_acting_time": "s", "recovered": "", **{m: "J" for m in MEASURES[1:]}}
SCORECARD_COLUMNS = [
    "source",
    "force",
    "duration",
    "measure",
    "unit",
    "reference",
    "ours",
    "our_uncertainty",
    "abs_diff",
    "rel_diff",
    "tolerance",
    "tolerance_basis",
    "within",
    "status",
    "reason",
    "citation",
]
DURATION_ATOL = 1e-9  # s: a reference push's duration is a cell's of our map within this


def _match(frame: pd.DataFrame, force: float) -> pd.DataFrame:
    """``frame``'s rows of the force nearest ``force`` that is the same force (same_force)."""
    forces = frame["force"].to_numpy(float)
    index = nearest_force(forces, np.asarray([force], float))[0]
    if index < 0:
        return frame.iloc[0:0]
    return frame[forces == forces[index]]


def energy_step(runs: pd.DataFrame | None, force: float, measure: str, max_time: float) -> float:
    """How much an energy at the max acting time moves over one bisection step: the change
    between the two longest recovered runs of that force (one step apart or scaled to one),
    NaN when the runs are not there."""
    if runs is None or not len(runs) or not np.isfinite(max_time):
        return float("nan")
    column = measure[: -len("_max")]
    if column not in runs:
        return float("nan")
    rec = _match(runs, force)
    rec = rec[(rec["outcome"] == "recovered") & (rec["duration"] <= max_time + 1e-9)]
    rec = rec.drop_duplicates("duration").sort_values("duration")
    if len(rec) < 2:
        return float("nan")
    (d0, e0), (d1, e1) = rec[["duration", column]].to_numpy(float)[-2:]
    return float(abs(e1 - e0) / max(d1 - d0, RESOLUTION) * RESOLUTION)


def our_value(
    measure: str, force: float, table: pd.DataFrame | None, runs: pd.DataFrame | None
) -> tuple[float, float, str, str]:
    """(ours, our uncertainty, its basis, status) of a table measure at ``force``; status is
    '' when there is a value to compare, else why not. The rule for one row; :func:`score`
    applies it to whole columns."""
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
        return math.nan, math.nan, "", _fell(measure)
    if measure.endswith("_01"):
        return value, 0.0, "the same push (T = 0.1 s)", ""
    step = energy_step(
        runs, float(row["force"]), measure, float(row.get("max_acting_time", math.nan))
    )
    return value, step, _step_basis(step), ""


def _fell(measure: str) -> str:
    what = "0.1-s push" if measure.endswith("_01") else "push"
    return (
        f"not comparable: our {what} at this force did not recover (the energy of a fall "
        "is not a recovery cost)"
    )


def _step_basis(step: float) -> str:
    return (
        f"its change over one bisection step ({step:.3g} J)"
        if np.isfinite(step)
        else "our uncertainty unknown (no neighbouring recovered run)"
    )


def our_recovered(
    force: float, duration: float, table: pd.DataFrame | None, region: pd.DataFrame | None
) -> tuple[float, str, str]:
    """(1.0 / 0.0 / NaN, how we know it, status) of the push (force, duration). The rule for
    one row; :func:`score` applies it to whole columns."""
    if region is not None and len(region):
        cell = _match(region, force)
        cell = cell[
            np.isclose(cell["duration"].to_numpy(float), duration, rtol=0, atol=DURATION_ATOL)
        ]
        if len(cell):
            return float(cell["outcome"].iloc[0] == "recovered"), "our region map's cell", ""
    row = None if table is None else _match(table, force)
    if row is None or not len(row):
        return math.nan, "", "not computed: (force, duration) in neither our map nor our table"
    row = row.iloc[0]
    if "max_acting_time" not in row.index:
        return math.nan, "", "not computed: our table has no max_acting_time"
    limit = float(row["max_acting_time"])
    if not np.isfinite(limit):
        return math.nan, "", "not computed: our table has no max acting time at this force"
    if not bool(row.get("monotone", True)):
        return math.nan, "", "not computed: recovery is not monotone in duration at this force"
    if limit < duration < limit + RESOLUTION:
        return (
            math.nan,
            "",
            (f"uncertain: within one bisection step of our max acting time {limit:g} s"),
        )
    return float(duration <= limit), f"our max acting time {limit:g} s", ""


def check_ours(table: pd.DataFrame | None, name: str = "table") -> None:
    """Our table as the scorecard reads it: a DataFrame with a numeric ``force`` column
    (ParameterError, a ValueError, naming ``name`` and what is missing: exit 2 on the command
    line; TypeError for another type)."""
    if table is None:
        return
    if not isinstance(table, pd.DataFrame):
        raise TypeError(
            f"{name}: expected a table DataFrame (as mjx_balance.table returns "
            f"it); got {type(table).__name__}"
        )
    if "force" not in table:
        found = ", ".join(map(str, table.columns)) or "none"
        raise ParameterError(
            f"{name}: our table needs the column force (and the measures to "
            f"compare: max_acting_time, ...; as mjx_balance.table returns it); "
            f"its columns: {found}"
        )
    try:
        table["force"].to_numpy(float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{name}: column force must hold numbers (newtons), got "
            f"{table['force'].iloc[:3].tolist()}"
        ) from None


# -- the scorecard ---------------------------------------------------------------------------------


def _printed_resolutions(text: pd.Series) -> np.ndarray:
    """:func:`stated_resolution` of every text of a column at once (each distinct text once)."""
    codes, uniques = pd.factorize(text.to_numpy(object))
    if len(uniques) <= 4096:
        return np.asarray([stated_resolution(str(u)) for u in uniques], float)[codes]
    words = pd.Series(uniques, dtype=str).str.strip().str.lower()
    length = words.str.len().to_numpy(float)
    e = words.str.find("e").to_numpy(float)
    end = np.where(e >= 0, e, length)
    dot = words.str.find(".").to_numpy(float)
    decimals = np.where((dot >= 0) & (dot < end), end - dot - 1, 0.0)
    power = np.zeros(len(words))
    has_e = e >= 0
    if has_e.any():
        tail = [w[int(i) + 1 :] for w, i in zip(words[has_e], e[has_e])]
        power[has_e] = [int(t) if t else 0 for t in tail]
    return (10.0 ** (-decimals + power))[codes]


def _tolerances(
    ref: Reference, rows: np.ndarray, column: str, ours_unc: np.ndarray, ours_basis: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each row's tolerance and its basis: the file's tolerance, else half its stated (or
    printed) resolution plus our uncertainty."""
    unit = UNITS.get(column, "")
    n = len(rows)
    stated = (
        ref.frame["resolution"].to_numpy(float)[rows]
        if "resolution" in ref.frame
        else np.full(n, np.nan)
    )
    has_stated = np.isfinite(stated)
    res = stated.copy()
    if not has_stated.all():
        printed = ref.text[column].iloc[rows[~has_stated]]
        res[~has_stated] = _printed_resolutions(printed)
    unc = np.where(np.isfinite(ours_unc), ours_unc, 0.0)
    tol = res / 2 + unc
    combos = pd.DataFrame(
        {
            "stated": has_stated,
            "res": res,
            "ours": pd.Series(ours_basis, dtype=object).fillna("").to_numpy(),
        }
    )
    codes = combos.groupby(["stated", "res", "ours"], sort=False).ngroup().to_numpy()
    first = combos.drop_duplicates(["stated", "res", "ours"])
    words = []
    basis: str | np.ndarray  # (a line's words, then every row's)
    for said, value, ours in zip(first["stated"], first["res"], first["ours"]):
        basis = (
            f"half the reference's {'stated' if said else 'printed'} resolution {value:g} {unit}"
        ).rstrip()
        words.append(f"{basis} + {ours}" if ours else basis)
    basis = np.asarray(words, object)[codes] if n else np.asarray([], object)
    if "tolerance" in ref.frame:
        given = ref.frame["tolerance"].to_numpy(float)[rows]
        own = np.isfinite(given)
        tol = np.where(own, given, tol)
        basis = np.where(own, "the reference file's tolerance", basis)
    return tol, basis


def _table_values(table: pd.DataFrame | None, column: str, index: np.ndarray) -> np.ndarray:
    """``table[column]`` at ``index`` (NaN where the index is -1 or the column absent)."""
    out = np.full(len(index), np.nan)
    if table is None or column not in table:
        return out
    have = index >= 0
    out[have] = pd.to_numeric(table[column], errors="coerce").to_numpy(float)[index[have]]
    return out


def _our_values(
    measure: str, index: np.ndarray, table: pd.DataFrame | None, runs: pd.DataFrame | None
) -> tuple[np.ndarray, ...]:
    """:func:`our_value` for the table rows ``index`` (-1: the force is not in our table)."""
    n = len(index)
    ours, unc = np.full(n, np.nan), np.full(n, np.nan)
    basis, status = np.full(n, "", object), np.full(n, "", object)
    found = index >= 0
    status[~found] = "not computed: force not in our table"
    if table is None or measure not in table:
        status[found] = f"not computed: our table has no {measure}"
        return ours, unc, basis, status
    value = _table_values(table, measure, index)
    if measure == "max_acting_time":
        ours[found], unc[found] = value[found], RESOLUTION
        basis[found] = f"our bisection step {RESOLUTION:g} s"
        return ours, unc, basis, status
    status[found & ~np.isfinite(value)] = _fell(measure)
    have = found & np.isfinite(value)
    ours[have] = value[have]
    if measure.endswith("_01"):
        unc[have], basis[have] = 0.0, "the same push (T = 0.1 s)"
        return ours, unc, basis, status
    limits = _table_values(table, "max_acting_time", index)
    forces = table["force"].to_numpy(float)
    for row in np.unique(index[have]):  # one step per force of our table
        mine = have & (index == row)
        step = energy_step(runs, float(forces[row]), measure, float(limits[mine][0]))
        unc[mine], basis[mine] = step, _step_basis(step)
    return ours, unc, basis, status


def _our_recovereds(
    forces: np.ndarray,
    durations: np.ndarray,
    index: np.ndarray,
    table: pd.DataFrame | None,
    region: pd.DataFrame | None,
) -> tuple[np.ndarray, ...]:
    """:func:`our_recovered` for whole columns: (1/0/NaN, how we know it, status)."""
    n = len(forces)
    ours = np.full(n, np.nan)
    how, status = np.full(n, "", object), np.full(n, "", object)
    todo = np.ones(n, bool)
    if region is not None and len(region):
        cells = region["force"].to_numpy(float)
        known = np.unique(cells)
        wanted = nearest_force(known, forces)
        left = pd.DataFrame({"key": wanted, "duration": durations, "at": np.arange(n)})
        left = left[left["key"] >= 0].sort_values("duration", kind="stable")
        right = pd.DataFrame(
            {
                "key": np.searchsorted(known, cells),
                "duration": region["duration"].to_numpy(float),
                "recovered": (region["outcome"] == "recovered").to_numpy(float),
            }
        )
        right = (
            right.dropna(subset=["duration"])
            .drop_duplicates(["key", "duration"])
            .sort_values("duration", kind="stable")
        )
        if len(left) and len(right):
            hit = pd.merge_asof(
                left, right, on="duration", by="key", direction="nearest", tolerance=DURATION_ATOL
            ).dropna(subset=["recovered"])
            at = hit["at"].to_numpy(int)
            ours[at], how[at] = hit["recovered"].to_numpy(float), "our region map's cell"
            todo[at] = False
    status[todo & (index < 0)] = "not computed: (force, duration) in neither our map nor our table"
    rest = todo & (index >= 0)
    if not rest.any():
        return ours, how, status
    assert table is not None  # (index >= 0 only against a table: score)
    if "max_acting_time" not in table:
        status[rest] = "not computed: our table has no max_acting_time"
        return ours, how, status
    limit = _table_values(table, "max_acting_time", index)
    monotone = (
        np.asarray([bool(v) for v in table["monotone"]])
        if "monotone" in table
        else np.ones(len(table), bool)
    )[np.maximum(index, 0)]
    unknown = rest & ~np.isfinite(limit)
    status[unknown] = "not computed: our table has no max acting time at this force"
    rest &= ~unknown
    bent = rest & ~monotone
    status[bent] = "not computed: recovery is not monotone in duration at this force"
    rest &= monotone
    near = rest & (limit < durations) & (durations < limit + RESOLUTION)
    said = {v: f"{v:g}" for v in np.unique(limit[rest])}
    for value, text in said.items():
        status[near & (limit == value)] = (
            f"uncertain: within one bisection step of our max acting time {text} s"
        )
        mine = rest & ~near & (limit == value)
        how[mine] = f"our max acting time {text} s"
    decided = rest & ~near
    ours[decided] = (durations[decided] <= limit[decided]).astype(float)
    return ours, how, status


def score(
    ref: Reference,
    table: pd.DataFrame | None,
    *,
    runs: pd.DataFrame | None = None,
    region: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """The scorecard rows of one reference (empty for a points file): for each of its rows, one
    per measure it gives (in :data:`MEASURES` order), then its ``recovered``."""
    if ref.kind != "table":
        return pd.DataFrame(columns=SCORECARD_COLUMNS)
    check_ours(table)
    f = ref.frame
    forces = f["force"].to_numpy(float)
    index = (
        nearest_force(table["force"].to_numpy(float), forces)
        if table is not None and len(table)
        else np.full(len(f), -1)
    )
    reason = f["reason"].to_numpy(object) if "reason" in f else np.full(len(f), "", object)
    citation = f["source"].to_numpy(object) if "source" in f else np.full(len(f), "", object)
    parts = []
    for k, measure in enumerate(ref.measures):
        reference = f[measure].to_numpy(float)
        rows = np.flatnonzero(np.isfinite(reference))
        if not rows.size:
            continue
        ours, unc, basis, status = _our_values(measure, index[rows], table, runs)
        tol, tol_basis = _tolerances(ref, rows, measure, unc, basis)
        parts.append(
            _rows(
                rows,
                k,
                measure,
                duration=np.full(rows.size, np.nan),
                reference=reference[rows],
                ours=ours,
                unc=unc,
                tol=tol,
                tol_basis=tol_basis,
                status=status,
            )
        )
    if "recovered" in f:
        reference = f["recovered"].to_numpy(float)
        rows = np.flatnonzero(np.isfinite(reference))
        if rows.size:
            durations = f["duration"].to_numpy(float)[rows]
            ours, how, status = _our_recovereds(forces[rows], durations, index[rows], table, region)
            tol_basis = np.where(how != "", "exact: " + how.astype(str), "").astype(object)
            parts.append(
                _rows(
                    rows,
                    len(MEASURES),
                    "recovered",
                    duration=durations,
                    reference=reference[rows],
                    ours=ours,
                    unc=np.zeros(rows.size),
                    tol=np.zeros(rows.size),
                    tol_basis=tol_basis,
                    status=status,
                )
            )
    if not parts:
        return pd.DataFrame(columns=SCORECARD_COLUMNS)
    columns = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
    order = np.lexsort((columns.pop("_k"), columns["_row"]))  # file order, then measure order
    rows = columns.pop("_row")[order]
    columns = {name: values[order] for name, values in columns.items()}
    columns.update(
        source=np.full(len(rows), ref.label, object),
        force=forces[rows],
        reason=reason[rows],
        citation=citation[rows],
    )
    return pd.DataFrame({name: columns[name] for name in SCORECARD_COLUMNS})


def _rows(
    rows: np.ndarray,
    k: int,
    measure: str,
    *,
    duration: np.ndarray,
    reference: np.ndarray,
    ours: np.ndarray,
    unc: np.ndarray,
    tol: np.ndarray,
    tol_basis: np.ndarray,
    status: np.ndarray,
) -> dict[str, np.ndarray]:
    """Scorecard rows of one measure, as columns: the differences, whether within the tolerance, the
    status (``agrees`` / ``differs`` where there is no other)."""
    diff = ours - reference
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(reference != 0, diff / np.abs(reference), np.where(diff == 0, 0.0, math.inf))
    finite = np.isfinite(diff)
    with np.errstate(invalid="ignore"):
        ok = finite & (np.abs(diff) <= tol + 1e-12)
    status = np.where(status == "", np.where(ok, "agrees", "differs"), status).astype(object)
    n = len(rows)
    return {
        "_row": rows,
        "_k": np.full(n, k),
        "duration": np.asarray(duration, float),
        "measure": np.full(n, measure, object),
        "unit": np.full(n, UNITS.get(measure, ""), object),
        "reference": reference,
        "ours": ours,
        "our_uncertainty": np.asarray(unc, float),
        "abs_diff": diff,
        "rel_diff": np.where(finite, rel, np.nan),
        "tolerance": np.asarray(tol, float),
        "tolerance_basis": np.asarray(tol_basis, object),
        "within": ok,
        "status": status,
    }


def scorecard(
    table: pd.DataFrame | None,
    refs: Sequence[Reference],
    *,
    runs: pd.DataFrame | None = None,
    region: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Every reference's scorecard rows, one after another (:data:`SCORECARD_COLUMNS`)."""
    check_ours(table)
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
        rows.append(
            {
                "source": source,
                "rows": len(group),
                "compared": int(compared.sum()),
                "agree": int((group["status"] == "agrees").sum()),
                "differ": int(differs.sum()),
                "differ_with_reason": int(reasoned.sum()),
                "not_compared": int((~compared).sum()),
            }
        )
    return pd.DataFrame(
        rows,
        columns=[
            "source",
            "rows",
            "compared",
            "agree",
            "differ",
            "differ_with_reason",
            "not_compared",
        ],
    )


def summary_text(card: pd.DataFrame) -> str:
    """One line per source: how many rows agree, differ (and have a reason), are not compared."""
    lines = []
    for row in summary(card).itertuples():
        lines.append(
            f"{row.source}: {row.agree} of {row.compared} compared rows agree within "
            f"tolerance, {row.differ} differ ({row.differ_with_reason} with a reason "
            f"from the reference file), {row.not_compared} not compared"
        )
    return "\n".join(lines)


# -- a folder's scorecard ------------------------------------------------------------------------

SCORECARD = "scorecard.csv"
SCORECARD_FIGURE = "scorecard.png"


def folder_results(folder: str | os.PathLike[str]) -> dict[str, pd.DataFrame | None]:
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


def write_scorecard(
    folder: str | Path, refs: Sequence[Reference], *, figure: bool = True
) -> pd.DataFrame | None:
    """scorecard.csv (and scorecard.png) in ``folder`` from its saved results and ``refs``;
    None when no reference is a table. Written atomically (:func:`scorecard_files`)."""
    return scorecard_files(folder, refs, figure=figure)[0]


def scorecard_files(
    folder: str | Path, refs: Sequence[Reference], *, figure: bool = True
) -> tuple[pd.DataFrame | None, list[Path]]:
    """(the scorecard, the files written): scorecard.csv, and scorecard.png when ``figure``
    and a measure has a panel (a ``recovered``-only scorecard has none: a figure left by an
    earlier run is removed, so that it never disagrees with the csv)."""
    tables = [r for r in refs if r.kind == "table"]
    if not tables:
        return None, []
    folder = Path(folder)
    found = folder_results(folder)
    check_ours(found["table"], str(folder / TABLE))
    card = scorecard(found["table"], tables, runs=found["runs"], region=found["region"])
    write_csv(card, folder / SCORECARD)
    written = [folder / SCORECARD]
    if figure:
        path = plot_scorecard(card, folder / SCORECARD_FIGURE, table=found["table"])
        if path is not None:
            written.append(path)
        else:
            from ..figures.style import figure_path  # lazy: matplotlib

            figure_path(folder / SCORECARD_FIGURE).unlink(missing_ok=True)
    return card, written
