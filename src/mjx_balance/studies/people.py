"""The people scorecard: every measure of the people reference (``data/references/people.csv``)
beside what the shipped human bodies predict (docs/people.md, "People").

Two bodies, each a shipped configuration whose every number is a cited measurement
(``sweeps/human.toml``, a young man; ``sweeps/human_older.toml``, an older man; docs/model.md,
"Human bodies"), each run through the protocols on the batched engine: lean and release
(``studies.lean``, with the ankle strategy alone, as that experiment asked) and the held waist
pull (``studies.pull``, loaded gradually as a spring-scale test, and at once); and two women
(:data:`WOMEN`: the young man's body as a young and an older woman, ``model.ageing``) through
lean and release, for the women's single-step rows.

Each reference row is one of three kinds (:data:`ROWS`):

- ``predicted``: a protocol's output, held against the published mean +- 2 SD (``agrees``);
- ``input``: a number the body takes from that very row (the onset latency, the rate of torque
  development): shown so the reader sees what went in, never counted as agreement;
- ``not modelled``: a protocol the tool does not have yet (a moving platform).

Every predicted row that does not agree, and every row not modelled, carries the reason found
by measurement (people.csv's ``reason`` column, written from docs/people.md's tables).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import pandas as pd

from ..figures.people import plot_people
from ..model.config_files import load_config
from ..model.params import Config
from ..model.subject import Subject
from ..runs.chunks import PlanHook, PlannedWork
from ..runs.definitions import find_sweep
from ..store.files import write_csv
from .lean import LeanLimits, check_resolution, lean_limits, planned_scenarios
from .pull import RAMP, PullLimits, check_pull_resolution, planned_pulls, pull_limits
from .references import read_people
from .thresholds import agreement, protocol_folder

BODIES = ("human", "human_older")  # shipped configurations (sweeps/), young and older
# Women's bodies for the single-step rows of Wojcik et al. 1999 (young women mean 25.0 yr, older
# women 73.7 yr; their statures and masses are not in the abstract: de Leva's reference woman,
# 1.735 m and 61.9 kg): the young man's body as a woman of that age (model.ageing: strength and
# timing by age and sex, each from a cited measurement). Lean and release only.
WOMEN = {
    "human_women": Subject(1.735, 61.9, "female", age=25.0),
    "human_older_women": Subject(1.735, 61.9, "female", age=73.7),
}


@dataclass(frozen=True)
class Row:
    """How the scorecard gets our value for one reference row."""

    kind: str  # "predicted", "input" or "not modelled"
    body: str = ""  # the shipped body that predicts it (BODIES)
    value: str = ""  # "lean.<LeanLimits field>", "pull.<PullLimits field>", or an input's name
    settings: str = ""  # the command that predicts it, in words


LEAN = "mjx-balance lean --config {body}"
PULL = "mjx_balance.waist_pull: the pull at the hip rising over 5 s, then held, {body}"
ONE_STEP = LEAN + " (one step: capturability from the feet-in-place runs)"
ONE_STEP_WOMAN = (
    "mjx-balance lean --config human --subject {subject} (one step: capturability from the "
    "feet-in-place runs)"
)
ROWS: dict[str, Row] = {
    "lean_release_static_recovery_limit_young": Row(
        "predicted", "human", "lean.static_deg", LEAN + " (static limit)"
    ),
    "lean_release_max_angle_young": Row(
        "predicted", "human", "lean.dynamic_deg", LEAN + " (dynamic limit)"
    ),
    "lean_release_peak_ankle_torque_young": Row(
        "predicted", "human", "lean.peak_ankle_torque", LEAN + " (peak ankle torque)"
    ),
    "lean_release_torque_onset_latency_young": Row(
        "input", "human", "delay_ms", "scenario.controller_delay of {body}"
    ),
    "lean_release_ankle_rtd_young": Row(
        "input", "human", "ankle_rate", "controller.input_rates[0] of {body}"
    ),
    "lean_release_single_step_max_angle_young_men": Row(
        "predicted", "human", "lean.one_step_deg", ONE_STEP
    ),
    "lean_release_single_step_max_angle_older_men": Row(
        "predicted", "human_older", "lean.one_step_deg", ONE_STEP
    ),
    "lean_release_single_step_max_angle_young_women": Row(
        "predicted", "human_women", "lean.one_step_deg", ONE_STEP_WOMAN
    ),
    "lean_release_single_step_max_angle_older_women": Row(
        "predicted", "human_older_women", "lean.one_step_deg", ONE_STEP_WOMAN
    ),
    "waist_pull_step_threshold_older_fallers": Row(
        "predicted", "human_older", "pull.forward_pct", PULL + " (forward)"
    ),
    "waist_pull_step_threshold_older_nonfallers": Row(
        "predicted", "human_older", "pull.forward_pct", PULL + " (forward)"
    ),
    "platform_translation_max_no_step_young": Row(
        "not modelled", settings="a support-surface translation"
    ),
    "platform_translation_max_no_step_older": Row(
        "not modelled", settings="a support-surface translation"
    ),
}
KINDS = ("predicted", "input", "not modelled")


@dataclass(frozen=True)
class BodyResults:
    """One body's protocol outputs."""

    config: Config
    lean: LeanLimits
    pull: PullLimits | None  # the pull loaded gradually (pull.RAMP), as a spring-scale test
    pull_step: PullLimits | None  # the pull applied at once and held (the sustained push's)

    def value(self, name: str) -> float:
        """``lean.<field>``, ``pull.<field>`` or an input (``delay_ms``, ``ankle_rate``)."""
        if name == "delay_ms":
            return 1000 * self.config.scenario.controller_delay
        if name == "ankle_rate":
            rates = self.config.controller.input_rates
            return float("nan") if rates is None else float(rates[0])
        protocol, field = name.split(".")
        return float(getattr(getattr(self, protocol), field))

    def rows(self, body: str) -> list[dict]:
        """The limits as people_limits.csv rows (body, protocol, measure, value)."""
        out = []
        for protocol in ("lean", "pull", "pull_step"):
            limits = getattr(self, protocol)
            if limits is None:  # not run on this body
                continue
            for measure, value in limits.row().items():
                out.append({"body": body, "protocol": protocol, "measure": measure, "value": value})
        return out


