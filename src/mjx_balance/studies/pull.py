"""The waist pull, people's protocol (DePasquale & Toscano 2009, J Geriatr Phys Ther 32(4): the
Spring Scale Test): a horizontal pull at the pelvis, held, raised in steps until the person
steps. Its threshold is the pull in % of body weight.

Our body keeps its feet in place, so its threshold is the largest pull it *holds*: a force at
the hip joint (``scenario.push_body = "hip"``, the pelvis of the two-link body), on from t = 0
to the end of the window, that does not knock the body over (the outcome is recovered or
not_settled, as the table's sustained-push limit), every smaller scanned pull held too. The
pull is loaded as a spring-scale test loads it, gradually: it rises linearly over ``ramp``
seconds (``scenario.push_ramp``; default :data:`RAMP`, slow beside the body's own sway of about
a second), then holds; ``ramp=0`` applies it at once (a step, as the table's sustained push). Found
on the batched engine by ``thresholds.largest_passing``, forward (a pull from the front, the
body's toes ahead) and backward (towards the heels), and given in newtons and in % of the body's
weight (total mass x g). A person steps at or before the pull their feet can hold, so ours is
an upper bound of theirs: people may step earlier by choice.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from ..measures.outcomes import NOT_SETTLED, RECOVERED
from ..model.params import Config
from ..rollout import BatchRunner
from ..runs.chunks import PlanHook, PlannedWork
from ..store.files import write_csv
from .thresholds import Bracket, check_bracket, largest_passing, planned_runs, protocol_folder

RAMP = 5.0  # s: the pull's default rise time (then held to t_end)
MAX_PULL = 0.6  # the scan's top, a fraction of body weight: beyond any pull feet in place hold
DIRECTIONS = {"forward": 1.0, "backward": -1.0}


@dataclass(frozen=True)
class PullLimits:
    """The held waist-pull limits of one configuration (N, % body weight; torques in N m)."""

    ramp_s: float  # the pull's rise time (0: a step)
    forward_n: float  # the largest forward pull held for the whole window
    forward_pct: float  # the same in % of body weight
    backward_n: float  # the largest backward pull held
    backward_pct: float
    resolution_n: float  # the brackets' width (the wider of the two)
    weight_n: float  # the body's weight, total mass x g
    peak_ankle_torque_forward: float  # |tau_ankle| peak of the run at the forward limit
    peak_ankle_torque_backward: float
    scenarios: int  # batched scenarios run

    def row(self) -> dict[str, float]:
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


def check_pull_resolution(resolution: Any) -> None:
    """Refuse a bracket width outside [0.01, 10] N (one line)."""
    check_bracket(resolution, 0.01, 10.0, "N")


def pulled(config: Config, ramp: float = 0.0) -> Config:
    """``config`` pulled at the hip joint (the pelvis), the pull rising over ``ramp`` s."""
    return config.replace(scenario={"push_body": "hip", "push_ramp": ramp})


def held(runner: Any, sign: float, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether each pull of ``forces`` N in direction ``sign``, on for the whole window, is held,
    and each run's peak |tau_ankle|."""
    t_end = runner.config.scenario.t_end
    out = runner.run(sign * np.asarray(forces, float), np.full(len(forces), t_end))
    return np.isin(np.asarray(out["outcome"]), (RECOVERED, NOT_SETTLED)), np.asarray(
        out["peak_tau_ankle"]
    )


def _limit(
    runner: Any,
    sign: float,
    name: str,
    weight: float,
    resolution: float,
    ramp: float,
    say: Callable[[str], None],
) -> Bracket:
    """The largest pull held in direction ``sign`` (``name``), bracketed to ``resolution``."""

    def passes(forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return held(runner, sign, forces)

    def progress(low: float, high: float) -> None:
        say(f"waist pull {name} ({ramp:g}-s rise): held at {low:.2f} N, not at {high:.2f} N")

    return largest_passing(passes, MAX_PULL * weight, resolution, progress)


def pull_limits(
    config: Config,
    *,
    resolution: float = 0.5,
    ramp: float = RAMP,
    runner: Any = None,
    slots: int | None = None,
    say: Callable[[str], None] | None = None,
) -> PullLimits:
    """The forward and backward held-pull limits of ``config`` pulled at the hip (module
    docstring); ``resolution``: the brackets' width in N; ``ramp``: the pull's rise time in s
    (0: a step); ``runner``: a batch runner of :func:`pulled` ``config`` (default: its
    batched engine)."""
    check_pull_resolution(resolution)
    say = say or (lambda _text: None)
    config = pulled(config, ramp)
    weight = config.body.total_mass * config.body.gravity
    if runner is None:
        runner = BatchRunner(config, physics="mjx", slots=slots)
    found = {
        name: _limit(runner, sign, name, weight, resolution, ramp, say)
        for name, sign in DIRECTIONS.items()
    }
    fwd, back = found["forward"], found["backward"]
    return PullLimits(
        ramp_s=ramp,
        forward_n=fwd.low,
        forward_pct=100 * fwd.low / weight,
        backward_n=back.low,
        backward_pct=100 * back.low / weight,
        resolution_n=max(fwd.width, back.width),
        weight_n=weight,
        peak_ankle_torque_forward=fwd.peak,
        peak_ankle_torque_backward=back.peak,
        scenarios=fwd.runs + back.runs,
    )


def planned_pulls(config: Config, resolution: float) -> int:
    """The most scenarios :func:`pull_limits` runs (both directions)."""
    top = MAX_PULL * config.body.total_mass * config.body.gravity
    return len(DIRECTIONS) * planned_runs(top, resolution)


PULL_CSV = "pull.csv"  # one row: PullLimits.row


def run_pull(
    out: str | os.PathLike[str],
    config: Config,
    *,
    resolution: float = 0.5,
    ramp: float = RAMP,
    slots: int | None = None,
    say: Callable[[str], None] = print,
    plan: PlanHook | None = None,
    wait: bool = False,
) -> pd.DataFrame:
    """The waist pull of ``config`` in OUT (``mjx-balance pull``): pull.csv (one row, the
    limits). Every input is checked, then ``plan`` hears the work, then the limits are found
    under OUT's lock (``wait``: for another run that holds it); a folder made with another
    configuration is refused. Returns pull.csv's row."""
    check_pull_resolution(resolution)
    pulled(config, ramp)  # the ramp checked (within the window) before the folder is made
    if plan is not None:
        work = planned_pulls(config, resolution)
        plan(PlannedWork(config, work, "pulls", note=f"the waist pull, {ramp:g}-s rise"))
    out = Path(out)
    settings = {"pull": {"resolution": resolution, "ramp": ramp}}
    with protocol_folder(out, config, settings, wait=wait):
        limits = pull_limits(config, resolution=resolution, ramp=ramp, slots=slots, say=say)
        frame = pd.DataFrame([limits.row()])
        write_csv(frame, out / PULL_CSV)
    say(
        f"waist pull ({ramp:g}-s rise, then held): forward {limits.forward_pct:.2f} % of body "
        f"weight ({limits.forward_n:.1f} N), backward {limits.backward_pct:.2f} % "
        f"({limits.backward_n:.1f} N)"
    )
    say(f"wrote {out / PULL_CSV}")
    return frame
