"""Lean and release with people's strength and timing (docs/people.md, "People"): the static
and dynamic lean limits of the ankle-only body as measured strength, the onset latency, the
relaxed start and the rate of torque development are added one at a time.

    python docs/scripts/lean_timing.py [--resolution 0.05]

Every number is a published measurement, never fitted to the limit it is held against:
- ankle strength: maximal isometric voluntary torques of 11 young men (mean 24 yr),
  plantarflexion 132 N m, dorsiflexion 45 N m (Simoneau, Martin & Van Hoecke 2005,
  J Gerontol A Biol Sci Med Sci 60(4):439-447, doi:10.1093/gerona/60.4.439, abstract). A
  forward lean is held by a negative ankle torque (docs/model.md, "Strength and timing"), so
  input1_bounds = [-132, 45];
- onset latency and rate of ankle torque development in the lean-and-release trials
  themselves: 99 +- 13 ms and 372 +- 267 N m/s (Robinovitch et al. 2002, J Neurophysiol
  88:613-620, people.csv). The delay is 0.1 s, the nearest whole number of 2-ms physics steps
  above 99 ms (0.098 and 0.100 are equally near; the later one is taken), compensated as the
  study's delay rows were. The rate is also run at the mean minus and plus one SD.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mjx_balance.model.params import Config
from mjx_balance.runs.definitions import load_sweep
from mjx_balance.studies.lean import lean_limits

ROOT = Path(__file__).resolve().parents[2]
PLANTAR, DORSI = 132.0, 45.0  # N m, Simoneau et al. 2005, young men
DELAY = 0.1  # s, Robinovitch et al. 2002: 99 +- 13 ms, on the 2-ms step grid
RATE, RATE_SD = 372.0, 267.0  # N m/s, Robinovitch et al. 2002


def rows(base):
    """(label, configuration) of each step, one change at a time."""
    strong = base.replace(controller={"input1_bounds": [-PLANTAR, DORSI]})
    late = strong.replace(
        controller={"delay_compensation": True}, scenario={"controller_delay": DELAY}
    )
    relaxed = late.replace(scenario={"relaxed_start": True})
    yield "ankle only, study's bound +-20 N m", base
    yield "ankle strength of young men [-132, 45] N m", strong
    yield "+ onset latency 0.1 s (compensated), lean seen before release", late
    yield "+ relaxed start (torque from 0, one latency after release)", relaxed
    for rate in (RATE - RATE_SD, RATE, RATE + RATE_SD):
        yield f"+ rate of torque development {rate:g} N m/s", relaxed.replace(
            controller={"input_rates": [rate, rate]}
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=float, default=0.05, help="degrees")
    args = parser.parse_args()
    base = load_sweep(ROOT / "sweeps" / "study_ankle_only.toml", Config()).config
    print("| configuration | static (torque / foot) | dynamic | peak ankle torque | s |")
    print("|---|---|---|---|---|")
    for label, config in rows(base):
        start = time.perf_counter()
        lim = lean_limits(config, resolution=args.resolution)
        print(
            f"| {label} | {lim.static_torque_deg:.2f} / {lim.static_foot_deg:.2f} deg "
            f"| {lim.dynamic_deg:.2f} deg | {lim.peak_ankle_torque:.1f} N m "
            f"| {time.perf_counter() - start:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
