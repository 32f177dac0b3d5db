"""Studies beyond the source study: which variant changes the recoverable region, and by how much.

A study compares region maps (force x duration outcome grids, ``runs.region.run_sweep``) of a few
variants of one base configuration on one grid. Each variant other than the base is a sweep
definition shipped in ``mjx_balance/sweeps/`` (``study_*.toml``: configuration overrides + the
grid), loadable on its own by ``runs.definitions.load_sweep`` and runnable with ``mjx-balance sweep
--sweep NAME``; the base variant (``file=None``) is the base configuration on the same grid.

Numbers of a map (``region_numbers``):

area       the recovered part of the grid in the (F, T) plane [N s]: every recovered cell counts
           with its cell's area, cell edges half-way between grid values and the outer edges on
           the first and last grid value (so the full grid has area (F_max - F_min)(T_max - T_min))
fraction   area / full grid area
f_max_ref  the largest force that recovers at the reference duration (the grid duration closest
           to 0.1 s, the study's push), NaN if none does
rest_recovered  1 if every unpushed cell (F = 0) recovers, 0 if not (the loop does not even
           hold upright rest), NaN without F = 0 on the grid

The one-paragraph readings (``reading``) are written from these numbers, not from expectations.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..measures.outcomes import OUTCOMES, RECOVERED
from ..model.params import Config, ParameterError
from ..runs import SweepDefinition, load_sweep
from ..runs.definitions import sweeps_dir as _sweeps_dir

REFERENCE_DURATION = 0.1  # s, the study's push duration


@dataclass(frozen=True)
class Variant:
    key: str  # folder name of its saved sweep
    label: str
    file: str | None  # shipped sweep definition in mjx_balance/sweeps/ (None: the base)


@dataclass(frozen=True)
class Study:
    key: str
    title: str
    question: str  # what is varied, as one sentence (no results)
    variants: tuple[Variant, ...]  # the first is the baseline of the comparison
    signed: bool = False  # one signed-force map compared with itself (backward vs forward)


BASE = Variant("base", "base configuration", None)

STUDIES: tuple[Study, ...] = (
    Study(
        "ankle_only",
        "Ankle-only strategy vs ankle–hip",
        "The hip is held at zero by a stiff position servo in the plant (a passive "
        "spring-damper; stiffness and damping in study_ankle_only.toml) and the hip motor "
        "is off (torque bound zero), so the controller can use the ankle only; the base "
        "controller uses both joints.",
        (
            Variant("ankle_hip", "ankle–hip (base)", None),
            Variant("ankle_only", "ankle only (hip servo, hip motor off)", "study_ankle_only.toml"),
        ),
    ),
    Study(
        "backward",
        "Backward pushes (signed force)",
        "The push acts backward (F < 0) as well as forward; the state bounds are asymmetric "
        "(x1 in [-0.26, 0.5] rad, x2 in [-0.35, 1.4] rad by default).",
        (Variant("signed", "signed forces", "study_backward.toml"),),
        signed=True,
    ),
    Study(
        "delay",
        "Sensorimotor delay",
        "The controller sees the joint state 0, 10, 20, 50, 100 or 150 ms late; the plant "
        "keeps running (before the push it sees upright rest). At 50, 100 and 150 ms also "
        "a delay-compensated controller, which predicts the present state from the late "
        "measurement and the inputs it has applied since (docs/model.md).",
        (
            Variant("delay_000ms", "0 ms (base)", None),
            Variant("delay_010ms", "10 ms", "study_delay_010ms.toml"),
            Variant("delay_020ms", "20 ms", "study_delay_020ms.toml"),
            Variant("delay_050ms", "50 ms", "study_delay_050ms.toml"),
            Variant("delay_100ms", "100 ms", "study_delay_100ms.toml"),
            Variant("delay_150ms", "150 ms", "study_delay_150ms.toml"),
            Variant("delay_comp_050ms", "50 ms, compensated", "study_delay_comp_050ms.toml"),
            Variant("delay_comp_100ms", "100 ms, compensated", "study_delay_comp_100ms.toml"),
            Variant("delay_comp_150ms", "150 ms, compensated", "study_delay_comp_150ms.toml"),
        ),
    ),
    Study(
        "offset_free",
        "Offset-free MPC",
        "The controller estimates the push as a constant disturbance (an observer) and "
        "regulates to the steady posture that cancels it within every bound, leaning only "
        "when upright cannot hold it (docs/model.md); the base is the study's controller, "
        "which regulates to upright and does not know of the push.",
        (
            Variant("plain", "study's MPC (base)", None),
            Variant("offset_free", "offset-free MPC", "study_offset_free.toml"),
        ),
    ),
    Study(
        "older_adult",
        "Weaker ankle and an older-adult body",
        "The ankle torque bound is scaled by 0.6 (weaker ankle), and in the older-adult "
        "profile also the body (3 % shorter, 10 % heavier) and the hip torque bound (0.8).",
        (
            Variant("reference_body", "reference body (base)", None),
            Variant("weak_ankle", "weaker ankle (0.6 x bound)", "study_weak_ankle.toml"),
            Variant("older_adult", "older adult", "study_older_adult.toml"),
        ),
    ),
    Study(
        "recovery_definition",
        "What “recovered” means: the settle band",
        "The settle band that defines a recovery (every angle within 0.01 rad and every "
        "rate within 0.05 rad/s at t_end) is made ten times tighter and ten times looser; "
        "the window is the same. (Windows of 6, 12 and 24 s and the max acting times under "
        "each definition: docs/study.md.)",
        (
            Variant("band_base", "0.01 rad, 0.05 rad/s (base)", None),
            Variant(
                "band_tight",
                "ten times tighter (0.001 rad, 0.005 rad/s)",
                "study_settle_tight.toml",
            ),
            Variant(
                "band_loose", "ten times looser (0.1 rad, 0.5 rad/s)", "study_settle_loose.toml"
            ),
        ),
    ),
    Study(
        "controllers",
        "Controllers on one map: the MPC, LQR, PD and a learned policy",
        "The study's MPC is replaced by its peers of the controller interface (docs/model.md, "
        '"Bring your own controller"): an LQR of the same model and weights, saturated; a '
        "PD at each joint with gravity compensation; and an MLP policy fitted offline to "
        "imitate the MPC. The body, the push and the outcome rules are the same.",
        (
            Variant("mpc", "the study's MPC (base)", None),
            Variant("lqr", "LQR, saturated", "study_controller_lqr.toml"),
            Variant("pd", "PD with gravity compensation", "study_controller_pd.toml"),
            Variant("mlp", "MLP policy imitating the MPC", "study_controller_mlp.toml"),
        ),
    ),
    Study(
        "push_height",
        "Push height: upper-body CoM vs hip",
        "The same force acts at the hip joint instead of the upper body's centre of mass.",
        (
            Variant("upper_com", "at the upper-body CoM (base)", None),
            Variant("hip", "at the hip", "study_push_height.toml"),
        ),
    ),
)


def study(key: str) -> Study:
    """A study beyond the paper by its key.

    Args:
        key: ``ankle_only``, ``backward``, ``delay``, ``offset_free``, ``older_adult``,
            ``recovery_definition``, ``controllers`` or ``push_height``.

    Returns:
        The study (its question and its variants).

    Raises:
        ParameterError: an unknown key, listing the known ones.
    """
    for s in STUDIES:
        if s.key == key:
            return s
    raise ParameterError(f"unknown study {key!r}; known: {', '.join(s.key for s in STUDIES)}")


def sweeps_dir() -> Path:
    """The shipped sweep definitions (package data, ``runs.definitions.sweeps_dir``)."""
    return _sweeps_dir()


def study_files(sweeps: Path | None = None) -> list[Path]:
    """Every sweep definition a study uses."""
    sweeps = Path(sweeps) if sweeps is not None else sweeps_dir()
    return [sweeps / v.file for s in STUDIES for v in s.variants if v.file]


def variant_definition(
    st: Study, variant: Variant, base: Config, sweeps: Path | None = None
) -> SweepDefinition:
    """The variant's configuration and grid. The base variant takes the grid of the study's
    first sweep file; all files of a study must have one grid (checked)."""
    sweeps = Path(sweeps) if sweeps is not None else sweeps_dir()
    files = [v.file for v in st.variants if v.file]
    first = load_sweep(sweeps / files[0], base)
    for name in files[1:]:
        other = load_sweep(sweeps / name, base)
        if (str(other.forces), str(other.durations)) != (str(first.forces), str(first.durations)):
            raise ParameterError(f"study {st.key}: {name} has another grid than {files[0]}")
    if variant.file is None:
        return SweepDefinition(base, first.forces, first.durations)
    return load_sweep(sweeps / variant.file, base)


# ---------------------------------------------------------------------------------------------
# Numbers of a region map


def is_recovered(region: pd.DataFrame) -> pd.Series:
    """Which cells of a region map (or summary rows) recovered."""
    return region["outcome"] == OUTCOMES[RECOVERED]


def cell_widths(values: np.ndarray) -> np.ndarray:
    """Width of each grid value's cell: half-way to the neighbours, nothing beyond the ends."""
    values = np.sort(np.asarray(values, dtype=float))
    if values.size == 1:
        return np.ones(1)
    edges = np.concatenate([[values[0]], 0.5 * (values[1:] + values[:-1]), [values[-1]]])
    return np.diff(edges)


