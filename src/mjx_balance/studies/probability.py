"""A cohort's probability map: per cell (F, T), P(recover | F, T) over the cohort's subjects,
its 95 % interval, the map's boundaries and how many subjects an interval's width needs.

P at a cell is the share of the subjects whose region map recovers that cell: ``k / n`` with
``k`` the subjects that recover and ``n`` those whose map holds the cell (every subject's, in a
finished cohort). The subjects are read as a sample of the population they were drawn from,
so P estimates the probability that a person of that population recovers from the push.

The interval is Wilson's score interval (Wilson 1927; Newcombe 1998, method 3): the
probabilities p whose score test ``|k/n - p| <= z sqrt(p (1 - p) / n)`` accepts, z the normal
quantile of 0.975. Chosen over Clopper-Pearson's exact interval: averaged over the true P,
Wilson's coverage is 95.0-95.4 % for 10 to 400 subjects where Clopper-Pearson's is 95.8-98.4 %
with intervals 3-17 % wider (it keeps 95 % at every P by being wider than it needs on average;
Brown, Cai and DasGupta 2001; docs/cohorts.md, "Cohorts", has the computation). Wilson's
interval stays inside [0, 1], has a width at k = 0 and k = n (0/10 gives [0, 0.278]) where the
normal approximation's collapses to a point, and its width has a closed form, so the subjects a
width needs are a formula (:func:`subjects_for`). Its price: near P = 0 and 1 its coverage can
dip below 95 % (to about 84 % at some P for 10 to 50 subjects).

Width. The half-width is largest at k/n = 1/2: ``z / (2 sqrt(n + z^2))`` (:func:`half_width`),
so n subjects give every cell's P to within that; ±10 % needs 93 subjects, ±5 % needs 381
(the normal approximation's 1.96^2 / (4 w^2): 97 and 385).

Boundaries (:func:`boundaries`). The boundary at a level q is a subject's recovery boundary on
the grid (``figures.region.recovery_boundary``: per force, the longest grid duration up to which
every grid duration recovers, 0 when the shortest does not) with "recovers" read as
"P(recover) >= q": per force, the longest grid duration T such that P >= q at every grid
duration up to T. For a cohort of one subject every level's boundary is that subject's.
"""

from __future__ import annotations

import math
from statistics import NormalDist
from typing import Any

import numpy as np
import pandas as pd

from ..figures.region import recovery_boundary
from ..measures.capture import saved
from ..measures.outcomes import OUTCOMES, RECOVERED
from ..model.params import ParameterError

CONFIDENCE = 0.95
Z = NormalDist().inv_cdf(0.5 + CONFIDENCE / 2)  # 1.959964
LEVELS = (95, 50, 5)  # percent: the boundaries' levels, innermost first
WIDTHS = (0.10, 0.05)  # the half-widths whose subject counts the planned-work line names
CELL_COLUMNS = [
    "force",
    "duration",
    "subjects",
    "recovered_subjects",
    "p_recover",
    "p_low",
    "p_high",
]
# With the subjects' capture column (steps_needed, measures/capture.py): P(recover in place or
# with at most one step) and its interval beside P(recover in place)
STEP_CELL_COLUMNS = ["one_step_subjects", "p_one_step", "p_one_step_low", "p_one_step_high"]
RECOVERED_TEXT = OUTCOMES[RECOVERED]
BELOW = "below"  # a thresholded map's outcome where P < q


def wilson(
    recovered: np.ndarray | int, n: np.ndarray | int, z: float = Z
) -> tuple[np.ndarray, np.ndarray]:
    """Wilson's score interval (module docstring) of ``recovered`` successes out of ``n`` > 0:
    (low, high), elementwise. ValueError for n < 1 or a count outside [0, n]."""
    k = np.asarray(recovered, dtype=float)
    n = np.asarray(n, dtype=float)
    if np.any(n < 1) or np.any(k < 0) or np.any(k > n):
        raise ValueError(
            f"wilson: needs 0 <= recovered <= n and n >= 1; got recovered = "
            f"{recovered!r}, n = {n!r}"
        )
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    # at k = 0 and k = n the bound is 0 or 1 in exact arithmetic; rounding leaves ~1e-17
    return np.where(k == 0, 0.0, centre - half), np.where(k == n, 1.0, centre + half)


def half_width(n: int, z: float = Z) -> float:
    """The Wilson interval's largest half-width over n subjects (at k/n = 1/2)."""
    if not (isinstance(n, (int, np.integer)) and n >= 1):
        raise ValueError(f"half_width: n = {n!r}: must be a whole number >= 1")
    return z / (2 * math.sqrt(n + z * z))


def subjects_for(width: float, z: float = Z) -> int:
    """The fewest subjects whose worst-case Wilson half-width is at most ``width`` (0 < width
    < 1/2): the smallest n with z / (2 sqrt(n + z^2)) <= width."""
    if not (isinstance(width, (int, float)) and 0 < width < 0.5):
        raise ValueError(f"subjects_for: width = {width!r}: must be a number in (0, 0.5)")
    n = max(1, math.ceil(z * z / (4 * width * width) - z * z))
    # the formula in floats can land one off the smallest such n: step to it
    while half_width(n, z) > width:
        n += 1
    while n > 1 and half_width(n - 1, z) <= width:
        n -= 1
    return n


