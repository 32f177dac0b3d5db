"""Why the older human body's waist-pull limit is below people's (docs/people.md, "People"):
the limit of ``sweeps/human_older.toml``, then one change at a time, each on the batched
engine (``mb.waist_pull``; the pull at the hip, forward and backward, 0.5-N brackets).

    python docs/scripts/pull_reasons.py

Prints one row per configuration: the forward and backward limits in % of body weight and
the peak ankle torque at each (the ankle bounds are [-80, 42] N m), and the steady lean of the
shipped body under the forward limit's pull (the reference loop, 12 s)."""

from __future__ import annotations

import mjx_balance as mb
from mjx_balance.reference import loop as reference
from mjx_balance.studies.people import human_config
from mjx_balance.studies.pull import pulled

OLDER = human_config("human_older")
NO_DELAY = {"controller_delay": 0.0}
ROWS = [
    ("human_older as shipped (pull rising over 5 s)", OLDER, 5.0),
    ("the same pull applied at once", OLDER, 0.0),
    (
        "no onset latency",
        OLDER.replace(controller={"delay_compensation": False}, scenario=NO_DELAY),
        5.0,
    ),
    (
        "no onset latency, offset-free controller (integral action)",
        OLDER.replace(
            controller={"delay_compensation": False, "offset_free": True}, scenario=NO_DELAY
        ),
        5.0,
    ),
]


def main() -> None:
    print("| configuration | forward | backward | peak ankle torque fwd / back |")
    print("|---|---|---|---|")
    first = None
    for name, config, ramp in ROWS:
        row = mb.waist_pull(config, ramp=ramp).iloc[0]
        first = first if first is not None else row
        print(
            f"| {name} | {row.forward_pct:.2f} % ({row.forward_n:.1f} N) | "
            f"{row.backward_pct:.2f} % ({row.backward_n:.1f} N) | "
            f"{row.peak_ankle_torque_forward:.1f} / {row.peak_ankle_torque_backward:.1f} N m |"
        )
    config = pulled(OLDER, 5.0)
    force = float(int(first.forward_n))  # a whole newton below the shipped body's limit
    series = reference.simulate_scenario(config, force, config.scenario.t_end)[1]
    end = series.iloc[-1]
    print(
        f"steady state under {force:g} N forward (reference, t = {end.time:.2f} s): ankle "
        f"{end.q_a * 57.29578:.1f} deg, hip {end.q_h * 57.29578:.1f} deg, ankle torque "
        f"{end.tau_ankle:.1f} N m (the pull's own moment {force * config.body.lower_length:.1f})"
    )


if __name__ == "__main__":
    main()
