"""The scalar reference's rate (simulate, the basin's push cells) in window-seconds per second:
light pushes (constraints inactive: OSQP stops in few iterations) and hard ones (bounds
active, or a fall), each in one process after a warm-up push. Run: python
docs/scripts/reference_rate.py; BENCHMARKS.md, "The scalar reference's rate", has its output."""

import time

from mjx_balance.model.params import Config
from mjx_balance.reference.loop import simulate_pairs

config = Config().replace(scenario={"t_end": 4.0})
simulate_pairs(config, [(10.0, 0.1)], progress=False)  # warm-up: imports, first model build
for name, pairs in {"light (0-30 N x 0.1 s)": [(f, 0.1) for f in (0, 10, 20, 30)],
                    "hard (40-100 N x 0.2 s)": [(f, 0.2) for f in (40, 60, 80, 100)]}.items():
    start = time.perf_counter()
    summary, _ = simulate_pairs(config, pairs, progress=False)
    seconds = time.perf_counter() - start
    window = len(pairs) * config.scenario.t_end
    print(f"{name}: {len(pairs)} pushes x {config.scenario.t_end:g} s in {seconds:.2f} s: "
          f"{window / seconds:.2f} window-s/s; outcomes {list(summary.outcome)}")
