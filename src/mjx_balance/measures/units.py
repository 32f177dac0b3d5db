"""The unit of every column the product writes, in one place.

``UNITS`` maps a column name to ``(unit, meaning)``. Units are SI strings: ``s``, ``N``, ``J``,
``m``, ``m/s``, ``rad``, ``rad/s``, ``N m``, ``N s``, ``ms``, ``kg``; ``1`` for a dimensionless
number (a ratio, a fraction, a count, a 1/0 flag stored as a number); ``""`` for a label, a
text or a True/False flag. Columns whose names carry a value (``max_acting_time_50N``, sensitivity's
``energy_study_paper_plain``) match :data:`PATTERNS`.

The writers (``store.files.write_parquet`` / ``write_csv``) put these units in the parquet
schema's field metadata and in a CSV's ``NAME.units.csv`` sidecar; ``tests/store/test_exports.py``
checks that every column of every table the commands write has an entry here and that
docs/outputs.md's units table lists the same units.
"""

from __future__ import annotations

import re
from typing import Iterable

_STUDY_EQ20 = "the study's energy (its eq. 20)"
_MOTORS = "the motors' absolute work"

UNITS: dict[str, tuple[str, str]] = {
    # --- the scenario summary (outcomes.SUMMARY_COLUMNS) and its derived columns
    "force": ("N", "push force, + forward"),
    "duration": ("s", "push duration (a whole number of physics steps)"),
    "convention": ("", "the controller's coordinates: paper or joint"),
    "outcome": ("", "recovered, not_settled, fell or diverged"),
    "settle_time": ("s", "time of the last sample outside the settle band (recovered runs)"),
    "fall_time": ("s", "time of the fall sample (fallen runs)"),
    "peak_ankle": ("rad", "largest |ankle joint angle|"),
    "peak_hip": ("rad", "largest |hip joint angle|"),
    "peak_foot_pitch": ("rad", "largest |foot pitch|"),
    "cop_min": ("m", "smallest load-cell centre of pressure x"),
    "cop_max": ("m", "largest load-cell centre of pressure x"),
    "com_min": ("m", "smallest whole-body centre of mass x"),
    "com_max": ("m", "largest whole-body centre of mass x"),
    "peak_tau_ankle": ("N m", "largest |ankle motor torque|"),
    "peak_tau_hip": ("N m", "largest |hip motor torque|"),
    "ankle_saturation_fraction": ("1", "fraction of control periods with u1 at a bound"),
    "hip_saturation_fraction": ("1", "fraction of control periods with u2 at a bound"),
    "energy_ankle": ("J", "sum |tau_ankle dq_a|"),
    "energy_hip": ("J", "sum |tau_hip dq_h|"),
    "energy_total": ("J", "energy_ankle + energy_hip"),
    "work_ankle": ("J", "sum tau_ankle dq_a (signed net work)"),
    "work_hip": ("J", "sum tau_hip dq_h (signed net work)"),
    "energy_u1": ("J", "sum |u1 dx1| in the convention's coordinates"),
    "energy_u2": ("J", "sum |u2 dx2| in the convention's coordinates"),
    "work_u1": ("J", "sum u1 dx1, signed"),
    "work_u2": ("J", "sum u2 dx2, signed"),
    "study_energy_u1": ("J", f"{_STUDY_EQ20} of the first pair, |sum u1 dx1|"),
    "study_energy_u2": ("J", f"{_STUDY_EQ20} of the second pair, |sum u2 dx2|"),
    "study_energy_total": ("J", "study_energy_u1 + study_energy_u2"),
    "nonconverged_solves": ("1", "count of QP solves not reported solved"),
    "max_residual": (
        "mixed",
        "largest primal residual of those solves, in the constraint "
        "rows' own units (rad, rad/s or N m)",
    ),
    "max_bound_violation": ("rad", "largest excess of a position state beyond its bound"),
    "fall_cause": (
        "",
        "the fall rule that fired (foot_pitch, heel_lift, toe_lift, "
        "state_bound, lower_tilt, non_finite), empty otherwise",
    ),
    "first_infeasible_time": ("s", "control instant of the first QP without a solution"),
    "com_vel_min": ("m/s", "smallest whole-body CoM x velocity"),
    "com_vel_max": ("m/s", "largest whole-body CoM x velocity"),
    "mos_min": ("m", "smallest margin of stability in the push's direction (Hof et al. 2005)"),
    "mos_min_time": ("s", "time of the first sample with the smallest margin"),
    "steps_needed": (
        "1",
        "fewest steps that capture the body from the decision instant (capturability): 0 "
        "without a fall, "
        "1 or 2, inf where two do not; NaN if diverged",
    ),
    "capture_margin": (
        "m",
        "one-step capture margin of the capture point at the decision instant (>= 0: one "
        "step captures); NaN without a fall",
    ),
    "decision_time": (
        "s",
        "decision instant of a fall: the first sample the feet in place cannot hold "
        "(capturability), else the fall sample; NaN without a fall",
    ),
    "hip_share": ("1", "energy_hip / energy_total"),
    "strategy": ("", "ankle or hip_ankle for a recovered run, empty otherwise"),
    # --- the time series (reference.loop.TIMESERIES_COLUMNS)
    "scenario": ("1", "scenario index (order of the runs in the file)"),
    "time": ("s", "sample time after push onset"),
    "q_a": ("rad", "ankle joint angle"),
    "q_h": ("rad", "hip joint angle"),
    "dq_a": ("rad/s", "ankle joint rate"),
    "dq_h": ("rad/s", "hip joint rate"),
    "x1": ("rad", "convention state 1 (paper: q1; joint: q_a)"),
    "x2": ("rad", "convention state 2 (paper: q2 = q_a + q_h; joint: q_h)"),
    "x3": ("rad/s", "rate of x1"),
    "x4": ("rad/s", "rate of x2"),
    "foot_x": ("m", "foot's horizontal displacement"),
    "foot_z": ("m", "foot's vertical displacement"),
    "foot_pitch": ("rad", "foot's pitch"),
    "u1": ("N m", "the controller's first input (tau1 or tau_ankle)"),
    "u2": ("N m", "the controller's second input (tau2 or tau_hip)"),
    "tau_ankle": ("N m", "ankle motor torque"),
    "tau_hip": ("N m", "hip motor torque"),
    "cop": ("m", "load-cell centre of pressure x"),
    "com": ("m", "whole-body centre of mass x"),
    "com_vel": ("m/s", "whole-body CoM x velocity"),
    "xcom": ("m", "extrapolated CoM x: com + com_vel / omega0"),
    "mos": ("m", "margin of stability in the push's direction"),
    # --- table.csv (runs.acting_time.TABLE_COLUMNS)
    "max_acting_time": ("s", "longest push of that force that recovers"),
    "ending_outcome": ("", "outcome of the shortest failing duration"),
    "monotone": ("", "False when a recovered duration lies beyond the first failure"),
    "recovered_beyond_failure": ("s", "the largest such recovered duration"),
    "outcome_01": ("", "outcome of the 0.1-s push"),
    "settle_time_01": ("s", "settle time of the 0.1-s push"),
    "settle_time_max": ("s", "settle time of the push at the max acting time"),
    "evaluations": ("1", "count of scenarios evaluated for this force"),
    "note": ("", "free text"),
    "sustained_push_limit": ("N", "largest force the body holds for the whole window"),
    "max_acting_time_one_step": (
        "s",
        "largest T such that every push up to it recovers in place or with one step "
        "(capturability)",
    ),
    # --- compare.csv and landscape.csv (studies.catalog.region_numbers and the study's own)
    "name": ("", "the configuration's name"),
    "t_end": ("s", "the scenario's window"),
    "area": ("N s", "recovered area of the force x duration grid"),
    "fraction": ("1", "area / the whole grid's area"),
    "recovered_cells": ("1", "count of recovered cells"),
    "cells": ("1", "count of cells"),
    "t_ref": ("s", "the grid duration closest to 0.1 s"),
    "f_max_ref": ("N", "largest force recovering at t_ref"),
    "rest_recovered": ("1", "1 if every unpushed cell recovers, 0 if not, NaN without one"),
    "mean_recovery_energy": ("J", "mean energy_total of the recovered cells"),
    "controller": ("", "the controller's kind (controller.kind: mpc, lqr, pd, module:factory)"),
    "mean_settle_time": ("s", "mean settle_time of the recovered cells"),
    "delay": ("", "the delay setting (e.g. 100c)"),
    "delay_ms": ("ms", "the controller delay"),
    "compensated": ("", "True for the delay-compensated controller"),
    "q_scale": ("1", "factor on controller.q_diag"),
    "r_scale": ("1", "factor on controller.r_diag"),
    "study": ("", "True for the base weights (1, 1)"),
    "paired_cells": ("1", "count of cells this setting and the base weights both recover"),
    "energy_vs_study": ("1", "mean energy_total over the paired cells / the base's"),
    # --- cohort.csv and cohort_summary.csv (studies.cohort): a subject's body, the statistic
    "id": ("", "the subject's id (its folder in subjects/)"),
    "height": ("m", "the subject's stature"),
    "mass": ("kg", "the subject's body mass"),
    "sex": ("", "male or female (de Leva's table)"),
    "ankle_strength": ("1", "factor on the mass-scaled ankle torque bound"),
    "hip_strength": ("1", "factor on the mass-scaled hip torque bound"),
    "age": ("yr", "the subject's age (strength and timing by age and sex; empty: none given)"),
    "statistic": ("", "mean, sd (n - 1), p5, p50 or p95 over the subjects"),
    # --- cohort_probability.csv and cohort_probability_boundaries.csv (studies.probability)
    "subjects": ("1", "count of subjects whose map holds the cell"),
    "recovered_subjects": ("1", "count of those subjects that recover at the cell"),
    "p_recover": ("1", "P(recover | F, T): recovered_subjects / subjects"),
    "p_low": ("1", "lower bound of P's 95 % Wilson interval"),
    "p_high": ("1", "upper bound of P's 95 % Wilson interval"),
    "one_step_subjects": (
        "1",
        "count of the subjects that recover there in place or with one step (steps_needed <= 1)",
    ),
    "p_one_step": (
        "1",
        "P(recover in place or with one step | F, T): one_step_subjects / subjects",
    ),
    "p_one_step_low": ("1", "lower bound of p_one_step's 95 % Wilson interval"),
    "p_one_step_high": ("1", "upper bound of p_one_step's 95 % Wilson interval"),
    "boundary_p95": ("s", "longest grid duration up to which P(recover) >= 0.95 at every one"),
    "boundary_p50": ("s", "longest grid duration up to which P(recover) >= 0.5 at every one"),
    "boundary_p5": ("s", "longest grid duration up to which P(recover) >= 0.05 at every one"),
    "boundary_base": ("s", "the base configuration's body's recovery boundary on the grid"),
    # --- basin.parquet and pushes.csv (studies.basin)
    "cell": ("1", "cell index"),
    "x_com": ("m", "CoM x relative to the ankle"),
    "v_com": ("m/s", "CoM x velocity"),
    "periods": ("1", "count of control periods simulated"),
    "certified": ("", "True when the recovery certificate ended the run early"),
    "q_a0": ("rad", "initial ankle joint angle"),
    "q_h0": ("rad", "initial hip joint angle"),
    "dq_a0": ("rad/s", "initial ankle joint rate"),
    "dq_h0": ("rad/s", "initial hip joint rate"),
    "capture_inside": ("", "True when the capture point x_com + v_com / omega0 lies on the foot"),
    # --- scorecard.csv (studies.scorecard.SCORECARD_COLUMNS): values in the row's unit
    "source": ("", "the reference file's label"),
    "measure": ("", "which value is compared"),
    "unit": ("", "the unit of the row's values"),
    "reference": ("(unit column)", "the reference's value, in the row's unit"),
    "ours": ("(unit column)", "our value, in the row's unit"),
    # --- lean and release (mjx-balance lean: lean.csv, lean_limits.csv)
    "published_mean": ("(unit column)", "the paper's mean, as printed, in the row's unit"),
    "published_sd": ("(unit column)", "the paper's standard deviation, as printed"),
    "agrees": ("", "ours within the published mean +- 2 SD"),
    "static_deg": ("deg", "largest rigid lean held still: the smaller of the two below"),
    "static_torque_deg": ("deg", "lean whose gravity torques leave the input bounds"),
    "static_foot_deg": ("deg", "lean at which the CoM leaves the toe"),
    "dynamic_deg": ("deg", "largest lean released from rest that recovers (every smaller too)"),
    "one_step_deg": (
        "deg",
        "largest lean released from rest that recovers in place or with one step (every smaller "
        "too; capturability)",
    ),
    "resolution_deg": ("deg", "width of the dynamic limit's final bracket"),
    "peak_ankle_torque": ("N m", "largest |ankle motor torque| of the run at the dynamic limit"),
    "scenarios": ("1", "batched scenarios run"),
    # --- the waist pull (mb.waist_pull; people_limits.csv's pull rows)
    "ramp_s": ("s", "the pull's rise time before it is held (0: applied at once)"),
    "forward_n": ("N", "largest forward pull at the hip held for the whole window"),
    "forward_pct": ("%", "forward_n as a percentage of body weight"),
    "backward_n": ("N", "largest backward pull at the hip held for the whole window"),
    "backward_pct": ("%", "backward_n as a percentage of body weight"),
    "resolution_n": ("N", "width of the wider of the two limits' final brackets"),
    "weight_n": ("N", "body weight: total mass x g"),
    "peak_ankle_torque_forward": ("N m", "largest |ankle motor torque| at the forward limit"),
    "peak_ankle_torque_backward": ("N m", "largest |ankle motor torque| at the backward limit"),
    # --- the people scorecard (mjx-balance people: people.csv, people_limits.csv)
    "population": ("", "who was measured, as the paper says"),
    "kind": ("", "predicted, input (taken from this row) or not modelled"),
    "body": ("", "the shipped human body that predicts the row (human, human_older)"),
    "settings": ("", "the protocol and output that predict the row"),
    "protocol": ("", "lean (lean and release) or pull (the held waist pull)"),
    "value": ("(measure column)", "the limit's value, in the unit of that measure"),
    "our_uncertainty": ("(unit column)", "our value's uncertainty, in the row's unit"),
    "abs_diff": ("(unit column)", "ours - reference, in the row's unit"),
    "rel_diff": ("1", "abs_diff / |reference|"),
    "tolerance": ("(unit column)", "the tolerance, in the row's unit"),
    "tolerance_basis": ("", "how the tolerance was derived"),
    "within": ("", "True when |abs_diff| <= tolerance"),
    "status": ("", "agrees, differs, not comparable, not computed or uncertain"),
    "reason": ("", "why the row differs, from the reference file"),
    "citation": ("", "the reference's source"),
    # --- the report's weight sweeps (studies.experiments)
    "weight": ("", "which weight is scaled"),
    "scale": ("1", "the factor on that weight"),
    # --- sensitivity.csv's spread across readings (studies.sensitivity)
    "max_acting_time_min": ("s", "smallest max acting time over the readings"),
    "max_acting_time_max": ("s", "largest max acting time over the readings"),
    "max_acting_time_ratio": ("1", "max / min of the max acting time over the readings"),
}

