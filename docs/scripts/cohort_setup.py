"""A cohort's set-up: the seconds ``studies.cohort.plan_cohort`` spends on each subject before
the first scenario (its configuration checked: the QP, its conditioning, the batched closed
loop's build). The plan line counts it (``runs.chunks.SUBJECT_CHECK_SECONDS``).

    python docs/scripts/cohort_setup.py [SUBJECTS]
"""

from __future__ import annotations

import sys
import tempfile
import time

import numpy as np

import mjx_balance as mb
from mjx_balance.model.params import Config
from mjx_balance.studies.cohort import plan_cohort
from mjx_balance.studies.members import numbered


def main(count: int = 40) -> None:
    base = Config().replace(scenario={"t_end": 2.0})
    rng = np.random.default_rng(0)
    heights, masses = rng.uniform(1.5, 1.95, count + 1), rng.uniform(50, 100, count + 1)
    people = [mb.Subject(float(h), float(m)) for h, m in zip(heights, masses)]
    with tempfile.TemporaryDirectory() as out:
        plan_cohort(out, numbered(people[:1]), base, [0, 50], [0.1])  # JAX started, cached
        started = time.perf_counter()
        plan_cohort(out, numbered(people[1:]), base, [0, 50], [0.1])
        seconds = (time.perf_counter() - started) / count
    print(f"{seconds:.3f} s a subject ({count} subjects checked)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
