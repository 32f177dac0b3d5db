"""A person's strength and timing by age and sex, relative to a young man's (docs/model.md,
"Age and sex").

A subject with an age (``Subject(..., age=70)``, ``cohort --ages``) takes its base
configuration as a young man's body (``sweeps/human.toml``: every number measured on young
adults) and changes what people measured to change with age and sex:

- the ankle's bounds: plantarflexion (the negative input-1 bound, which holds a forward lean)
  132 -> 80 N m, dorsiflexion (the positive bound) 45 -> 42 N m, from 11 young (mean 24 yr) to
  12 elderly men (mean 77 yr) (Simoneau, Martin & Van Hoecke 2005, J Gerontol A 60:439-447);
- the rate of torque development: 25 to 36 % lower in 24 old (mean 72 yr) than in 24 young
  adults (mean 23 yr), the middle 30.5 % (Thelen, Schultz, Alexander & Ashton-Miller 1996,
  J Gerontol A 51:M226-M232);
- the onset latency: + 22 ms, the older body's 0.122 s against the young's 0.1 s (reaction times
  164 against 141 ms, the same study, on the young's 99 ms);
- the step's landing time: + 75 ms, the middle of "50-100 ms faster in young than in elderly"
  (Hsiao-Wecksler & Robinovitch 2007, Clin Biomech 22:574-580).

These are the two shipped men's bodies' differences (``sweeps/human.toml``,
``sweeps/human_older.toml``), and as there the older numbers measured at 72 yr are taken as the
77-yr group's: between 24 and 77 yr each changes linearly (men's strength declines linearly with
age from 25 yr: Danneskiold-Samsoe et al. 2009, Acta Physiol,
doi:10.1111/j.1748-1716.2009.02022.x), so a man of 73 kg at 24 yr is ``human.toml`` and at 77 yr
``human_older.toml``; below 24 yr each is the young's and above 77 yr the older's (no
measurement beyond them). The hip keeps the base's bounds at every age (no published hip torque
in N m was found; as ``human_older.toml``).

Sex: women's ankle torques were 62 to 70 % of men's (20 men, 20 women, 25-60 yr: "Strength
and range of motion in the ankle in two age groups of men and women", abstract read at
paperexplained.cn, which prints neither its authors nor its journal; the middle, 0.66). A
subject's bounds already scale with its mass (de Leva's reference woman, 61.9 kg, gets
61.9 / 73.0 of the reference man's), so a woman's factor is the rest, 0.66 x 73.0 / 61.9 =
0.778, on the ankle and the hip bounds and on the rates. The same decline with age is taken for
women as for men (an assumption: the sources above measured men, or men and women together).
"""

from __future__ import annotations

from typing import NamedTuple

# The young and the older group's mean ages [yr] (Simoneau et al. 2005), and the older group's
# value over the young's (a factor) or minus it (s): module docstring for the sources
AGES = (24.0, 77.0)
PLANTARFLEXION_OLDER = 80.0 / 132.0
DORSIFLEXION_OLDER = 42.0 / 45.0
RATE_OLDER = 1.0 - 0.305
ONSET_OLDER = 0.022  # s, added
STEP_TIME_OLDER = 0.075  # s, added
# Women's torques over men's (62-70 %, the middle; module docstring), and de Leva's reference
# sample masses [kg] (model.subject.REFERENCE_BODY) that a subject's mass scaling already uses
FEMALE_STRENGTH = 0.66
REFERENCE_MASSES = {"male": 73.0, "female": 61.9}
AGE_RANGE = (18.0, 110.0)  # yr: adults (the sources measured adults)


class Ageing(NamedTuple):
    """What an age and a sex change, relative to a young man's body of the same mass."""

    plantarflexion: float  # factor on the negative input-1 bound
    dorsiflexion: float  # factor on the positive input-1 bound
    hip: float  # factor on both input-2 bounds
    rate: float  # factor on the input rates (ankle and hip)
    onset: float  # s added to scenario.controller_delay
    step_time: float  # s added to body.step_time


# What a subject without an age gets: nothing changed (its sex changes the segments only)
NO_AGEING = Ageing(1.0, 1.0, 1.0, 1.0, 0.0, 0.0)


def share(age: float) -> float:
    """How far ``age`` lies from the young group's age to the older group's, in [0, 1]."""
    young, older = AGES
    return min(1.0, max(0.0, (age - young) / (older - young)))


def sex_factor(sex: str) -> float:
    """A woman's strength over a man's of her mass (1 for a man; module docstring)."""
    if sex == "male":
        return 1.0
    return FEMALE_STRENGTH * REFERENCE_MASSES["male"] / REFERENCE_MASSES["female"]


def ageing(age: float, sex: str) -> Ageing:
    """The factors and additions of ``age`` [yr] and ``sex`` (module docstring)."""
    k, t = sex_factor(sex), share(age)
    return Ageing(
        plantarflexion=k * (1.0 + (PLANTARFLEXION_OLDER - 1.0) * t),
        dorsiflexion=k * (1.0 + (DORSIFLEXION_OLDER - 1.0) * t),
        hip=k,
        rate=k * (1.0 + (RATE_OLDER - 1.0) * t),
        onset=ONSET_OLDER * t,
        step_time=STEP_TIME_OLDER * t,
    )