def region_numbers(region: pd.DataFrame) -> dict[str, float]:
    """A region's numbers.

    Args:
        region: A region map: region.parquet's rows (:func:`sweep`'s frame).

    Returns:
        ``area`` [N s], ``fraction``, ``recovered_cells``, ``cells``, the reference duration
        ``t_ref`` and ``f_max_ref`` [N] (the largest force recovered at it).
    """
    forces = np.sort(region["force"].unique())
    durations = np.sort(region["duration"].unique())
    wf = dict(zip(forces, cell_widths(forces)))
    wd = dict(zip(durations, cell_widths(durations)))
    ok = is_recovered(region).to_numpy()
    weight = region["force"].map(wf).to_numpy() * region["duration"].map(wd).to_numpy()
    total = float(sum(wf.values()) * sum(wd.values()))
    t_ref = float(durations[np.argmin(np.abs(durations - REFERENCE_DURATION))])
    at_ref = region[(region["duration"] == t_ref) & is_recovered(region)]
    rest = region[region["force"] == 0]
    return {
        "area": float(weight[ok].sum()),
        "fraction": float(weight[ok].sum() / total) if total > 0 else float(ok.mean()),
        "recovered_cells": int(ok.sum()),
        "cells": int(len(region)),
        "t_ref": t_ref,
        "f_max_ref": float(at_ref["force"].abs().max()) if len(at_ref) else float("nan"),
        # every F = 0 cell recovered (1), some not (0), no F = 0 on the grid (NaN)
        "rest_recovered": float(is_recovered(rest).all()) if len(rest) else float("nan"),
    }


