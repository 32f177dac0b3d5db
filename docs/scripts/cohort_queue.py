"""A cohort's time with each subject its own engine run (``--queue each``) and with every
subject in one engine queue (``--queue one``), beside a plain sweep of as many cells, in one
process (one sitting, the same machine load for all three).

    python docs/scripts/cohort_queue.py OUT [--forces 0:105:15] [--durations 0.1,0.2,0.3,0.5] \
        [--subjects 3] [--t-end 12] [--repeats 3]

Each program is compiled first (a warm-up cohort of the same subjects on a two-cell grid in
each mode: the one queue's program depends on their count), so the times are runs, not
compiles; the three runs are alternated ``--repeats`` times and the medians reported (one
run's times vary by a third on this shared machine). Prints seconds, seconds per scenario and
per scenario-period (the control periods the
engine simulated, summed over the run's cells: bodies whose cells run longer cost more per
scenario for the same engine speed).
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import numpy as np

import mjx_balance as mb
from mjx_balance.rollout import engine as engine_mod
from mjx_balance.runs.folders import run_region
from mjx_balance.runs.grid import parse_grid
from mjx_balance.studies import cohort
from mjx_balance.studies import members as cohort_members

PEOPLE = [mb.Subject(1.55, 50, "female"), mb.Subject(1.70, 70), mb.Subject(1.85, 90),
          mb.Subject(1.62, 58, "female"), mb.Subject(1.78, 82), mb.Subject(1.92, 100)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out")
    p.add_argument("--forces", default="0:105:15")
    p.add_argument("--durations", default="0.1,0.2,0.3,0.5")
    p.add_argument("--subjects", type=int, default=3)
    p.add_argument("--t-end", type=float, default=12.0)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    out = Path(args.out)
    shutil.rmtree(out, ignore_errors=True)
    config = mb.Config().replace(scenario={"t_end": args.t_end})
    people = cohort_members.numbered(PEOPLE[:args.subjects])
    forces = parse_grid(args.forces, "forces")
    durations = parse_grid(args.durations, "durations")
    cells = forces.size * durations.size
    for queue in ("each", "one"):  # compile both programs (and the plain sweep's)
        cohort.run_cohort(out / f"warm-{queue}", people, config, forces[:2], durations[:1],
                          say=None, queue=queue)
    runs: dict[str, list[float]] = {}
    outputs: dict[str, float] = {}
    write_outputs = cohort.write_outputs

    def timed_outputs(*a, **k):  # the cohort's tables and figures, timed apart
        t = time.perf_counter()
        try:
            return write_outputs(*a, **k)
        finally:
            outputs[queue] = time.perf_counter() - t

    cohort.write_outputs = timed_outputs
    work: dict[str, int] = {}
    stream = engine_mod.Engine.stream

    def counted(self, *a, **k):  # the control periods of every cell the engines decide
        for index, raw in stream(self, *a, **k):
            work[label] = work.get(label, 0) + int(raw["periods"].sum())
            yield index, raw

    engine_mod.Engine.stream = counted
    # the plain sweep: as many cells as a cohort runs (its subjects' and the base body's),
    # the study's body, forces spread over the cohort's range
    n = (len(people) + 1) * cells
    plain = np.linspace(forces[0], forces[-1], n // durations.size)
    for r in range(args.repeats):
        for queue in ("each", "one"):
            label = f"cohort --queue {queue}"
            work[label] = 0
            t0 = time.perf_counter()
            cohort.run_cohort(out / f"{queue}{r}", people, config, forces, durations, say=None,
                              queue=queue)
            runs.setdefault(label, []).append(time.perf_counter() - t0 - outputs[queue])
        label = "plain sweep"
        work[label] = 0
        t0 = time.perf_counter()
        run_region(out / f"plain{r}", config, plain, durations)
        runs.setdefault(label, []).append(time.perf_counter() - t0)
    times = {name: float(np.median(ts)) for name, ts in runs.items()}
    print(f"{len(people)} subjects x {cells} cells and the base body's map: {n} scenarios a "
          f"run; t_end {args.t_end:g} s")
    plain_rate = times["plain sweep"] / work["plain sweep"]
    for name, seconds in times.items():
        each = ", ".join(f"{t:.1f}" for t in runs[name])
        print(f"{name}: median {seconds:.1f} s of {each}; {1e3 * seconds / n:.1f} ms a scenario, "
              f"{seconds / times['plain sweep']:.2f} x the plain sweep; {work[name]} "
              f"scenario-periods, {1e6 * seconds / work[name]:.0f} us each, "
              f"{seconds / work[name] / plain_rate:.2f} x the plain sweep's")
    print("(the cohorts' times leave out their tables and figures: "
          + ", ".join(f"{q} {s:.1f} s" for q, s in outputs.items()) + ")")


if __name__ == "__main__":
    main()
