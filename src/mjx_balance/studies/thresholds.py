"""People's protocols report a threshold: the largest lean, or the largest held pull, that the
body survives with its feet in place. This module finds such a threshold on the batched engine
and holds it against the published value.

- :func:`largest_passing` scans ``SCAN`` values from 0 to a top in one batched call, then
  rounds of ``SCAN`` values inside the first bracket that fails (k-section), until the bracket
  is ``resolution`` wide: every call has the same shape, so one compiled program serves all.
  The threshold is the largest value seen passing with every smaller scanned value passing too.
- :func:`agreement` is the people reference's rule: a prediction agrees when it lies within the
  published mean +- 2 SD (docs/people.md, "People").
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pandas as pd

from ..model.params import Config, ParameterError
from ..store.folder import OutputFolder, folder_lock

SCAN = 16  # values per batched call (one compiled shape for every round)


@dataclass(frozen=True)
class Bracket:
    """A threshold found by :func:`largest_passing`."""

    low: float  # the largest value seen passing (every smaller scanned value passing too)
    high: float  # the smallest value seen failing (inf: none failed up to the top)
    peak: float  # the run's measure at ``low`` (e.g. its peak ankle torque; nan: none passed)
    runs: int  # scenarios run

    @property
    def width(self) -> float:
        """The bracket's width (0 when nothing failed up to the top: the limit is beyond it)."""
        return 0.0 if math.isinf(self.high) else self.high - self.low


def largest_passing(
    passes: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    top: float,
    resolution: float,
    progress: Callable[[float, float], None] | None = None,
) -> Bracket:
    """The largest value in [0, ``top``] that passes, to ``resolution`` (module docstring).
    ``passes(values)`` takes ``SCAN`` values and returns (passed [bool], measure) for each;
    ``progress(low, high)`` hears each bracket before it is narrowed."""
    low, high, peak, runs = 0.0, math.inf, float("nan"), 0
    values = np.linspace(0.0, top, SCAN)
    while True:
        ok, measure = passes(values)
        runs += values.size
        failing = np.flatnonzero(~np.asarray(ok, bool))
        stop = int(failing[0]) if failing.size else values.size  # the values below all pass
        if stop > 0:
            low, peak = float(values[stop - 1]), float(measure[stop - 1])
        elif values[0] == 0.0:  # the unperturbed body itself fails
            return Bracket(0.0, 0.0, float("nan"), runs)
        if failing.size:
            high = float(values[stop])
        if math.isinf(high):  # every value of the scan passes: the limit is beyond it
            return Bracket(low, high, peak, runs)
        if progress is not None:
            progress(low, high)
        if high - low <= resolution:
            return Bracket(low, high, peak, runs)
        values = np.linspace(low, high, SCAN + 2)[1:-1]


def check_bracket(resolution: Any, low: float, high: float, unit: str) -> None:
    """Refuse a bracket width that is not a number within [``low``, ``high``] ``unit`` (one
    line, before any work)."""
    if isinstance(resolution, bool) or not (
        isinstance(resolution, (int, float)) and low <= resolution <= high
    ):
        raise ParameterError(
            f"resolution must be within [{low:g}, {high:g}] {unit}, got {resolution!r}"
        )


@contextmanager
def protocol_folder(
    out: Path, config: Config, settings: dict[str, Any], *, wait: bool = False
) -> Iterator[None]:
    """OUT under its lock, opened for ``config`` (a folder made with another configuration is
    refused) with the protocol's ``settings`` ({name: values}) recorded in its manifest."""
    with folder_lock(out, wait=wait):
        folder = OutputFolder(out, config)
        manifest = folder.open()
        manifest.update(settings)
        folder.write_manifest(manifest)
        yield


def planned_runs(top: float, resolution: float) -> int:
    """The most scenarios :func:`largest_passing` runs: the scan, then rounds of SCAN values,
    each shrinking the bracket by SCAN + 1, until it is ``resolution`` wide."""
    bracket, rounds = top / (SCAN - 1), 0
    while bracket > resolution:
        bracket, rounds = bracket / (SCAN + 1), rounds + 1
    return SCAN * (1 + rounds)


def agreement(measure: str, ours: float, people: pd.DataFrame) -> dict:
    """The people reference's row ``measure`` beside our prediction ``ours``: ``agrees`` when
    it lies within the published mean +- 2 SD (a row without an SD: never)."""
    ref = people.set_index("measure").loc[measure]
    low, high = ref["mean"] - 2 * ref["sd"], ref["mean"] + 2 * ref["sd"]
    return {
        "measure": measure,
        "unit": ref["unit"],
        "published_mean": ref["mean"],
        "published_sd": ref["sd"],
        "ours": ours,
        "agrees": bool(low <= ours <= high),
        "source": ref["source"],
    }