def infeasibility_numbers(region: pd.DataFrame) -> dict[str, float]:
    """Falls and infeasible QPs: falls, falls preceded by a control period whose QP had no
    solution (``first_infeasible_time`` before ``fall_time``), and the lead of the first
    infeasible QP over the fall [s]: median, min and max over those falls (NaN if none).
    Regions written before the column existed give NaN counts."""
    fell = region[region["outcome"] == "fell"]
    if "first_infeasible_time" not in region:
        return {
            "falls": int(len(fell)),
            "preceded": float("nan"),
            "lead_median": float("nan"),
            "lead_min": float("nan"),
            "lead_max": float("nan"),
        }
    lead = (fell["fall_time"] - fell["first_infeasible_time"]).dropna().to_numpy()
    lead = lead[lead >= 0]
    pick = (lambda f: float(f(lead))) if lead.size else (lambda f: float("nan"))
    return {
        "falls": int(len(fell)),
        "preceded": int(lead.size),
        "lead_median": pick(np.median),
        "lead_min": pick(np.min),
        "lead_max": pick(np.max),
    }


def infeasibility_text(region: pd.DataFrame) -> str:
    """One sentence of :func:`infeasibility_numbers` for the report."""
    n = infeasibility_numbers(region)
    if n["falls"] == 0:
        return "No push on this grid fell."
    if not n["preceded"] == n["preceded"]:  # NaN: an older region without the column
        return f"{n['falls']} falls (this region predates the infeasible-QP column)."
    text = (
        f"{n['preceded']} of {n['falls']} falls came after a control period whose QP had "
        "no solution"
    )
    if n["preceded"]:
        text += (
            f", {n['lead_median'] * 1000:.0f} ms before the fall (median; "
            f"{n['lead_min'] * 1000:.0f}-{n['lead_max'] * 1000:.0f} ms)"
        )
    return text + (
        ". After an infeasible QP the fall depends on the solver's answer to it (docs/model.md)."
    )


