"""A cohort's subjects, as a request gives them: a grid of heights, masses, sexes and
strengths (:func:`subject_grid`), a sampled population (:func:`population`), a CSV file of
participants (:func:`read_subjects`) or Subjects (:func:`as_members`); each numbered or named
by a checked id (:func:`check_ids`). ``cohort.py`` runs them.

Populations (:func:`population`): ``N`` subjects drawn from a NumPy ``Generator`` seeded
with ``seed``; subject by subject: sex (female with probability ``female_fraction``), then
height ~ Normal(height_mean, height_sd) and mass ~ Normal(mass_mean, mass_sd), independent,
each redrawn until it lies in the range a Subject accepts (``subject.HEIGHT_RANGE``, then
``SUBJECT_MASS_RANGE`` narrowed to the body mass indices of ``BMI_RANGE`` at that height): a
truncated normal; with ``age_mean``, then age ~ Normal(age_mean, age_sd) in ``ageing.AGE_RANGE``
(to 0.1 yr). The same seed gives the same subjects.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..model.params import ParameterError
from ..model.ageing import AGE_RANGE
from ..model.subject import BMI_RANGE, HEIGHT_RANGE, SUBJECT_MASS_RANGE, Subject, subject_rows

ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")
ID_LENGTH = 64  # characters: a folder name far below every file system's limit (255 bytes)


@dataclass(frozen=True)
class Member:
    """One subject of a cohort under its id (its folder's name in ``OUT/subjects``)."""

    id: str
    subject: Subject

    def record(self) -> dict[str, Any]:
        return {"id": self.id, **self.subject.to_dict()}


def numbered(subjects: Sequence[Subject]) -> list[Member]:
    """Subjects under the ids s01, s02, ... (zero-padded to the cohort's size)."""
    width = max(2, len(str(len(subjects))))
    return [Member(f"s{i:0{width}d}", s) for i, s in enumerate(subjects, start=1)]


def id_problem(ident: Any) -> str | None:
    """Why ``ident`` cannot be a subject's id (None if it can): ids are folder names, of
    letters, digits, '.', '_', '-', starting with a letter or digit, at most ID_LENGTH long."""
    if not isinstance(ident, str) or not ID_PATTERN.fullmatch(ident):
        return (
            "is not a folder name (letters, digits, '.', '_', '-', starting with a letter or digit)"
        )
    if len(ident) > ID_LENGTH:
        return f"is {len(ident)} characters long; an id has at most {ID_LENGTH}"
    return None


def check_ids(members: Sequence[Member]) -> None:
    """Ids are folder names (:func:`id_problem`) and each is given once (also ignoring case: a
    case-insensitive disk would merge them)."""
    if not members:
        raise ParameterError("a cohort needs at least one subject")
    seen: dict[str, str] = {}
    for member in members:
        problem = id_problem(member.id)
        if problem:
            raise ParameterError(f"subject id {_shown(member.id)} {problem}")
        if member.id.lower() in seen:
            raise ParameterError(f"subject id {member.id!r} is given twice")
        seen[member.id.lower()] = member.id


def _shown(ident: Any) -> str:
    """An id as an error message shows it: repr, a long one cut in the middle."""
    text = repr(ident)
    return text if len(text) <= 40 else f"{text[:20]}...{text[-12:]}"


def subject_grid(
    heights: Sequence[float] | np.ndarray,
    masses: Sequence[float] | np.ndarray,
    sexes: Sequence[str] = ("male",),
    ankle_strengths: Sequence[float] | np.ndarray = (1.0,),
    hip_strengths: Sequence[float] | np.ndarray = (1.0,),
    ages: Sequence[float | None] | np.ndarray = (None,),
) -> list[Member]:
    """Every combination of the lists (heights vary slowest, ages fastest), numbered s01, s02,
    ...; a value a Subject refuses raises ParameterError naming it."""
    subjects = [
        Subject(float(h), float(m), str(s), float(a), float(p), None if y is None else float(y))
        for h, m, s, a, p, y in itertools.product(
            heights, masses, sexes, ankle_strengths, hip_strengths, ages
        )
    ]
    return numbered(subjects)


def _truncated(
    rng: np.random.Generator, mean: float, sd: float, low: float, high: float, name: str
) -> float:
    """One draw of Normal(mean, sd) redrawn until it lies in [low, high]."""
    for _ in range(10_000):
        value = float(rng.normal(mean, sd))
        if low <= value <= high:
            return value
    raise ParameterError(
        f"{name}: Normal({mean:g}, {sd:g}) almost never falls in the range "
        f"a subject accepts, [{low:g}, {high:g}]; check the mean and SD"
    )


def _rounded_within(mass: float, low: float, high: float) -> float:
    """``mass`` to 0.01 kg, kept inside [low, high] (rounding must not leave the range)."""
    rounded = round(mass, 2)
    return rounded if low <= rounded <= high else mass


def population(
    n: int,
    seed: int,
    *,
    height_mean: float = 1.70,
    height_sd: float = 0.09,
    mass_mean: float = 70.0,
    mass_sd: float = 12.0,
    female_fraction: float = 0.5,
    age_mean: float | None = None,
    age_sd: float | None = None,
) -> list[Member]:
    """``n`` subjects drawn with ``np.random.default_rng(seed)`` (module docstring: sex, then
    truncated-normal height and mass, independent, then with ``age_mean`` a truncated-normal
    age), numbered s01, s02, ..."""
    checks = {
        "n": (n, n >= 1 and float(n).is_integer()),
        "seed": (seed, seed >= 0 and float(seed).is_integer()),
        "height_sd": (height_sd, height_sd >= 0),
        "mass_sd": (mass_sd, mass_sd >= 0),
        "female_fraction": (female_fraction, 0 <= female_fraction <= 1),
        "age_mean": (age_mean, age_mean is None or AGE_RANGE[0] <= age_mean <= AGE_RANGE[1]),
        "age_sd": (age_sd, age_sd is None or age_sd >= 0),
    }
    for name, (value, ok) in checks.items():
        if not ((value is None or math.isfinite(float(value))) and ok):
            raise ParameterError(
                f"population {name} = {value!r}: out of range (n >= 1 and "
                "seed >= 0 whole, SDs >= 0, female_fraction in [0, 1], age_mean in "
                f"[{AGE_RANGE[0]:g}, {AGE_RANGE[1]:g}] yr)"
            )
    rng = np.random.default_rng(int(seed))
    subjects = []
    for _ in range(int(n)):
        sex = "female" if rng.random() < female_fraction else "male"
        height = round(_truncated(rng, height_mean, height_sd, *HEIGHT_RANGE, "height"), 4)
        low = max(SUBJECT_MASS_RANGE[0], BMI_RANGE[0] * height**2)  # a body that can be
        high = min(SUBJECT_MASS_RANGE[1], BMI_RANGE[1] * height**2)  # (subject.BMI_RANGE)
        mass = _truncated(rng, mass_mean, mass_sd, low, high, "mass")
        age = None  # drawn last: a population without ages draws what it drew before
        if age_mean is not None:
            age = round(_truncated(rng, age_mean, age_sd or 0.0, *AGE_RANGE, "age"), 1)
        subjects.append(Subject(height, _rounded_within(mass, low, high), sex, age=age))
    return numbered(subjects)


def read_subjects(path: str | Path) -> list[Member]:
    """The subjects of a CSV file (``subject.subject_rows``: columns id (optional), height,
    mass, sex, ankle_strength, hip_strength, notes; a bad column or row refused naming its
    line and value); rows without an id are numbered s01, ... by their position. Ids are
    checked here, as the file is read (:func:`id_problem`, each once)."""
    path = Path(path)
    rows = subject_rows(path)
    defaults = numbered([row.subject for row in rows])
    members = []
    for row, default in zip(rows, defaults):
        problem = id_problem(row.id) if row.id else None
        if problem:
            raise ParameterError(f"{path}, line {row.line}: id = {_shown(row.id)} {problem}")
        members.append(Member(row.id or default.id, row.subject))
    try:
        check_ids(members)
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None
    return members


def as_members(subjects: Any) -> list[Member]:
    """Members from a CSV path, a dict id -> Subject, one Subject (id s01) or Member, or a
    sequence of Subjects (ids s01, s02, ...) or of Members; anything else is refused naming
    ``subjects`` and the item that is wrong."""
    if isinstance(subjects, (str, Path)):
        return read_subjects(subjects)
    if isinstance(subjects, (Subject, Member)):
        subjects = [subjects]
    if isinstance(subjects, dict):
        for key, value in subjects.items():
            if not isinstance(value, Subject):
                raise ParameterError(
                    f"subjects[{_shown(key)}] = {value!r}: expected a Subject (mb.Subject)"
                )
        members = [Member(str(k), v) for k, v in subjects.items()]
    else:
        try:
            items = list(subjects)
        except TypeError:
            raise ParameterError(
                f"subjects: expected a Subject (mb.Subject), a sequence of them, a dict id -> "
                f"Subject or a CSV file's path; got {type(subjects).__name__} "
                f"({subjects!r})"
            ) from None
        kinds = {type(s) for s in items}
        if kinds <= {Subject}:
            members = numbered(items)
        elif kinds <= {Member} and all(isinstance(m.subject, Subject) for m in items):
            members = items
        else:
            bad = next(
                (
                    s
                    for s in items
                    if not (
                        isinstance(s, Subject)
                        or isinstance(s, Member)
                        and isinstance(s.subject, Subject)
                    )
                ),
                None,
            )
            raise ParameterError(
                f"subjects: expected Subjects (mb.Subject), got {bad!r} ({type(bad).__name__})"
                if bad is not None
                else "subjects: give Subjects (numbered s01, s02, ...) or "
                "Members (each with its id), not both"
            )
    check_ids(members)
    return members
