"""The report's reproduction sections: the scorecard against reference files (first section),
and the strategy map inside each convention's region section.

    DIR/references/*.csv   the reference files given with ``report --reference`` (copied, so
                           ``--html-only`` later scores them again)
    DIR/scorecard.csv      every reference row and measure beside ours, per convention
                           (``studies.scorecard``; column ``convention``)

Nothing here infers why a row differs: a reason comes from the reference file's ``reason``
column, and the measured causes of the known differences are in docs/study.md.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..figures.scorecard import plot_scorecard
from ..figures.strategy import plot_strategy, plot_threshold
from ..measures.strategy import HIP_SHARE_THRESHOLD, STRATEGIES
from ..model.params import Config
from ..store.files import write_atomic
from ..studies import references
from ..studies.reference_files import read_references
from ..studies.scorecard import (
    SCORECARD,
    folder_results,
    scorecard,
    summary,
)
from .blocks import img

REFERENCES_DIR = "references"
STUDY = "study"  # the shipped study table, scored in every report's paper convention
SCORECARD_HEADING = "Scorecard: the reference tables beside ours"
DIFFERENCES_DOC = "docs/study.md, 'Differences from the study, and their measured causes'"


def store_references(out: str | Path, paths: Sequence[str | Path] | None) -> list[Path]:
    """Copy the reference files into DIR/references/, each under its own name: the file's stem
    with ``.csv`` (the folder is read as ``*.csv``: a ``lab.txt`` is kept as ``lab.csv``), a
    suffix where two given files share a stem (``a/study.csv`` and ``b/study.csv``:
    ``study.csv`` and ``study_2.csv``, labelled ``study`` and ``study_2`` as when they were
    read); a file stored under the same name by an earlier run is replaced. Returns the stored
    paths. Each is read first, so a bad file is refused before any copy."""
    if not paths:
        return []
    read_references(paths)
    folder = Path(out) / REFERENCES_DIR
    folder.mkdir(parents=True, exist_ok=True)
    stored: list[Path] = []
    for path in paths:
        source = references.resolve(path)  # a shipped reference's name: its file
        stem, count = source.stem or "reference", 1
        target = folder / f"{stem}.csv"
        while target in stored:
            count += 1
            target = folder / f"{stem}_{count}.csv"
        write_atomic(target, lambda tmp, src=source: shutil.copyfile(src, tmp))  # type: ignore[misc]  # mypy cannot infer a lambda with a default argument
        stored.append(target)
    return stored


def reference_files(out: str | Path) -> list[Path]:
    """The reference files stored in DIR/references/, by name (``study`` before ``study_2``
    before ``study_10``: the order they were given in)."""

    def order(path: Path) -> tuple:
        stem, _, count = path.stem.rpartition("_")
        return (stem, int(count)) if stem and count.isdigit() else (path.stem, 1)

    return sorted((Path(out) / REFERENCES_DIR).glob("*.csv"), key=order)


def report_scorecard(out: str | Path, conventions: Sequence[str]) -> pd.DataFrame | None:
    """Every stored reference table scored against each convention's table and region map of
    the report, and the study's Table 2 (shipped: ``studies.references``) against the paper
    convention's when it was not given; written to DIR/scorecard.csv. None when no reference
    is a table (a report without the paper convention and without reference files)."""
    out = Path(out)
    refs = [r for r in read_references(reference_files(out)) if r.kind == "table"]
    study = (
        None
        if "paper" not in conventions or any(r.label == STUDY for r in refs)
        else read_references([STUDY])[0]
    )
    parts = []
    for convention in conventions:
        scored = refs + ([study] if study is not None and convention == "paper" else [])
        if not scored:
            continue
        found = folder_results(out / convention / "table")
        region = folder_results(out / convention / "region")["region"]
        card = scorecard(found["table"], scored, runs=found["runs"], region=region)
        parts.append(card.assign(convention=convention))
    if not parts:
        return None
    card = pd.concat(parts, ignore_index=True)
    write_atomic(out / SCORECARD, lambda tmp: card.to_csv(tmp, index=False))
    return card


def _fmt(value: float, unit: str = "") -> str:
    if value is None or not np.isfinite(value):
        return "–"
    return f"{value:.3g}" + (f" {unit}" if unit else "")


def _text(value: object) -> str:
    return value if isinstance(value, str) else ""


def _citations(card: pd.DataFrame) -> dict[str, list[str]]:
    """Each source's citations (its file's ``source`` column), in order, each once."""
    cited: dict[str, list[str]] = {}
    for source, citation in card[["source", "citation"]].drop_duplicates().itertuples(index=False):
        if _text(citation):
            cited.setdefault(source, []).append(citation)
    return cited


def scorecard_section(out: str | Path, conventions: Sequence[str], figures: Path) -> dict | None:
    """The scorecard section (None without a reference table): how many rows agree per source
    and convention, every differing row with its reason, the figure and the whole table."""
    card = report_scorecard(out, conventions)
    if card is None:
        return None
    blocks: list[dict] = [_agreement_block(card, conventions)]
    blocks += _differing_rows_block(card)
    blocks += _scorecard_figures(out, card, conventions, figures)
    blocks.append(_scorecard_table(card))
    blocks.append(
        {
            "kind": "paragraph",
            "cls": "",
            "text": (
                "Tolerance: half the reference's stated (or printed) resolution plus our "
                "uncertainty (the bisection step of 0.01 s for a max acting time; an energy's "
                "change over one step at the max acting time), never fitted to agreement "
                "(scorecard.csv's tolerance_basis says which, row by row). Every row is in "
                "scorecard.csv."
            ),
        }
    )
    return {"id": "scorecard", "heading": SCORECARD_HEADING, "blocks": blocks}


def _agreement_block(card: pd.DataFrame, conventions: Sequence[str]) -> dict:
    """The paragraph of how many rows agree per convention and source, and the sources."""
    lines = []
    for convention in conventions:
        mine = card[card["convention"] == convention]
        for row in summary(mine).itertuples():
            lines.append(
                f"{convention} convention, {row.source}: {row.agree} of {row.compared} "
                f"compared rows agree within tolerance, {row.differ} differ "
                f"({row.differ_with_reason} with a reason), {row.not_compared} not "
                "compared (our push fell, or the value is not in our results)."
            )
    cited = [f"{source}: {', '.join(texts)}" for source, texts in _citations(card).items()]
    if cited:
        lines.append("Sources: " + "; ".join(cited) + ".")
    return {"kind": "paragraph", "cls": "reading", "text": "\n".join(lines)}


def _differing_rows_block(card: pd.DataFrame) -> list[dict]:
    """The paragraph listing every row that differs, with its reason (none: no such row)."""
    differs = card[card["status"] == "differs"]
    if not len(differs):
        return []
    items = [
        f"{r.convention}, {r.source}: {r.measure} at {r.force:g} N"
        + (f" x {r.duration:g} s" if np.isfinite(r.duration) else "")
        + f": reference {_fmt(r.reference, r.unit)}, ours {_fmt(r.ours, r.unit)} — "
        + (
            str(r.reason)
            if isinstance(r.reason, str) and r.reason
            else f"no reason in the reference file; see {DIFFERENCES_DOC}"
        )
        for r in differs.itertuples()
    ]
    return [
        {
            "kind": "paragraph",
            "cls": "",
            "text": "Rows that differ:\n" + "\n".join(f"• {item}" for item in items),
        }
    ]


def _scorecard_figures(
    out: str | Path, card: pd.DataFrame, conventions: Sequence[str], figures: Path
) -> list[dict]:
    """Draw each convention's scorecard figure into ``figures``; returns their image blocks."""
    blocks = []
    for convention in conventions:
        mine = card[card["convention"] == convention]
        found = folder_results(Path(out) / convention / "table")
        path = plot_scorecard(mine, figures / f"scorecard_{convention}.png", table=found["table"])
        if path is not None:
            blocks.append(
                img(
                    path,
                    f"{convention} convention: ours (black, with our "
                    "uncertainty) and each reference (open: within "
                    "tolerance, filled: differs, cross: not compared)",
                )
            )
    return blocks


