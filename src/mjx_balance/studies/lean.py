"""Lean and release, people's protocol (Robinovitch et al. 2002, J Neurophysiol 88:613-620): how
far a body can lean forward and still come back to upright with the feet in place.

Two limits, each as the experiment reports it:

- **static** (the tethered lean): the largest lean at which the body can be *held* still, feet in
  place, hip straight. Holding lean theta asks the motors for the gravity torques at that pose
  (MuJoCo's ``qfrc_bias`` at the ankle and hip with zero velocity); the lean is held when those
  torques, written in the controller's inputs (``LinearModel.torque_map``: in ``paper``
  tau_ankle = tau1 + tau2, tau_hip = tau2; in ``joint`` u = tau; with a hip servo, the servo
  holds the hip and the inputs give the ankle's torque alone), lie within the input bounds, and
  when the CoM (the static centre of pressure) stays over the foot. The smaller of the two
  angles is the limit; both are reported.
- **dynamic** (lean and release): the largest initial lean, released from rest (the body rigid,
  hip straight, zero velocity; the controller starts cold, after its delay; with
  ``scenario.relaxed_start`` from relaxed muscles, its first torque one delay after release,
  rising no faster than ``controller.input_rates``), from which the
  closed loop recovers with the feet in place (the push map's ``recovered``), every smaller lean
  recovering too. Found on the batched engine (its per-scenario initial state, as the basin's
  cells) by ``thresholds.largest_passing``: a scan, then rounds inside the first bracket that
  fails, until the bracket is ``resolution`` wide.
- **one step** (Thelen et al. 1997's single-step protocol): the largest lean released from rest
  from which the body recovers in place or would with one step (``steps_needed`` <= 1: the
  capture columns of the same feet-in-place runs, docs/model.md "Stepping: capturability"),
  every smaller lean too; the same search.

The lean is the angle of the rigid body (ankle to CoM) from vertical, positive forward: the
direction in which a positive push moves the CoM (``Plane.com_x`` grows with q_a). People's
numbers to hold these against ship in ``data/references/people.csv`` (docs/people.md,
"People").
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import mujoco
import numpy as np
import pandas as pd
import scipy.optimize

from ..measures.capture import saved
from ..measures.outcomes import RECOVERED
from ..model.linear import linear_model
from ..model.params import Config
from ..rollout import BatchRunner
from ..runs.chunks import PlanHook, PlannedWork
from ..store.files import write_csv
from .basin import Plane
from .references import read_people
from .thresholds import (
    SCAN,
    agreement,
    check_bracket,
    largest_passing,
    planned_runs,
    protocol_folder,
)

MAX_LEAN_DEG = 30.0  # the scan's upper end: beyond any lean a feet-in-place body recovers
# The one-step scan's upper end: people's single-step limits reach 32.5 deg (young men, Thelen
# et al. 1997), beyond the feet-in-place scan's; no one-step recovery from 60 deg was reported
MAX_STEP_LEAN_DEG = 60.0


@dataclass(frozen=True)
class LeanLimits:
    """The lean-and-release limits of one configuration (degrees; torques in N m)."""

    static_deg: float  # held still: min(static_torque_deg, static_foot_deg)
    static_torque_deg: float  # where the gravity torques leave the input bounds
    static_foot_deg: float  # where the CoM leaves the foot (the toe)
    dynamic_deg: float  # released from rest: the largest lean that recovers (every smaller too)
    resolution_deg: float  # the dynamic limit's bracket width
    peak_ankle_torque: float  # |tau_ankle| peak of the run at the dynamic limit
    scenarios: int  # batched scenarios run
    # released from rest: the largest lean that recovers in place or with one step (every
    # smaller too; steps_needed, capturability, docs/model.md "Stepping: capturability")
    one_step_deg: float = float("nan")

    def row(self) -> dict[str, float]:
        return {name: getattr(self, name) for name in self.__dataclass_fields__}


def _bias_torques(plane: Plane, lean: float) -> np.ndarray:
    """The joint torques [tau_ankle, tau_hip] that hold the rigid lean ``lean`` still."""
    data, ix = plane.data, plane.ix
    data.qpos[:] = plane.rest
    data.qpos[[ix.ankle_qpos, ix.hip_qpos]] = (lean, 0.0)
    data.qvel[:] = 0.0
    mujoco.mj_forward(plane.model, data)
    return data.qfrc_bias[[ix.ankle_dof, ix.hip_dof]].copy()


def static_limits(config: Config, plane: Plane | None = None) -> tuple[float, float]:
    """(torque-limited, foot-limited) static lean limits in degrees, forward."""
    plane = plane or Plane(config)
    lm = linear_model(config.body, config.controller.convention, config.scenario.control_dt)
    (lo1, hi1), (lo2, hi2) = config.controller.input_bounds

    servo = config.body.hip_servo_stiffness > 0

    def excess(lean: float) -> float:  # > 0: the inputs that hold this lean leave the bounds
        tau = _bias_torques(plane, lean)
        if servo:  # the hip servo holds the hip; the motors give the ankle's torque alone
            return max(tau[0] - hi1, lo1 - tau[0])  # tau = Sᵀ u, u2 = 0: u1 = tau_ankle
        u = np.linalg.solve(lm.torque_map, tau)
        return max(u[0] - hi1, lo1 - u[0], u[1] - hi2, lo2 - u[1])

    top = math.radians(MAX_LEAN_DEG)
    if excess(0.0) > 0:
        torque = 0.0  # even upright rest is beyond the bounds
    elif excess(top) <= 0:
        torque = top
    else:
        torque = scipy.optimize.brentq(excess, 0.0, top, xtol=1e-10)
    foot = scipy.optimize.brentq(
        lambda a: plane.com_x("rigid", a) - plane.toe, 0.0, math.radians(89.0), xtol=1e-10
    )
    return math.degrees(torque), math.degrees(foot)


def lean_states(plane: Plane, leans_deg: np.ndarray) -> np.ndarray:
    """Initial joint states [q_a, q_h, dq_a, dq_h] of rigid leans (degrees), at rest."""
    out = np.zeros((len(leans_deg), 4))
    out[:, 0] = np.radians(leans_deg)
    return out


def recovers(
    runner: Any, plane: Plane, leans_deg: np.ndarray, within: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Whether each lean released from rest recovers (``within``: in place or with at most that
    many steps, ``steps_needed``), and each run's peak |tau_ankle|, in calls of ``SCAN`` leans
    (the last padded with its first lean)."""
    ok, peaks = [], []
    for start in range(0, len(leans_deg), SCAN):
        part = np.asarray(leans_deg[start : start + SCAN], float)
        padded = np.concatenate([part, np.full(SCAN - part.size, part[0])])
        zeros = np.zeros(SCAN)
        out = runner.run(zeros, zeros, lean_states(plane, padded))
        passed = saved(np.asarray(out["outcome"]) == RECOVERED, out.get("steps_needed"), within)
        ok.append(passed[: part.size])
        peaks.append(np.asarray(out["peak_tau_ankle"])[: part.size])
    return np.concatenate(ok), np.concatenate(peaks)


