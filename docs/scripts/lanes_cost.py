"""What the per-lane bodies cost a plain sweep: the same cells through the engine with one
shared body and with the body as per-lane data (the cohort's one queue; its QPs by body tiles
of each size asked), alternated in one process so that all see the same machine load.

    python docs/scripts/lanes_cost.py [--forces 0:155:5] [--durations 0.1,0.2,0.3,0.5] \
        [--t-end 12] [--repeats 3] [--tiles 8]

Prints seconds per run (compiling excluded: each engine runs once before timing).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import mjx_balance as mb
from mjx_balance.rollout import BatchRunner
from mjx_balance.rollout.engine import Engine
from mjx_balance.rollout.runner import push_steps
from mjx_balance.runs.grid import grid_cells, parse_grid


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--forces", default="0:155:5")
    p.add_argument("--durations", default="0.1,0.2,0.3,0.5")
    p.add_argument("--t-end", type=float, default=12.0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--slots", type=int, default=None)
    p.add_argument("--tiles", default="8", help="body tile sizes, comma-separated")
    args = p.parse_args()
    config = mb.Config().replace(scenario={"t_end": args.t_end})
    f, d = grid_cells(parse_grid(args.forces, "forces"), parse_grid(args.durations, "durations"))
    n_push = push_steps(d, config.scenario.physics_dt)
    runner = BatchRunner(config, slots=args.slots, physics="mjx")
    engines = {"shared body": Engine(runner, slots=args.slots)}
    for tile in (int(t) for t in args.tiles.split(",")):
        engines[f"per-lane body, tiles of {tile}"] = Engine(runner, slots=args.slots,
                                                            bodies=[runner], tile=tile)
    for name, engine in engines.items():
        t0 = time.perf_counter()
        engine.run(f, n_push)
        print(f"{name}: first run (compiles) {time.perf_counter() - t0:.1f} s", flush=True)
    times: dict[str, list[float]] = {name: [] for name in engines}
    for _ in range(args.repeats):
        for name, engine in engines.items():
            t0 = time.perf_counter()
            raw = engine.run(f, n_push)
            times[name].append(time.perf_counter() - t0)
    print(f"{f.size} cells, t_end {args.t_end:g} s, {engines['shared body'].slots} slots, "
          f"{int(raw['periods'].sum())} scenario-periods a run")
    for name, ts in times.items():
        runs = ", ".join(f"{t:.2f}" for t in ts)
        print(f"{name}: median {np.median(ts):.2f} s of {len(ts)} ({runs})")
    for name, ts in times.items():
        if name != "shared body":
            print(f"{name} / shared: {np.median(ts) / np.median(times['shared body']):.3f}")


if __name__ == "__main__":
    main()
