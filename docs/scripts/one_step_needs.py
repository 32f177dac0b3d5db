"""What the single-step rows' published means ask of the step (people.csv's reasons for the
four single-step rows; docs/people.md, "The people scorecard").

For each body of the people scorecard that predicts a single-step row (the young and the older
man, the young and the older woman), the one-step lean limit as shipped, then, bisected with the
other number as shipped: the step length (of height) whose one-step limit reaches the
published mean, and the step's landing time that does. The feet-in-place runs are the lean
protocol's (ankle strategy, 0.05-deg brackets on the batched engine); only the capture columns'
step changes (body data: one compiled program).

    python docs/scripts/one_step_needs.py        # 2-core CPU: about 15 min
"""

from __future__ import annotations

import time

from mjx_balance.rollout import BatchRunner
from mjx_balance.studies import lean, people
from mjx_balance.studies.basin import Plane
from mjx_balance.studies.references import read_people
from mjx_balance.studies.thresholds import largest_passing

ROWS = {
    "lean_release_single_step_max_angle_young_men": "human",
    "lean_release_single_step_max_angle_older_men": "human_older",
    "lean_release_single_step_max_angle_young_women": "human_women",
    "lean_release_single_step_max_angle_older_women": "human_older_women",
}
RESOLUTION = 0.05  # deg, as the scorecard
ROUNDS = 7  # bisection rounds on the step's number


def one_step_deg(config) -> float:
    """The one-step lean limit of ``config`` (ankle strategy), the scorecard's search."""
    ankle = people.ankle_strategy(config)
    runner = BatchRunner(ankle, physics="mjx")
    plane = Plane(ankle)
    found = largest_passing(
        lambda leans: lean.recovers(runner, plane, leans, within=1),
        lean.MAX_STEP_LEAN_DEG,
        RESOLUTION,
    )
    return found.low


def needed(config, field: str, low: float, high: float, target: float) -> float:
    """The ``body.<field>`` at which the one-step limit reaches ``target`` (the limit grows with
    the step's length and falls with its time), bisected in [low, high]."""
    grows = field == "step_length"
    for _ in range(ROUNDS):
        mid = (low + high) / 2
        reaches = one_step_deg(config.replace(body={field: mid})) >= target
        if reaches == grows:
            high = mid
        else:
            low = mid
    return (low + high) / 2


def main() -> None:
    published = read_people().set_index("measure")["mean"]
    print(
        "| row | body | published | ours | step length for it (of height, m) | landing time for it |"
    )
    print("|---|---|---|---|---|---|")
    for measure, body in ROWS.items():
        t0 = time.perf_counter()
        config = people.human_config(body)
        target = float(published[measure])
        ours = one_step_deg(config)
        length = needed(config, "step_length", 0.05, 1.2, target)
        landing = needed(config, "step_time", 0.05, 0.8, target)
        height = config.body.height
        print(
            f"| {measure} | {body} | {target:g} | {ours:.2f} | {length:.3f} ({length * height:.2f} m) "
            f"| {landing:.3f} s (shipped {config.body.step_time:.3f}) | {time.perf_counter() - t0:.0f} s",
            flush=True,
        )


if __name__ == "__main__":
    main()