def check_resolution(resolution: Any) -> None:
    """Refuse a bracket width outside [0.001, 1] degrees (one line)."""
    check_bracket(resolution, 0.001, 1.0, "degrees")


def lean_limits(
    config: Config,
    *,
    resolution: float = 0.05,
    runner: Any = None,
    slots: int | None = None,
    say: Callable[[str], None] | None = None,
) -> LeanLimits:
    """The static and dynamic lean limits of ``config`` (module docstring); ``resolution``: the
    dynamic limit's bracket width in degrees; ``runner``: a batch runner with ``run(forces,
    durations, inits)`` (default: the batched engine of ``config``)."""
    check_resolution(resolution)
    say = say or (lambda _text: None)
    plane = Plane(config)
    if not plane.com_x("rigid", 0.01) > plane.com_x("rigid", 0.0):
        raise RuntimeError("a positive ankle angle does not lean the body forward")
    torque_deg, foot_deg = static_limits(config, plane)
    if runner is None:
        runner = BatchRunner(config, physics="mjx", slots=slots)
    found = largest_passing(
        lambda leans: recovers(runner, plane, leans),
        MAX_LEAN_DEG,
        resolution,
        lambda low, high: say(
            f"lean and release: recovers at {low:.3f} deg, not at {high:.3f} deg"
        ),
    )
    stepped = largest_passing(
        lambda leans: recovers(runner, plane, leans, within=1),
        MAX_STEP_LEAN_DEG,
        resolution,
        lambda low, high: say(
            f"lean and release, one step: recovers at {low:.3f} deg, not at {high:.3f} deg"
        ),
    )
    return LeanLimits(
        static_deg=min(torque_deg, foot_deg),
        static_torque_deg=torque_deg,
        static_foot_deg=foot_deg,
        dynamic_deg=found.low,
        resolution_deg=found.width,
        peak_ankle_torque=found.peak,
        scenarios=found.runs + stepped.runs,
        one_step_deg=stepped.low,
    )


