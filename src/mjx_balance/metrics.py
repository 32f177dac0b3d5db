"""Measurements of one closed-loop run (SPEC §4–5), numpy.

Names shared with the batched rollout: ``OUTCOMES`` (index = the integer outcome code used in
JAX) and ``SUMMARY_COLUMNS`` (the per-scenario summary row, in table order).
"""

from __future__ import annotations

OUTCOMES = ("recovered", "not_settled", "fell", "diverged")

SUMMARY_COLUMNS = [
    "force", "duration", "convention", "outcome", "settle_time", "fall_time",
    "peak_ankle", "peak_hip", "peak_foot_pitch",
    "cop_min", "cop_max", "com_min", "com_max",
    "peak_tau_ankle", "peak_tau_hip",
    "ankle_saturation_fraction", "hip_saturation_fraction",
    "energy_ankle", "energy_hip", "energy_total", "work_ankle", "work_hip",
    "energy_u1", "energy_u2",
    "nonconverged_solves", "max_residual", "max_bound_violation",
]