def _scorecard_table(card: pd.DataFrame) -> dict:
    """The whole scorecard as a table block, its citations as numbered notes."""
    header = [
        "convention",
        "source",
        "force [N]",
        "duration [s]",
        "measure",
        "reference",
        "ours",
        "our ±",
        "difference",
        "tolerance",
        "status",
        "reason",
        "citation",
    ]
    notes = list(dict.fromkeys(c for c in map(_text, card["citation"]) if c))  # [1], [2], ...
    rows = [
        [
            r.convention,
            r.source,
            f"{r.force:g}",
            _fmt(r.duration),
            r.measure,
            _fmt(r.reference, r.unit),
            _fmt(r.ours, r.unit),
            _fmt(r.our_uncertainty),
            _fmt(r.abs_diff),
            _fmt(r.tolerance),
            r.status,
            _text(r.reason),
            f"[{notes.index(r.citation) + 1}]" if _text(r.citation) else "",
        ]
        for r in card.itertuples()
    ]
    return {"kind": "table", "header": header, "rows": rows, "notes": notes}


# -- the strategy map ------------------------------------------------------------------------------


def _share(table: pd.DataFrame, when: str) -> np.ndarray:
    hip = table.get(f"energy_hip_{when}")
    total = table.get(f"energy_total_{when}")
    if hip is None or total is None:
        return np.full(len(table), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (hip / total).to_numpy(float)


def strategy_table(table: pd.DataFrame) -> pd.DataFrame:
    """Per table force: the hip's share of the motors' work and the strategy at T = 0.1 s and
    at the max acting time (the longest recovered push), where that push recovered."""
    t = table.sort_values("force")
    frame = pd.DataFrame(
        {
            "force": t["force"].to_numpy(float),
            "max_acting_time": t["max_acting_time"].to_numpy(float),
            "share_01": _share(t, "01"),
            "share_max": _share(t, "max"),
        }
    )
    for when in ("01", "max"):
        share = frame[f"share_{when}"].to_numpy()
        frame[f"strategy_{when}"] = np.where(
            np.isfinite(share),
            np.where(share > HIP_SHARE_THRESHOLD, STRATEGIES[1], STRATEGIES[0]),
            "",
        )
    return frame


def _span(values: pd.Series) -> str:
    low, high = float(values.min()), float(values.max())
    return f"{low:.2f}" if f"{low:.2f}" == f"{high:.2f}" else f"{low:.2f}-{high:.2f}"


def strategy_reading(table: pd.DataFrame) -> str:
    """The study's statement (the hip joins in for the larger forces at the longest recovered
    duration) checked against the table's runs, in numbers."""
    frame = strategy_table(table)
    at_max = frame.dropna(subset=["share_max"])
    at_01 = frame.dropna(subset=["share_01"])
    if not len(at_max):
        return "No table force has a recovered push to read the strategy from."
    hip_max = at_max[at_max["strategy_max"] == STRATEGIES[1]]["force"]
    hip_01 = at_01[at_01["strategy_01"] == STRATEGIES[1]]["force"]
    text = (
        f"At each force's max acting time (its longest recovered push) the hip's share of "
        f"the motors' work is {_span(at_max['share_max'])}: hip_ankle (share > "
        f"{HIP_SHARE_THRESHOLD:g}) at {len(hip_max)} of {len(at_max)} forces"
        + (f" ({', '.join(f'{f:g}' for f in hip_max)} N)." if len(hip_max) else ".")
    )
    if len(at_01):
        text += (
            f" For the fixed 0.1-s push it is {_span(at_01['share_01'])} over the forces "
            "that recover "
            f"({', '.join(f'{f:g}' for f in at_01['force'])} N); hip_ankle at "
            f"{', '.join(f'{f:g}' for f in hip_01) or 'none of them'}"
            + (" N." if len(hip_01) else ".")
        )
    rising = at_max["share_max"].is_monotonic_increasing
    text += (
        " The study says the hip joins in for the larger forces at the longest recovered "
        "duration; here the share at the max acting time "
        + (
            "rises with the force."
            if rising
            else "does not rise steadily with the force: the longest recovered push of a small "
            "force is a long push, in which the hip also does much of the work."
        )
    )
    return text


def strategy_blocks(
    region: pd.DataFrame, table: pd.DataFrame | None, figures: Path, config: Config, convention: str
) -> list[dict]:
    """The strategy map's blocks of a region section: the map, how it moves with its
    threshold, and the reading of the study's statement from the table."""
    strategy = plot_strategy(region, figures / f"strategy_{convention}.png", config=config)
    threshold = plot_threshold(
        region, figures / f"strategy_threshold_{convention}.png", config=config
    )
    blocks = [
        {
            "kind": "paragraph",
            "cls": "",
            "text": (
                "Recovery strategy: the hip's share of the two motors' absolute work in each "
                "recovered cell (docs/model.md: in this model the hip bends about as much as the "
                "ankle after any push, so the joints' excursions cannot tell the strategies apart; "
                "the work says which motor does the recovering). Threshold "
                f"{HIP_SHARE_THRESHOLD:g}: about twice the share of the linear regime, the mode of "
                "the distribution (region.parquet's strategy column)."
            ),
        },
        img(strategy, "the hip's share of the work; dashed: where the hip takes over"),
        img(threshold, "how the map moves with the threshold"),
    ]
    if table is not None and len(table):
        blocks.append({"kind": "paragraph", "cls": "reading", "text": strategy_reading(table)})
    return blocks