# The people reference's rows these limits predict (data/references/people.csv: measure ->
# the LeanLimits field that predicts it). Not the static recovery limit: there the tether stays
# on while the subject pulls back to upright (it carries part of the weight), which our static
# limit, the lean held still without support, is not.
PREDICTS = {
    "lean_release_max_angle_young": "dynamic_deg",
    "lean_release_peak_ankle_torque_young": "peak_ankle_torque",
}


def against_people(limits: LeanLimits, people: pd.DataFrame) -> pd.DataFrame:
    """The people reference's lean-and-release rows beside our prediction: agreement within the
    published mean +- 2 SD (``thresholds.agreement``)."""
    return pd.DataFrame(
        [agreement(m, float(getattr(limits, f)), people) for m, f in PREDICTS.items()]
    )


def scored(limits: LeanLimits) -> pd.DataFrame:
    """:func:`against_people` with the people reference, every limit in
    ``.attrs["limits"]`` (:meth:`LeanLimits.row`): what ``mb.lean_release`` returns."""
    frame = against_people(limits, read_people())
    frame.attrs["limits"] = limits.row()
    return frame


LEAN_CSV = "lean.csv"  # the people reference's rows beside our prediction
LIMITS_CSV = "lean_limits.csv"  # every limit (LeanLimits.row)


def planned_scenarios(resolution: float) -> int:
    """The most scenarios :func:`lean_limits` runs (``thresholds.planned_runs``: in place, and
    with one step)."""
    return planned_runs(MAX_LEAN_DEG, resolution) + planned_runs(MAX_STEP_LEAN_DEG, resolution)


def run_lean(
    out: str | os.PathLike[str],
    config: Config,
    *,
    resolution: float = 0.05,
    slots: int | None = None,
    say: Callable[[str], None] = print,
    plan: PlanHook | None = None,
    wait: bool = False,
) -> pd.DataFrame:
    """Lean and release of ``config`` in OUT (``mjx-balance lean``): lean.csv (the people
    reference's rows of the protocol beside our prediction, ``agrees`` within 2 SD) and
    lean_limits.csv (every limit). Every input is checked, then ``plan`` hears the work, then
    the limits are found under OUT's lock (``wait``: for another run that holds it); a folder
    made with another configuration is refused. Returns lean.csv's rows (:func:`scored`)."""
    check_resolution(resolution)
    if plan is not None:
        plan(PlannedWork(config, planned_scenarios(resolution), "leans", note="lean and release"))
    out = Path(out)
    with protocol_folder(out, config, {"lean": {"resolution": resolution}}, wait=wait):
        limits = lean_limits(config, resolution=resolution, slots=slots, say=say)
        frame = scored(limits)
        write_csv(frame, out / LEAN_CSV)
        write_csv(pd.DataFrame([limits.row()]), out / LIMITS_CSV)
    say(
        f"lean and release: static {limits.static_deg:.2f} deg (torque "
        f"{limits.static_torque_deg:.2f}, foot {limits.static_foot_deg:.2f}), dynamic "
        f"{limits.dynamic_deg:.2f} deg, peak ankle torque {limits.peak_ankle_torque:.1f} N m, "
        f"with one step {limits.one_step_deg:.2f} deg; "
        f"{int(frame.agrees.sum())} of {len(frame)} people's measures agree"
    )
    say(f"wrote {out / LEAN_CSV} and {out / LIMITS_CSV}")
    return frame
