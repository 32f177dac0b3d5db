"""The figures behind the recovery certificate's margins (``control/certificate.py``), measured
on MJX runs: ``python -m mjx_balance.rollout.margins`` prints them."""

from __future__ import annotations

import jax
import numpy as np

from ..model.params import Config
from .runner import BatchRunner


def measure(config=None, forces=None, durations=None) -> dict:
    """The figures behind the margins, from MuJoCo runs (MJX, float32): certified scenarios of a
    grid of pushes re-run to t_end with trajectories. Returns (and ``python -m
    mjx_balance.rollout.margins`` prints) the band use after the certified instant (largest |joint
    angle| / settle tolerance and |rate| / tolerance: < 1 means the band held; MARGIN allows
    0.5 for the linear prediction), the largest growth of V after it, and the foot pitch per CoP
    excursion over every sample of recovering runs."""
    config = config or Config()
    forces = np.array(
        [5.0, 10.0, 20.0, 30.0, 40.0, 60.0, 80.0, 100.0, -20.0, -40.0, -80.0]
        if forces is None
        else forces
    )
    durations = np.array([0.05, 0.1, 0.2, 0.5, 1.0] if durations is None else durations)
    f, d = np.repeat(forces, durations.size), np.tile(durations, forces.size)
    sc = config.scenario
    with jax.enable_x64(False):
        early = BatchRunner(config)
        early.run(f, d)
        assert early.last_certified is not None and early.last_periods is not None  # (run sets)
        pick = np.nonzero(early.last_certified)[0]
        traj = BatchRunner(config, trajectories=True)
        summary = traj.run(f[pick], d[pick])
    series, sensors = traj.last_trajectories, traj.sensors
    assert series is not None  # (trajectories=True)
    lm = traj.qp.linear
    P = traj.qp.Qf
    com_rest = float(np.asarray(early.engine.cert.rest)[1])
    angle_use = rate_use = growth = 0.0
    ratio, floor = 0.0, 0.0
    for row, i in enumerate(pick):
        step = int(early.last_periods[i]) * sc.substeps
        q = series["qpos"][row][:, sensors.joints_q]
        dq = series["qvel"][row][:, sensors.joints_v]
        angle_use = max(angle_use, float(np.abs(q[step - 1 :]).max()) / sc.settle_angle_tol)
        rate_use = max(rate_use, float(np.abs(dq[step - 1 :]).max()) / sc.settle_rate_tol)
        x = lm.state_from_joints(q[step - 1 :: sc.substeps], dq[step - 1 :: sc.substeps])
        V = np.einsum("ti,ij,tj->t", x, P, x)
        growth = max(growth, float(V.max() / V[0]))
        if summary["outcome"][row] == 0:  # recovered: the foot-pitch relation
            pitch = np.abs(series["qpos"][row][:, sensors.foot_pitch])
            excursion = np.abs(series["cop"][row] - com_rest)
            big = np.isfinite(excursion) & (excursion > 1e-4)
            ratio = max(ratio, float((pitch[big] / excursion[big]).max(initial=0.0)))
            floor = max(floor, float(pitch[np.isfinite(excursion) & ~big].max(initial=0.0)))
    return dict(
        scenarios=int(f.size),
        certified=int(pick.size),
        band_use_angle=angle_use,
        band_use_rate=rate_use,
        V_growth=growth,
        pitch_per_cop=ratio,
        pitch_near_rest=floor,
    )


if __name__ == "__main__":
    import json

    print(json.dumps(measure(), indent=1))
