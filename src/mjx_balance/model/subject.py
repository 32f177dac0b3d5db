"""A person's three segments from a published segment table (anthropometric scaling).

The table is de Leva P. (1996), "Adjustments to Zatsiorsky-Seluyanov's segment inertia
parameters", Journal of Biomechanics 29(9):1223-1230, Table 4 (the segments with joint-centre
endpoints, upper half of the table). For each segment and sex it gives the mean longitudinal
length of the reference sample (mm), the mass (% of body mass), the CoM position (% of the
segment's length from the origin endpoint, the first endpoint listed) and the radius of
gyration about the sagittal axis (% of the segment's length). Reference samples: males
1741 mm, 73.0 kg; females 1735 mm, 61.9 kg.

How our three segments aggregate the table's (docs/model.md, "Subjects"):

- **foot**: the two feet. Mass 2 m_foot; length the table's foot (HEEL-TTIP); pitch inertia
  2 m_foot (r_foot L_foot)^2 (both feet on one axis). The model keeps its ankle above the sole's
  centre and the foot's CoM there: the table's foot CoM position (44 % / 40 % from the heel) is
  not used.
- **lower body** (ankle -> hip): two shanks (KJC-LMAL) and two thighs (HJC-KJC), stacked from
  the ankle (the lateral malleolus, at the model's ankle). Length L_shank + L_thigh; CoM the
  mass-weighted mean of the four segments' CoMs; pitch inertia the sum of each segment's own
  (m (r L)^2) and its parallel-axis term m d^2, d its CoM's distance from the aggregate's CoM
  along the leg.
- **upper body** (hip -> top of the head): trunk (MIDH-SUPR) from the hip up, head
  (VERT-MIDG) hanging from the top of the link, and two arms (upper arm, forearm, hand) hanging
  at the sides from the shoulder joint centres, taken at the trunk's top (suprasternale)
  height. Length: the stature minus the lower body (the model's ankle is at the floor, as in
  the study, so the link reaches the top of the head). CoM and pitch inertia aggregated as for
  the lower body.

Segment lengths scale with stature (L = L_table x height / stature_table), masses with body
mass; CoM and radius fractions are the table's. Everything here is plain arithmetic on floats
(no configuration classes: ``params.Subject`` builds the configuration from these values).
"""

from __future__ import annotations

from typing import NamedTuple

SEXES = ("male", "female")


class Segment(NamedTuple):
    """One row of de Leva (1996) Table 4 for one sex."""

    length: float  # m, mean longitudinal length of the reference sample
    mass: float  # fraction of body mass
    com: float  # CoM distance from the origin endpoint, fraction of the length
    radius: float  # sagittal radius of gyration, fraction of the length


# de Leva (1996) Table 4: (length mm / 1000, mass % / 100, CoM % / 100, sagittal r % / 100).
# Origin endpoints: head VERT (vertex), trunk SUPR (suprasternale), upper arm SJC, forearm EJC,
# hand WJC, thigh HJC, shank KJC, foot HEEL.
DE_LEVA_1996: dict[str, dict[str, Segment]] = {
    "male": {
        "head": Segment(0.2033, 0.0694, 0.5976, 0.362),
        "trunk": Segment(0.5319, 0.4346, 0.4486, 0.372),
        "upper_arm": Segment(0.2817, 0.0271, 0.5772, 0.285),
        "forearm": Segment(0.2689, 0.0162, 0.4574, 0.276),
        "hand": Segment(0.0862, 0.0061, 0.7900, 0.628),
        "thigh": Segment(0.4222, 0.1416, 0.4095, 0.329),
        "shank": Segment(0.4340, 0.0433, 0.4459, 0.255),
        "foot": Segment(0.2581, 0.0137, 0.4415, 0.257),
    },
    "female": {
        "head": Segment(0.2002, 0.0668, 0.5894, 0.330),
        "trunk": Segment(0.5293, 0.4257, 0.4151, 0.357),
        "upper_arm": Segment(0.2751, 0.0255, 0.5754, 0.278),
        "forearm": Segment(0.2643, 0.0138, 0.4559, 0.261),
        "hand": Segment(0.0780, 0.0056, 0.7474, 0.531),
        "thigh": Segment(0.3685, 0.1478, 0.3612, 0.369),
        "shank": Segment(0.4323, 0.0481, 0.4416, 0.271),
        "foot": Segment(0.2283, 0.0129, 0.4014, 0.299),
    },
}
# The reference samples' mean stature [m] and body mass [kg] (de Leva 1996).
REFERENCE_BODY = {"male": (1.741, 73.0), "female": (1.735, 61.9)}


