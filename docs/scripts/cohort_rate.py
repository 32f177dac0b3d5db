"""A cohort's engine rate and slot occupancy, and a plain sweep of as many cells beside it (one
process, one sitting): the figures issue 39 asks of an accelerator.

    python docs/scripts/cohort_rate.py OUT [--population 100] [--seed 1] \
        [--forces 0:150:4] [--durations 0.05:2.0:0.05] [--slots 16384] [--queue one] \
        [--no-plain] [--json FILE] [--tile 8]

The cohort runs as ``mjx-balance cohort --population N --seed S`` does (``run_cohort``); the
plain sweep maps the study's body over as many cells (forces spread over the cohort's range,
the same durations). Each engine's compile is timed apart (the first build of its compiled
call), so "engine s" is the queue's run alone: every call, the host's refills and the
harvested cells' hand-over; so are the cohort's runners (its bodies' models, rest states and
QPs), the one queue's set-up (stacking the bodies), its maps' folders and its tables and
figures. Occupancy: the cells' control periods summed over the
slot-periods the engine ran (calls x block x slots of every device); scen/s: cells over
engine seconds.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np

import mjx_balance as mb
from mjx_balance.rollout import engine as engine_mod
from mjx_balance.runs.folders import run_region
from mjx_balance.runs import population
from mjx_balance.runs.grid import parse_grid
from mjx_balance.studies import cohort
from mjx_balance.studies import members as cohort_members


class Meter:
    """Counts what every engine run of a label did (wraps ``Engine.stream`` and
    ``Engine.block_fn``)."""

    def __init__(self):
        self.label = None
        self.streaming = False
        self.figures: dict[str, dict] = {}
        stream, block_fn = engine_mod.Engine.stream, engine_mod.Engine.block_fn
        meter = self

        def counted(engine, *a, **k):
            fig = meter.figures[meter.label]
            t0 = time.perf_counter()
            meter.streaming = True
            for index, raw in stream(engine, *a, **k):
                fig["cells"] += index.size
                fig["cell_periods"] += int(raw["periods"].sum())
                yield index, raw
            fig["engine_s"] += time.perf_counter() - t0
            meter.streaming = False
            fig["slot_periods"] += fig.pop("_calls", 0) * engine.block * engine.slots \
                * engine.n_devices
            fig["slots"], fig["block"], fig["tile"] = engine.slots * engine.n_devices, \
                engine.block, engine.tile

        def timed_build(engine):
            fig = meter.figures[meter.label]
            if engine._fn is None:
                t0 = time.perf_counter()
                fn = block_fn(engine)
                fig["compile_s"] += time.perf_counter() - t0
                if meter.streaming:  # built inside the stream: not the queue's time
                    fig["engine_s"] -= time.perf_counter() - t0
            else:
                fn = block_fn(engine)

            def call(*a, **k):
                fig["_calls"] = fig.get("_calls", 0) + 1
                return fn(*a, **k)
            return call

        engine_mod.Engine.stream = counted
        engine_mod.Engine.block_fn = timed_build
        # a population's runners (its bodies' models, rest states and QPs), the one queue's
        # set-up (stacking the bodies), its maps' folders and a cohort's tables and figures,
        # timed apart
        population.BatchRunner = self.timed("runners_s", population.BatchRunner)
        population.Population.__init__ = self.timed("setup_s", population.Population.__init__)
        population.run_region = self.timed("folders_s", population.run_region)
        cohort.write_outputs = self.timed("outputs_s", cohort.write_outputs)

    def timed(self, name: str, fn):
        def run(*a, **k):
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                fig = self.figures[self.label]
                fig[name] = fig.get(name, 0.0) + time.perf_counter() - t0
        return run

    def start(self, label: str) -> None:
        self.label = label
        self.figures[label] = dict(cells=0, cell_periods=0, slot_periods=0, engine_s=0.0,
                                   compile_s=0.0)

    def summary(self, label: str, wall: float) -> dict:
        fig = self.figures[label]
        fig["wall_s"] = wall
        fig["scen_per_s"] = fig["cells"] / fig["engine_s"]
        fig["occupancy"] = fig["cell_periods"] / max(1, fig["slot_periods"])
        fig["calls"] = fig["slot_periods"] // max(1, fig["block"] * fig["slots"])
        return fig


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out")
    p.add_argument("--population", type=int, default=100)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--forces", default="0:150:4")
    p.add_argument("--durations", default="0.05:2.0:0.05")
    p.add_argument("--slots", type=int, default=None)
    p.add_argument("--queue", default="one", choices=("one", "each"))
    p.add_argument("--no-plain", action="store_true", help="the cohort alone")
    p.add_argument("--json", default=None, help="also write the figures to this file")
    p.add_argument("--tile", type=int, default=None,
                   help="slots per body tile (default: the engine's LANE_TILE)")
    args = p.parse_args()
    if args.tile:
        engine_mod.LANE_TILE = args.tile  # read when an engine is built
    out = Path(args.out)
    shutil.rmtree(out, ignore_errors=True)
    config = mb.Config()
    people = cohort_members.population(args.population, args.seed)
    forces = parse_grid(args.forces, "forces")
    durations = parse_grid(args.durations, "durations")
    n = (len(people) + 1) * forces.size * durations.size
    meter = Meter()
    results = {}
    label = f"cohort --queue {args.queue}"
    meter.start(label)
    t0 = time.perf_counter()
    cohort.run_cohort(out / "cohort", people, config, forces, durations, say=None,
                      queue=args.queue, slots=args.slots, physics="mjx")
    results[label] = meter.summary(label, time.perf_counter() - t0)
    if not args.no_plain:
        plain = np.linspace(forces[0], forces[-1], n // durations.size)
        label = "plain sweep"
        meter.start(label)
        t0 = time.perf_counter()
        run_region(out / "plain", config, plain, durations, slots=args.slots, physics="mjx",
                   progress=False, say=None)
        results[label] = meter.summary(label, time.perf_counter() - t0)
    print(f"{len(people)} subjects x {forces.size * durations.size} cells and the base body's "
          f"map: {n} scenarios")
    for name, fig in results.items():
        print(f"{name}: {fig['cells']} cells, wall {fig['wall_s']:.1f} s (compile "
              f"{fig['compile_s']:.1f} s), engine {fig['engine_s']:.1f} s: "
              f"{fig['scen_per_s']:.0f} scen/s; {fig['slots']} slots, tile {fig['tile']}, "
              f"{fig['calls']} calls of {fig['block']} periods; occupancy "
              f"{100 * fig['occupancy']:.1f} %; {fig['cell_periods']} scenario-periods, "
              f"{1e6 * fig['engine_s'] / fig['cell_periods']:.2f} us each"
              + "".join(f"; {what} {fig[key]:.1f} s" for key, what in (
                  ("runners_s", "runners"), ("setup_s", "the queue's set-up"),
                  ("folders_s", "maps' folders"),
                  ("outputs_s", "tables and figures")) if key in fig))
    if len(results) == 2:
        (_, a), (_, b) = results.items()
        per_cell = (a["engine_s"] / a["cells"]) / (b["engine_s"] / b["cells"])
        per_period = (a["engine_s"] / a["cell_periods"]) / (b["engine_s"] / b["cell_periods"])
        print(f"cohort / plain: {per_cell:.2f}x per scenario, {per_period:.2f}x per "
              f"scenario-period")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