def compare(regions: dict[str, pd.DataFrame], labels: dict[str, str]) -> pd.DataFrame:
    """One row per variant (in order): its numbers and the change against the first variant,
    plus cells recovered only by the variant / only by the baseline."""
    keys = list(regions)
    base = regions[keys[0]]
    base_numbers = region_numbers(base)
    base_ok = _recovered_cells(base)
    rows = []
    for key in keys:
        numbers = region_numbers(regions[key])
        ok = _recovered_cells(regions[key])
        rows.append(
            {
                "variant": key,
                "label": labels.get(key, key),
                **numbers,
                "area_change": numbers["area"] - base_numbers["area"],
                "relative_change": (
                    (numbers["area"] - base_numbers["area"]) / base_numbers["area"]
                    if base_numbers["area"] > 0
                    else float("nan")
                ),
                "gained_cells": len(ok - base_ok),
                "lost_cells": len(base_ok - ok),
            }
        )
    return pd.DataFrame(rows)


def signed_halves(region: pd.DataFrame) -> pd.DataFrame:
    """Backward (F <= 0) and forward (F >= 0) halves of a signed map, backward forces mirrored."""
    back = region[region["force"] <= 0].assign(force=lambda f: -f["force"])
    forward = region[region["force"] >= 0]
    rows = []
    for key, label, half in (
        ("backward", "backward (F < 0)", back),
        ("forward", "forward (F > 0)", forward),
    ):
        rows.append({"variant": key, "label": label, **region_numbers(half)})
    frame = pd.DataFrame(rows)
    frame["area_change"] = frame["area"] - frame["area"].iloc[1]
    both = set(map(tuple, back[is_recovered(back)][["force", "duration"]].to_numpy()))
    fwd = set(map(tuple, forward[is_recovered(forward)][["force", "duration"]].to_numpy()))
    frame["gained_cells"] = [len(both - fwd), 0]
    frame["lost_cells"] = [len(fwd - both), 0]
    return frame


def _recovered_cells(region: pd.DataFrame) -> set[tuple[float, float]]:
    ok = region[is_recovered(region)]
    return set(zip(ok["force"].round(9), ok["duration"].round(9)))


# ---------------------------------------------------------------------------------------------
# Readings


def grid_text(region: pd.DataFrame) -> str:
    """The grid of a region map in words: how many forces and durations, and their ranges."""
    f, d = region["force"], region["duration"]
    return (
        f"{f.nunique()} forces ({f.min():g} to {f.max():g} N) x {d.nunique()} durations "
        f"({d.min():g} to {d.max():g} s)"
    )


def force_text(value: float) -> str:
    """A largest recovered force in words (f_max_ref: NaN when no force recovers)."""
    if not np.isfinite(value):
        return "no force"
    return "F = 0 only (no push)" if value == 0 else f"{value:g} N"