_ENERGIES = (
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "energy_u1",
    "energy_u2",
    "study_energy_u1",
    "study_energy_u2",
    "study_energy_total",
)
for _name in _ENERGIES:  # table.csv: the 0.1-s push and the push at the max acting time
    UNITS[f"{_name}_01"] = ("J", f"{_name} of the 0.1-s push if it recovered")
    UNITS[f"{_name}_max"] = ("J", f"{_name} of the push at the max acting time")
del _name

# Columns whose names carry a value: (pattern, unit, meaning); the first match wins.
PATTERNS: list[tuple[re.Pattern[str], str, str]] = [
    (
        re.compile(r"max_acting_time_-?[0-9.e+-]+N"),
        "s",
        "max acting time at the force the name gives (N)",
    ),
    (
        re.compile(r"energy_(study|motors)(_01)?_(min|max)"),
        "J",
        "smallest / largest energy over the sensitivity readings",
    ),
    (
        re.compile(r"energy_study(_01)?_[a-z_]+"),
        "J",
        f"{_STUDY_EQ20} in the reading the name gives",
    ),
    (re.compile(r"energy_motors(_01)?_[a-z_]+"), "J", f"{_MOTORS} in the reading the name gives"),
    (re.compile(r"max_acting_time_[a-z_]+"), "s", "max acting time in the reading the name gives"),
]


def describe(column: str) -> tuple[str, str] | None:
    """``(unit, meaning)`` of a column, or None when the registry does not know it."""
    if column in UNITS:
        return UNITS[column]
    for pattern, unit, meaning in PATTERNS:
        if pattern.fullmatch(column):
            return unit, meaning
    return None


def unit(column: str) -> str:
    """The unit of a column (module docstring); KeyError naming a column the registry lacks."""
    found = describe(column)
    if found is None:
        raise KeyError(f"no unit recorded for column {column!r} (measures/units.py)")
    return found[0]


def unknown(columns: Iterable[str]) -> list[str]:
    """The columns the registry has no unit for, in order."""
    return [str(c) for c in columns if describe(str(c)) is None]
