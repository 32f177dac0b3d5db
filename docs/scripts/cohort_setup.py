"""A cohort's set-up per subject: the seconds ``studies.cohort.plan_cohort`` spends checking a
subject's configuration before the folder is made (the QP, its conditioning, the batched
closed loop's build), and the seconds the one engine queue spends on each map outside the
engine (``runs.population``: its closed loop built and checked when its queue starts, its
folder written from the queue's results). The plan line counts them
(``runs.chunks.SUBJECT_CHECK_SECONDS``, ``SUBJECT_SETUP_SECONDS``).

    python docs/scripts/cohort_setup.py [SUBJECTS]
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

import mjx_balance as mb
from mjx_balance.model.params import Config
from mjx_balance.runs import population
from mjx_balance.studies.cohort import plan_cohort, run_plan
from mjx_balance.studies.members import numbered

spent: dict[str, float] = defaultdict(float)


def timed(name: str, fn):
    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            spent[name] += time.perf_counter() - start

    return wrapper


def main(count: int = 40) -> None:
    base = Config().replace(scenario={"t_end": 2.0})
    rng = np.random.default_rng(0)
    heights, masses = rng.uniform(1.5, 1.95, count + 1), rng.uniform(50, 100, count + 1)
    people = [mb.Subject(float(h), float(m)) for h, m in zip(heights, masses)]
    with tempfile.TemporaryDirectory() as out:
        plan_cohort(out, numbered(people[:1]), base, [0, 50], [0.1])  # JAX started, cached
        started = time.perf_counter()
        plan = plan_cohort(Path(out) / "c", numbered(people[1:]), base, [0, 50], [0.1])
        check = (time.perf_counter() - started) / count
        population.checked_runner = timed("built", population.checked_runner)
        population.run_region = timed("written", population.run_region)
        run_plan(plan, say=None)
    maps = count + 1  # and the base body's
    print(f"{check:.3f} s a subject checked before the folder ({count} subjects)")
    built, written = spent["built"] / maps, spent["written"] / maps
    print(f"{built:.3f} s a map's closed loop built, {written:.3f} s its folder written: ", end="")
    print(f"{built + written:.3f} s a map in the queue ({maps} maps)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
