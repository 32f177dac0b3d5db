"""A runner's set-up time (``rollout.BatchRunner``: the body's MuJoCo and MJX models, its rest
state, the QP) for five subjects' bodies, after a first runner: what a cohort, compare or
landscape pays per body before its first scenario.

    PYTHONPATH=CHECKOUT/src python docs/scripts/runner_setup.py

Prints the package's path and the mean seconds a runner.
"""

from __future__ import annotations

import time

import mjx_balance as mb
from mjx_balance.rollout import BatchRunner


def main() -> None:
    configs = [mb.Subject(1.55 + 0.05 * i, 50 + 5 * i).config() for i in range(6)]
    BatchRunner(configs[0], physics="mjx")  # the first: imports and first traces
    t0 = time.perf_counter()
    for config in configs[1:]:
        BatchRunner(config, physics="mjx")
    print(mb.__file__, f"{(time.perf_counter() - t0) / 5:.3f} s a runner")


if __name__ == "__main__":
    main()
