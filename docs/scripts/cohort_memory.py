"""A cohort's memory against its subjects: one cohort of N subjects on a 32-cell grid (0:105:15
N x 0.1, 0.2, 0.3, 0.5 s, 1-s windows), run in this process through ``mb.cohort``'s own
functions, printing after each engine queue the subjects done, the resident set (VmRSS) and
its peak so far (VmHWM). The queues grow from 16 bodies to the cell limit (625 bodies of 32
cells), so memory flat in the subjects shows as the same resident set after every full-size
queue.

    python docs/scripts/cohort_memory.py OUT [SUBJECTS [QUEUES]]

Defaults: 10,000 subjects; QUEUES stops after that many queues (the run is then interrupted
as Ctrl-C would: what finished is kept in OUT).
"""

from __future__ import annotations

import sys
import time

from mjx_balance.model.params import Config
from mjx_balance.studies import cohort
from mjx_balance.studies import members as cohort_members


def status(name: str) -> int:
    """A /proc/self/status field in MB (Linux)."""
    with open("/proc/self/status") as lines:
        for line in lines:
            if line.startswith(name + ":"):
                return int(line.split()[1]) // 1024
    raise KeyError(name)


def main(out: str, count: int = 10_000, stop: int | None = None) -> None:
    base = Config().replace(scenario={"t_end": 1.0})
    plan = cohort.plan_cohort(
        out, cohort_members.population(count, 1), base, "0:105:15", "0.1,0.2,0.3,0.5"
    )
    start, queues, done = time.perf_counter(), 0, 0

    def say(text: str) -> None:
        nonlocal queues, done
        if "in one engine queue" in text:
            print(
                f"queue {queues + 1} starts: {done} subjects done, {time.perf_counter() - start:.0f} s, "
                f"VmRSS {status('VmRSS')} MB, VmHWM {status('VmHWM')} MB",
                flush=True,
            )
            if stop is not None and queues == stop:
                raise KeyboardInterrupt
            queues += 1
            done += int(text.split("cohort: ")[-1].split()[0])

    try:
        cohort.run_plan(plan, say=say)
    except KeyboardInterrupt:
        print(f"stopped before queue {queues + 1}")
    print(f"end: VmRSS {status('VmRSS')} MB, VmHWM {status('VmHWM')} MB")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(args[0], *(int(a) for a in args[1:]))
