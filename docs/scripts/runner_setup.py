"""A runner's set-up time (``rollout.BatchRunner``: the body's MuJoCo and MJX models, its rest
state, the QP) for five subjects' bodies, after a first runner: what a cohort, compare or
landscape pays per body before its first scenario; and, with ``--stack N``, the one queue's
stacking of N bodies' arrays and certificates (``engine.lane_bodies``, after a first stacking
of three), per body.

    PYTHONPATH=CHECKOUT/src python docs/scripts/runner_setup.py [--stack 24]

Prints the package's path and the mean seconds a runner (and a stacked body).
"""

from __future__ import annotations

import argparse
import time

import mjx_balance as mb
from mjx_balance.rollout import BatchRunner
from mjx_balance.rollout.engine import lane_bodies


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--stack", type=int, default=0)
    args = p.parse_args()
    configs = [mb.Subject(1.55 + 0.05 * i, 50 + 5 * i).config() for i in range(6)]
    BatchRunner(configs[0], physics="mjx")  # the first: imports and first traces
    t0 = time.perf_counter()
    for config in configs[1:]:
        BatchRunner(config, physics="mjx")
    print(mb.__file__, f"{(time.perf_counter() - t0) / 5:.3f} s a runner")
    if args.stack:
        runners = [BatchRunner(mb.Subject(1.55 + 0.35 * i / args.stack, 50 + 50 * i
                                          / args.stack).config(), physics="mjx")
                   for i in range(args.stack)]
        lane_bodies(runners[0], runners[:3], True)
        t0 = time.perf_counter()
        lane_bodies(runners[0], runners, True)
        print(f"{(time.perf_counter() - t0) / args.stack:.4f} s a stacked body "
              f"({args.stack} bodies)")


if __name__ == "__main__":
    main()
