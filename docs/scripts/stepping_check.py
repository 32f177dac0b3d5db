"""The capture columns checked by simulation, and what the decision instant's choice moves
(docs/beyond.md, "Stepping").

    python docs/scripts/stepping_check.py [study|human|human_older] [--forces SPEC]
        [--durations SPEC]

For every cell of the grid (default: the default sweep's, 0:150:10 N x 0.05..1.5 s, on the
chosen body) that falls with its feet in place on the batched engine, the scalar reference
(MuJoCo C, OSQP) runs the push with its series recorded, and prints:

1. the closed form (measures/capture.py) against the reduced model that takes the step
   (reference/stepping.py: the same pendulum with a reactive stepping controller, from the
   CoM state at the decision instant): a table of (closed form, simulated) step counts;
2. per force, the largest duration whose pushes all recover in place or with one step, with
   the decision read at the chosen instant (the first sample the feet in place cannot hold),
   at the fall sample and at the push's end (a fall before the push's end is read at its fall
   sample there): how far the choice moves the one-step boundary.
"""

from __future__ import annotations

import argparse
import math
from collections import Counter

import numpy as np

from mjx_balance.measures import capture
from mjx_balance.model.params import Config, push_steps
from mjx_balance.reference import loop as reference
from mjx_balance.reference.stepping import simulated_steps
from mjx_balance.rollout import BatchRunner
from mjx_balance.runs.grid import parse_grid
from mjx_balance.studies.people import human_config

FORCES = "0:150:10"
DURATIONS = "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5"


def steps_at(model, frame, force, duration, at):
    """The fewest steps (1, 2; inf) the closed form gives from the decision instant ``at``."""
    time = frame["time"].to_numpy()
    i = int(np.argmin(np.abs(time - at)))
    remaining = push_steps(duration, model.physics_dt) * model.physics_dt - time[i]
    xi = frame["xcom"].to_numpy()[i]
    for n in (1, 2):
        if capture.margins(model, xi, force, remaining, n)[0] >= 0:
            return float(n)
    return math.inf


def one_step_boundary(cells, key):
    """Per force, the largest duration up to which every cell recovers or needs <= 1 step."""
    out = {}
    for force in sorted({f for f, _ in cells}):
        top = 0.0
        for duration in sorted(d for f, d in cells if f == force):
            if cells[(force, duration)][key] > 1:
                break
            top = duration
        out[force] = top
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("body", nargs="?", default="study")
    parser.add_argument("--forces", default=FORCES)
    parser.add_argument("--durations", default=DURATIONS)
    args = parser.parse_args()
    config = Config() if args.body == "study" else human_config(args.body)
    model = capture.step_model(config)
    forces, durations = parse_grid(args.forces, "forces"), parse_grid(args.durations, "durations")
    f, d = np.repeat(forces, durations.size), np.tile(durations, forces.size)
    batched = BatchRunner(config).run_frame(f, d)
    print(f"{args.body}: {model}")
    cells = {}
    pairs: Counter = Counter()
    for force, duration, outcome in zip(f, d, batched["outcome"]):
        if outcome != "fell":
            cells[(force, duration)] = {"decision": 0.0, "fall": 0.0, "push_end": 0.0}
            continue
        ref, frame = reference.simulate_scenario(config, force, duration)
        if ref["outcome"] != "fell":  # the paths differ at this cell: left out
            print(f"  {force:g} N {duration:g} s: the reference {ref['outcome']}, left out")
            continue
        simulated = simulated_steps(model, frame, force, duration, ref["decision_time"])
        pairs[(ref["steps_needed"], simulated)] += 1
        end = min(push_steps(duration, model.physics_dt) * model.physics_dt, ref["fall_time"])
        cells[(force, duration)] = {
            "decision": ref["steps_needed"],
            "fall": steps_at(model, frame, force, duration, ref["fall_time"]),
            "push_end": steps_at(model, frame, force, duration, end),
        }
        if ref["steps_needed"] != simulated:
            print(
                f"  {force:g} N {duration:g} s: closed form {ref['steps_needed']:g}, simulated "
                f"{simulated:g} (decision {ref['decision_time']:.3f} s, margin "
                f"{ref['capture_margin']:.3f} m, push left "
                f"{max(duration - ref['decision_time'], 0):.3f} s)"
            )
    print("\n| closed form | simulated | cells |\n|---|---|---|")
    for (closed, sim), n in sorted(pairs.items()):
        print(f"| {closed:g} | {sim:g} | {n} |")
    agree = sum(n for (a, b), n in pairs.items() if a == b)
    print(f"agree on {agree} of {sum(pairs.values())} falls")
    bounds = {key: one_step_boundary(cells, key) for key in ("decision", "fall", "push_end")}
    print("\n| force [N] | one-step boundary [s]: decision instant | fall sample | push's end |")
    print("|---|---|---|---|")
    for force in sorted(bounds["decision"]):
        row = " | ".join(f"{bounds[k][force]:g}" for k in ("decision", "fall", "push_end"))
        print(f"| {force:g} | {row} |")


if __name__ == "__main__":
    main()
