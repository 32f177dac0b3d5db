"""The human body's recovery basin beside Pai & Patton's (1997) feasible stability region
(docs/people.md, "People"): the young human body with the ankle strategy alone (an inverted
pendulum on a foot, as their model), released from a rigid posture at each (x_com, v_com), on
the batched engine (``mb.basin``); their boundary points, converted to this body, drawn on it.

    python docs/scripts/basin_fsr.py OUT      # ~3 min on a 2-core CPU; OUT/basin_fsr.png

Two panels: the body as shipped, and the same with strength only (no onset latency, no rate
limit, not relaxed), nearer their model's instant torques.

Pai YC, Patton JL (1997), J Biomech 30(4):347-354 (erratum 31(2):199), abstract: "The upper
boundary of the resulting feasible region ran from a velocity of 1.1 s-1 (normalized to body
height) at 2.4 foot lengths behind the heel, to 0.45 s-1 over the heel, to zero over the toe,
and the lower boundary from a velocity of 0.9 s-1 at 2.7 foot lengths behind the heel, to zero
over the heel." Positions in foot lengths from the heel, velocities times the body's height.
Their region is a model's (an optimisation over ankle torques with the CoM brought to rest over
the foot), not a measurement of people; it reaches far behind the heel (sit-to-stand), where a
standing body's lean is beyond its joint bounds, so only its part over the foot is drawn.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import mjx_balance as mb
from mjx_balance.studies.people import ankle_strategy, human_config

HEIGHT = 1.741  # m, the human body's stature (de Leva's reference male)
UPPER = [(-2.4, 1.1), (0.0, 0.45), (1.0, 0.0)]  # (foot lengths from the heel, v / height [1/s])
LOWER = [(-2.7, 0.9), (0.0, 0.0)]


def converted(points, heel: float, foot: float) -> np.ndarray:
    """Pai & Patton's points as (x_com [m] from the ankle, v_com [m/s]) of this body."""
    return np.array([(heel + f * foot, v * HEIGHT) for f, v in points])


BODIES = {
    "human, ankle strategy (strength, onset, rate, relaxed start)": {},
    "strength only (no onset latency, no rate limit, not relaxed)": {
        "controller": {"input_rates": None, "delay_compensation": False},
        "scenario": {"controller_delay": 0.0, "relaxed_start": False},
    },
}


def spans(frame: pd.DataFrame) -> pd.DataFrame:
    """Per velocity, the recovered cells' smallest and largest x_com (NaN: none)."""
    ok = frame[frame["outcome"] == "recovered"].groupby("v_com")["x_com"]
    every = pd.Index(sorted(frame["v_com"].unique()), name="v_com")
    return pd.DataFrame({"x_min": ok.min(), "x_max": ok.max()}).reindex(every)


def main(out: Path) -> None:
    base = ankle_strategy(human_config("human"))
    heel, toe = base.body.sole_edges
    upper = converted(UPPER, heel, toe - heel)
    lower = converted(LOWER, heel, toe - heel)
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), layout="constrained", sharey=True)
    table = []
    for ax, (name, change) in zip(axes, BODIES.items()):
        config = base.replace(**change) if change else base
        folder = out / ("basin_timing" if not change else "basin_strength")
        frame = mb.basin(config, out=folder, x_com="-0.16:0.18:0.02", v_com="-0.4:1.0:0.1")
        grid = frame.pivot(index="v_com", columns="x_com", values="outcome") == "recovered"
        xs, vs = grid.columns.to_numpy(), grid.index.to_numpy()
        ax.pcolormesh(xs, vs, grid.to_numpy(float), cmap="Greens", vmin=0, vmax=1.4,
                      shading="nearest")
        ax.plot(upper[:, 0], upper[:, 1], "k-o", label="Pai & Patton 1997: upper boundary")
        ax.plot(lower[:, 0], lower[:, 1], "k--s", label="lower boundary")
        for x, edge in ((heel, "heel"), (toe, "toe")):
            ax.axvline(x, color="grey", lw=0.8)
            ax.text(x, vs.max(), f" {edge}", va="top", fontsize=8)
        ax.set_xlim(xs.min() - 0.01, xs.max() + 0.01)
        ax.set_ylim(vs.min() - 0.05, vs.max() + 0.05)
        ax.set_xlabel("x_com, CoM ahead of the ankle [m]")
        ax.set_title(f"{name}:\nrecovered from a rigid start (green)", fontsize=9)
        table.append(spans(frame).add_prefix(f"{'timing' if not change else 'strength'}_"))
    axes[0].set_ylabel("v_com [m/s]")
    axes[0].legend(fontsize=8, loc="lower left")
    fig.savefig(out / "basin_fsr.png", dpi=110)
    print(pd.concat(table, axis=1).round(3).to_string())
    print("Pai & Patton upper boundary here:", np.round(upper, 3).tolist())
    print("lower boundary here:", np.round(lower, 3).tolist())


if __name__ == "__main__":
    main(Path(sys.argv[1]))