class Part(NamedTuple):
    """A segment placed on one of our links: mass [kg], CoM height on the link [m], pitch
    inertia about its own CoM [kg m^2]."""

    mass: float
    z: float
    inertia: float


def aggregate(parts: list[Part]) -> tuple[float, float, float]:
    """(mass, CoM height, pitch inertia about that CoM) of rigidly joined parts on one line
    (parallel-axis theorem: I = sum(I_i + m_i (z_i - z)^2))."""
    mass = sum(p.mass for p in parts)
    com = sum(p.mass * p.z for p in parts) / mass
    inertia = sum(p.inertia + p.mass * (p.z - com) ** 2 for p in parts)
    return mass, com, inertia


def _part(seg: Segment, scale: float, body_mass: float, z: float, count: int = 1) -> Part:
    """``count`` copies of ``seg`` with their CoM at height ``z`` on the link."""
    mass = count * seg.mass * body_mass
    return Part(mass, z, mass * (seg.radius * seg.length * scale) ** 2)


def segments(height: float, mass: float, sex: str = "male") -> dict[str, float]:
    """The body's segment values (BodyParams field names) for a person of ``height`` [m],
    ``mass`` [kg] and ``sex``, from de Leva (1996) Table 4 (the module docstring says how)."""
    if sex not in SEXES:
        raise ValueError(f"sex = {sex!r}: must be one of {SEXES}")
    table = DE_LEVA_1996[sex]
    s = height / REFERENCE_BODY[sex][0]  # length scale
    length = {name: seg.length * s for name, seg in table.items()}

    foot = table["foot"]
    foot_mass = 2 * foot.mass * mass
    foot_inertia = foot_mass * (foot.radius * length["foot"]) ** 2

    # lower body, heights above the ankle: the shank's origin (KJC) is at its top
    shank, thigh = table["shank"], table["thigh"]
    lower_length = length["shank"] + length["thigh"]
    lower = aggregate([
        _part(shank, s, mass, length["shank"] * (1 - shank.com), 2),
        _part(thigh, s, mass, lower_length - length["thigh"] * thigh.com, 2),
    ])

    # upper body, heights above the hip: trunk up from MIDH, head down from the top, arms
    # down from the shoulders (at the trunk's top)
    upper_length = height - lower_length
    shoulder = length["trunk"]
    elbow = shoulder - length["upper_arm"]
    wrist = elbow - length["forearm"]
    upper = aggregate([
        _part(table["trunk"], s, mass, length["trunk"] * (1 - table["trunk"].com)),
        _part(table["head"], s, mass, upper_length - length["head"] * table["head"].com),
        _part(table["upper_arm"], s, mass, shoulder - length["upper_arm"]
              * table["upper_arm"].com, 2),
        _part(table["forearm"], s, mass, elbow - length["forearm"] * table["forearm"].com, 2),
        _part(table["hand"], s, mass, wrist - length["hand"] * table["hand"].com, 2),
    ])
    return {
        "foot_mass": foot_mass, "foot_length": length["foot"], "foot_inertia": foot_inertia,
        "lower_mass": lower[0], "lower_length": lower_length, "lower_com": lower[1],
        "lower_inertia": lower[2],
        "upper_mass": upper[0], "upper_length": upper_length, "upper_com": upper[1],
        "upper_inertia": upper[2],
    }