def human_config(name: str) -> Config:
    """The shipped human body ``name`` (BODIES) or a woman's (WOMEN: on the young man's)."""
    if name in WOMEN:
        return WOMEN[name].config(load_config(find_sweep(BODIES[0])))
    return load_config(find_sweep(name))


# The ankle strategy alone (the lean-and-release experiment's instruction): the hip held by a
# stiff servo in the plant and the hip motor off, as sweeps/study_ankle_only.toml: K = 2e4
# N m/rad (that file derives it), D critically damping the upper body about the hip.
HIP_SERVO_STIFFNESS = 2e4  # N m/rad


def ankle_strategy(config: Config) -> Config:
    """``config`` with the hip held by a servo and its motor off: D = 2 sqrt((K - m2 g c2) I_h),
    I_h = I2 + m2 c2^2, the upper body's inertia about the hip (580 N m s/rad for the study's
    body, as study_ankle_only.toml)."""
    b = config.body
    upper_about_hip = b.upper_pitch_inertia + b.upper_mass * b.upper_com**2
    stiffness = HIP_SERVO_STIFFNESS - b.upper_mass * b.gravity * b.upper_com
    damping = 2 * math.sqrt(stiffness * upper_about_hip)
    return config.replace(
        body={"hip_servo_stiffness": HIP_SERVO_STIFFNESS, "hip_servo_damping": damping},
        controller={"input2_bounds": [0.0, 0.0]},
    )


def body_results(
    config: Config,
    *,
    lean_resolution: float = 0.05,
    pull_resolution: float = 0.5,
    slots: int | None = None,
    say: Callable[[str], None] | None = None,
    pull: bool = True,
) -> BodyResults:
    """Lean and release with the ankle strategy alone (:func:`ankle_strategy`, as the
    experiment asked) and, with ``pull``, the held waist pull of ``config`` (ankle and hip),
    each on the batched engine."""
    ankle = ankle_strategy(config)
    lean = lean_limits(ankle, resolution=lean_resolution, slots=slots, say=say)
    pulls = [
        pull_limits(config, resolution=pull_resolution, ramp=ramp, slots=slots, say=say)
        if pull
        else None
        for ramp in (RAMP, 0.0)
    ]
    return BodyResults(config, lean, *pulls)