def _change_text(change: float, relative: float, scale: float) -> str:
    if abs(change) <= 1e-9 * max(scale, 1.0):
        return "unchanged"
    word = "larger" if change > 0 else "smaller"
    rel = f", {relative:+.0%}" if np.isfinite(relative) else ""
    return f"{abs(change):.3g} N·s {word} ({change:+.3g} N·s{rel})"


def reading(st: Study, numbers: pd.DataFrame, region: pd.DataFrame) -> str:
    """One paragraph on a study's maps, written from their numbers.

    Args:
        st: The study (:func:`study`).
        numbers: Its variants' numbers (``compare``/``signed_halves``).
        region: The base variant's region map, when the reading needs it (None: not used).

    Returns:
        The paragraph.
    """
    rows = numbers.to_dict("records")
    grid = grid_text(region)
    t_ref = rows[0]["t_ref"]
    if st.signed:
        back, fwd = rows
        ratio = back["area"] / fwd["area"] if fwd["area"] > 0 else float("nan")
        return (
            f"On {grid}, backward pushes recover {back['area']:.3g} N·s "
            f"({back['recovered_cells']} cells) against {fwd['area']:.3g} N·s "
            f"({fwd['recovered_cells']} cells) forward"
            + (f", {ratio:.2f} times the forward area" if np.isfinite(ratio) else "")
            + f". At T = {t_ref:g} s the largest backward force that recovers is "
            f"{force_text(back['f_max_ref'])}, forward {force_text(fwd['f_max_ref'])}. "
            f"Mirrored cell by cell, {back['gained_cells']} (|F|, T) cells recover only backward "
            f"and {back['lost_cells']} only forward."
        )
    base = rows[0]
    name = base["label"].replace(" (base)", "")
    text = (
        f"On {grid}, the base variant ({name}) recovers {base['area']:.3g} N·s "
        f"({base['fraction']:.0%} of the grid, {base['recovered_cells']} of {base['cells']} "
        f"cells; at T = {t_ref:g} s up to {force_text(base['f_max_ref'])})."
    )
    if base.get("rest_recovered") == 0:
        text += " Even the unpushed base (F = 0) does not stay upright."
    for row in rows[1:]:
        text += (
            f" {row['label'][0].upper() + row['label'][1:]}: {row['area']:.3g} N·s, "
            f"{_change_text(row['area_change'], row['relative_change'], base['area'])}; "
            f"at T = {t_ref:g} s up to {force_text(row['f_max_ref'])}; "
            f"{row['gained_cells']} cells gained, {row['lost_cells']} lost"
            + (
                "; even F = 0 fails: this loop does not hold upright rest"
                if row.get("rest_recovered") == 0
                else ""
            )
            + "."
        )
    unstable = [r["label"] for r in rows[1:] if r.get("rest_recovered") == 0]
    stable = [r["label"] for r in rows[1:] if r.get("rest_recovered") == 1]
    if unstable and stable:
        text += f" Upright rest holds with {', '.join(stable)} but not with {', '.join(unstable)}."
    if st.key == "ankle_only" and len(rows) == 2:
        added = base["area"] - rows[1]["area"]
        text += f" The hip adds {added:+.3g} N·s to the ankle-only region."
    if st.key == "delay" and base["area"] > 0:
        # each compensated map against the plain one at the same delay (delay_comp_050ms and
        # delay_050ms), as fractions of the undelayed area
        by_key = {r["variant"]: r for r in rows}
        pairs = [
            (r, by_key.get(r["variant"].replace("_comp_", "_")))
            for r in rows
            if "_comp_" in str(r["variant"])
        ]
        if pairs:
            text += (
                " As a fraction of the undelayed area, the delay-compensated controller "
                "keeps "
                + ", ".join(
                    f"{c['area'] / base['area']:.0%} at {c['label'].split(',')[0]}"
                    + (
                        f" (without compensation {p['area'] / base['area']:.0%})"
                        if p is not None
                        else ""
                    )
                    for c, p in pairs
                )
                + "."
            )
    return text
