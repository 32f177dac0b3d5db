"""Which strategy a recovered body uses: the hip's share of the motors' work.

The index of a run is ``hip_share = energy_hip / energy_total``: the hip motor's absolute work
over both motors' (``energy_*``: the integral of |tau q_dot| of each joint motor, docs/model.md).
Why this index and not the joints' excursions: in this model the hip joint bends about as much
as the ankle even after the smallest push (the closed loop's linear mode keeps the upper body
near vertical while the lower body tilts, so |q_hip| ~ |q_ankle|), so an angle ratio sits near
0.5 everywhere and says little; the work says which motor does the recovering. It is the same
number in both conventions (motor torques and joint rates), and it needs nothing the summary row
does not already hold, so a sweep computes it for the whole plane.

What its distribution shows (docs/beyond.md, "The strategy map"): in the linear regime (no
bound active, short pushes) the share is a property of the controller, 0.13-0.15 for the study's
MPC at every force: the mode of the distribution. It rises from there continuously, with the
ankle's torque bound saturating (short strong pushes, up to 0.66) and with the length of a push
(a small push held for 2 s: 0.33), so there is no gap to put a threshold in.
``HIP_SHARE_THRESHOLD`` = 0.25 is about twice the linear-regime share: every cell of the mode is
an ankle recovery, and the hip counts as joining in when it does twice its linear share of the
work. The take-over line it draws moves little between 0.2 and 0.3 above 20 N; the report draws
how the map moves with the threshold (``figures.strategy.threshold_figure``).

``strategy`` is ``ankle`` or ``hip_ankle`` for recovered runs and empty for the others (a run
that fell or did not settle has no recovery strategy). A run whose motors did almost no work
(``ENERGY_FLOOR``: F = 0, where the work is solver noise of a few 1e-7 J) has no share (NaN)
and counts as ``ankle``: the body did not move.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .outcomes import OUTCOMES, RECOVERED

HIP_SHARE_THRESHOLD = 0.25
ENERGY_FLOOR = 1e-4  # J: below it the motors did not recover anything (no push)
STRATEGIES = ("ankle", "hip_ankle")
STRATEGY_COLUMNS = ["hip_share", "strategy"]


def hip_share(frame: pd.DataFrame) -> np.ndarray:
    """The hip motor's share of both motors' absolute work, per row (NaN below ENERGY_FLOOR or
    where the energies are missing)."""
    hip = frame["energy_hip"].to_numpy(float)
    total = frame["energy_total"].to_numpy(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > ENERGY_FLOOR, hip / total, np.nan)
    return share


def strategy_of(frame: pd.DataFrame, threshold: float = HIP_SHARE_THRESHOLD) -> np.ndarray:
    """``ankle`` / ``hip_ankle`` per recovered row (``hip_share`` above ``threshold``: the
    hip's), '' for the others."""
    if not 0.0 < threshold < 1.0:
        raise ValueError(f"threshold must lie in (0, 1), got {threshold!r}")
    share = frame["hip_share"].to_numpy(float) if "hip_share" in frame else hip_share(frame)
    recovered = (frame["outcome"] == OUTCOMES[RECOVERED]).to_numpy()
    hip = np.nan_to_num(share, nan=0.0) > threshold
    return np.where(recovered, np.where(hip, STRATEGIES[1], STRATEGIES[0]), "").astype(object)


def with_strategy(frame: pd.DataFrame, threshold: float = HIP_SHARE_THRESHOLD) -> pd.DataFrame:
    """``frame`` with the columns ``hip_share`` and ``strategy`` (computed from the summary
    columns; a frame that has them is returned as it is)."""
    if all(c in frame for c in STRATEGY_COLUMNS) or "energy_hip" not in frame:
        return frame
    frame = frame.copy()
    frame["hip_share"] = hip_share(frame)
    frame["strategy"] = strategy_of(frame, threshold).astype(str)
    return frame


def takeover(region: pd.DataFrame, threshold: float = HIP_SHARE_THRESHOLD) -> pd.DataFrame:
    """Where the hip takes over, per force of a region map: ``takeover`` = the shortest
    duration whose push recovers with the hip's share above ``threshold`` (NaN: every recovered
    duration of that force is an ankle recovery), ``recovered_max`` = the longest recovered
    duration (NaN: none), and ``share_at_max`` = the hip's share there. Forces ascending."""
    frame = region.drop(columns=[c for c in STRATEGY_COLUMNS if c in region])
    frame = frame.assign(hip_share=hip_share(frame))
    frame["strategy"] = strategy_of(frame, threshold)
    rows = []
    for force, group in frame.sort_values("duration").groupby("force", sort=True):
        rec = group[group["strategy"] != ""]
        hip = rec[rec["strategy"] == STRATEGIES[1]]
        rows.append(
            {
                "force": float(force),
                "takeover": float(hip["duration"].iloc[0]) if len(hip) else np.nan,
                "recovered_max": float(rec["duration"].iloc[-1]) if len(rec) else np.nan,
                "share_at_max": float(rec["hip_share"].iloc[-1]) if len(rec) else np.nan,
            }
        )
    return pd.DataFrame(rows, columns=["force", "takeover", "recovered_max", "share_at_max"])
