"""What the study's body would need to meet people's lean-and-release limit (issue 49, item 6;
docs/people.md, "People"): the factor on its ankle bounds with which the ankle-only study
body's dynamic limit reaches the people reference's 5.9 +- 1.1 deg (Robinovitch et al. 2002):
its mean and the lower edge of agreement (mean - 2 SD, 3.7 deg), without and with people's
timing (the 0.1-s compensated onset, the relaxed start, 372 N m/s rising: docs/model.md,
"Strength and timing"; the rate scaled with the bound, as a subject's).

    python docs/scripts/study_needs.py     # ~4 min on a 2-core CPU

Each factor is found by bisection (brentq, to 0.01) on the dynamic limit of mb.lean_release
(bracket 0.05 deg): the study's body, `joint` convention, ankle bound +-20 N m x factor."""

from __future__ import annotations

import scipy.optimize

from mjx_balance.model.params import Config
from mjx_balance.runs.definitions import find_sweep, load_sweep
from mjx_balance.studies.lean import lean_limits

STUDY = load_sweep(find_sweep("study_ankle_only"), Config()).config.replace(
    controller={"convention": "joint"}
)
TIMING = {
    "controller": {"delay_compensation": True},
    "scenario": {"controller_delay": 0.1, "relaxed_start": True},
}
TOP = 6.6  # the factor that gives +-132 N m, the young men's plantarflexion (Simoneau 2005)
RATE = 372.0  # N m/s at the factor that gives the young men's plantarflexion, 132 N m


def dynamic(factor: float, timing: bool) -> float:
    bound = 20.0 * factor
    controller = {"input1_bounds": [-bound, bound]}
    config = STUDY.replace(controller=controller)
    if timing:
        config = config.replace(**TIMING).replace(
            controller={"input_rates": [RATE * bound / 132.0, RATE * bound / 132.0]}
        )
    return lean_limits(config, resolution=0.05).dynamic_deg


def main() -> None:
    print("| timing | target | factor on +-20 N m | ankle bound | dynamic limit there |")
    print("|---|---|---|---|---|")
    for timing in (False, True):
        for target in (3.7, 5.9):
            top = dynamic(TOP, timing)
            if top < target:  # not reached with the young men's plantarflexion either way
                print(
                    f"| {'people' if timing else 'none'} | {target} deg | not reached up to "
                    f"{TOP} | +-{20 * TOP:.0f} N m | {top:.2f} deg |"
                )
                continue
            factor = scipy.optimize.brentq(
                lambda f, t, g: dynamic(f, t) - g, 1.0, TOP, args=(timing, target), xtol=0.01
            )
            print(
                f"| {'people' if timing else 'none'} | {target} deg | {factor:.2f} | "
                f"+-{20 * factor:.0f} N m | {dynamic(factor, timing):.2f} deg |"
            )


if __name__ == "__main__":
    main()