def scorecard(results: dict[str, BodyResults], people: pd.DataFrame | None = None) -> pd.DataFrame:
    """Every people row beside our value (:data:`ROWS`): kind, body, settings, ours, agrees (a
    predicted row within the published mean +- 2 SD; otherwise empty) and the row's reason when
    it is not a predicted agreement."""
    people = read_people() if people is None else people
    out = []
    for _, ref in people.iterrows():
        row = ROWS[ref["measure"]]
        ours = results[row.body].value(row.value) if row.body else math.nan
        scored = agreement(ref["measure"], ours, people)
        agrees = scored["agrees"] if row.kind == "predicted" else None
        out.append(
            {
                "measure": ref["measure"],
                "population": ref["population"],
                "kind": row.kind,
                "body": row.body,
                "settings": row.settings.format(
                    body=row.body,
                    subject=WOMEN[row.body].describe() if row.body in WOMEN else "",
                ),
                "unit": ref["unit"],
                "published_mean": ref["mean"],
                "published_sd": ref["sd"],
                "ours": ours,
                "agrees": agrees,
                "reason": "" if agrees else _text(ref.get("reason", "")),
                "source": ref["source"],
            }
        )
    return pd.DataFrame(out)


def _text(value: object) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else str(value)


PEOPLE_CSV = "people.csv"  # the scorecard: every people row beside ours
PEOPLE_LIMITS_CSV = "people_limits.csv"  # every limit of every body
PEOPLE_FIGURE = "people.png"  # people.png: the predicted rows against the published ranges


def planned_people(
    configs: dict[str, Config], lean_resolution: float, pull_resolution: float
) -> int:
    """The most scenarios :func:`run_people` runs on ``configs`` (every body, both
    protocols)."""
    return sum(
        planned_scenarios(lean_resolution)
        + (0 if name in WOMEN else 2 * planned_pulls(c, pull_resolution))
        for name, c in configs.items()
    )


def run_people(
    out: str | os.PathLike[str],
    *,
    lean_resolution: float = 0.05,
    pull_resolution: float = 0.5,
    slots: int | None = None,
    say: Callable[[str], None] = print,
    plan: PlanHook | None = None,
    wait: bool = False,
) -> pd.DataFrame:
    """The people scorecard in OUT (``mjx-balance people``): people.csv (:func:`scorecard`),
    people_limits.csv (every body's limits), people.png and a manifest that records both
    bodies (a folder made with other bodies is refused). Returns people.csv's rows."""
    check_resolution(lean_resolution)
    check_pull_resolution(pull_resolution)
    configs = {b: human_config(b) for b in (*BODIES, *WOMEN)}
    if plan is not None:
        total = planned_people(configs, lean_resolution, pull_resolution)
        plan(PlannedWork(configs[BODIES[0]], total, "scenarios", note="the people scorecard"))
    out = Path(out)
    settings = {
        "people": {
            "bodies": {b: c.to_dict() for b, c in configs.items()},
            "lean_resolution": lean_resolution,
            "pull_resolution": pull_resolution,
        }
    }
    with protocol_folder(out, configs[BODIES[0]], settings, wait=wait):
        results = {}
        for body, config in configs.items():
            say(f"people: {body}")
            results[body] = body_results(
                config,
                lean_resolution=lean_resolution,
                pull_resolution=pull_resolution,
                slots=slots,
                say=say,
                pull=body not in WOMEN,
            )
        card = scorecard(results)
        limits = pd.DataFrame([r for b, res in results.items() for r in res.rows(b)])
        write_csv(card, out / PEOPLE_CSV)
        write_csv(limits, out / PEOPLE_LIMITS_CSV)
        plot_people(card, out / PEOPLE_FIGURE)
    predicted = card[card.kind == "predicted"]
    say(
        f"people: {int(predicted.agrees.sum())} of {len(predicted)} predicted measures agree "
        f"(within 2 SD); {int((card.kind == 'input').sum())} inputs, "
        f"{int((card.kind == 'not modelled').sum())} not modelled"
    )
    say(f"wrote {out / PEOPLE_CSV}, {out / PEOPLE_LIMITS_CSV} and the figure")
    return card