def interval_text(n: int) -> str:
    """One line on what n subjects give: P(recover) per cell, its worst-case half-width, and the
    subjects ±10 % and ±5 % need."""
    needs = ", ".join(f"±{100 * w:g} % needs {subjects_for(w)}" for w in WIDTHS)
    return (
        f"P(recover) per cell over {n} subject{'' if n == 1 else 's'}: 95 % Wilson "
        f"interval within ±{100 * half_width(n):.1f} % at worst ({needs})"
    )


def cells(regions: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """cohort_probability.csv: per cell (force, duration), the subjects whose map holds it, those
    that recover, P = recovered / subjects and its Wilson interval; forces then durations
    ascending. ``regions``: each subject's region map (force, duration, outcome). Where every
    map has ``steps_needed`` (capturability), also the subjects that recover in place or with
    one step, P of that and its Wilson interval (STEP_CELL_COLUMNS). :class:`Tally` counts the
    maps one at a time (a large cohort's are never all in memory)."""
    tally = Tally()
    for region in regions.values():
        tally.add(region)
    return tally.cells()


class Tally:
    """:func:`cells`' counts, added one subject's region map at a time (:meth:`add`); the host
    keeps a count per cell, not the maps."""

    def __init__(self) -> None:
        self.counts: pd.DataFrame | None = None
        self.steps = True  # every map so far has steps_needed

    def add(self, region: pd.DataFrame) -> None:
        """One subject's region map (force, duration, outcome; steps_needed where it has it)."""
        self.steps = self.steps and "steps_needed" in region
        recovered = region["outcome"] == RECOVERED_TEXT
        part = pd.DataFrame(
            {
                "force": region["force"],
                "duration": region["duration"],
                "subjects": 1,
                "recovered_subjects": recovered.astype(np.int64),
            }
        )
        if self.steps:
            one_step = saved(recovered, region["steps_needed"], 1)
            part["one_step_subjects"] = np.asarray(one_step).astype(np.int64)
        counts = part.groupby(["force", "duration"], sort=True).sum()
        if self.counts is None:
            self.counts = counts
        else:  # counts stay whole: float64 holds them exactly
            self.counts = self.counts.add(counts, fill_value=0)
        if not self.steps and "one_step_subjects" in self.counts:
            self.counts = self.counts.drop(columns="one_step_subjects")

    def cells(self) -> pd.DataFrame:
        """cohort_probability.csv's frame of the maps added (:func:`cells`)."""
        if self.counts is None:
            raise ParameterError("a probability map needs at least one subject's region map")
        frame = self.counts.sort_index().reset_index()
        n = frame["subjects"].to_numpy().astype(int)
        k = frame["recovered_subjects"].to_numpy().astype(int)
        frame["subjects"], frame["recovered_subjects"] = n, k
        frame["p_recover"] = k / n
        frame["p_low"], frame["p_high"] = wilson(k, n)
        if not self.steps:
            return frame[CELL_COLUMNS]
        k1 = frame["one_step_subjects"].to_numpy().astype(int)
        frame["one_step_subjects"], frame["p_one_step"] = k1, k1 / n
        frame["p_one_step_low"], frame["p_one_step_high"] = wilson(k1, n)
        return frame[CELL_COLUMNS + STEP_CELL_COLUMNS]


def at_level(recovered: Any, subjects: Any, percent: int) -> np.ndarray:
    """Where P = recovered / subjects >= percent / 100, compared in whole counts (100 k >=
    percent n: 19 of 20 is at 95 %, exactly); elementwise."""
    return 100 * np.asarray(recovered) >= percent * np.asarray(subjects)


def thresholded(frame: pd.DataFrame, percent: int) -> pd.DataFrame:
    """The probability map read as one outcome map: "recovered" where P >= percent / 100, else
    "below" (:func:`at_level`)."""
    ok = at_level(frame["recovered_subjects"], frame["subjects"], percent)
    return pd.DataFrame(
        {
            "force": frame["force"].to_numpy(),
            "duration": frame["duration"],
            "outcome": np.where(ok, RECOVERED_TEXT, BELOW),
        }
    )


def boundaries(frame: pd.DataFrame, base: pd.DataFrame | None = None) -> pd.DataFrame:
    """cohort_probability_boundaries.csv: per force, ``boundary_p95``, ``boundary_p50`` and
    ``boundary_p5`` [s] (module docstring) and, with ``base`` (the base configuration's region
    map), ``boundary_base``: that body's own recovery boundary on the grid."""
    out = pd.DataFrame({"force": np.sort(frame["force"].unique())})
    for percent in LEVELS:
        found = recovery_boundary(thresholded(frame, percent)).set_index("force")["boundary"]
        out[f"boundary_p{percent}"] = out["force"].map(found).to_numpy(float)
    if base is not None:
        found = recovery_boundary(base).set_index("force")["boundary"]
        out["boundary_base"] = out["force"].map(found).to_numpy(float)
    return out
