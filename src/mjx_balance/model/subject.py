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
mass; CoM and radius fractions are the table's.

:class:`Subject` is a person (height, mass, sex, strengths) checked for plausibility, and builds
a configuration from the table's values (``Subject.config``); it is read from ``--subject``
(:func:`parse_subject`), a configuration's ``[subject]`` table (:func:`as_subject`) or a CSV
file of participants (:func:`subject_rows`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, NamedTuple

from .ageing import AGE_RANGE, NO_AGEING, Ageing, ageing
from .params import (
    BodyParams,
    Config,
    ControllerParams,
    ParameterError,
    check_finite,
    check_range,
    fail,
    is_number,
    plain,
)

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
    lower = aggregate(
        [
            _part(shank, s, mass, length["shank"] * (1 - shank.com), 2),
            _part(thigh, s, mass, lower_length - length["thigh"] * thigh.com, 2),
        ]
    )

    # upper body, heights above the hip: trunk up from MIDH, head down from the top, arms
    # down from the shoulders (at the trunk's top)
    upper_length = height - lower_length
    shoulder = length["trunk"]
    elbow = shoulder - length["upper_arm"]
    wrist = elbow - length["forearm"]
    upper = aggregate(
        [
            _part(table["trunk"], s, mass, length["trunk"] * (1 - table["trunk"].com)),
            _part(table["head"], s, mass, upper_length - length["head"] * table["head"].com),
            _part(
                table["upper_arm"],
                s,
                mass,
                shoulder - length["upper_arm"] * table["upper_arm"].com,
                2,
            ),
            _part(table["forearm"], s, mass, elbow - length["forearm"] * table["forearm"].com, 2),
            _part(table["hand"], s, mass, wrist - length["hand"] * table["hand"].com, 2),
        ]
    )
    return {
        "foot_mass": foot_mass,
        "foot_length": length["foot"],
        "foot_inertia": foot_inertia,
        "lower_mass": lower[0],
        "lower_length": lower_length,
        "lower_com": lower[1],
        "lower_inertia": lower[2],
        "upper_mass": upper[0],
        "upper_length": upper_length,
        "upper_com": upper[1],
        "upper_inertia": upper[2],
    }


# -- subjects -------------------------------------------------------------------------------
# A subject's torque bounds are the base configuration's bounds, read as those of the base's
# own body, times mass / that body's total mass (the study's: 66.3 kg) times a strength factor.
HEIGHT_RANGE = (0.5, 2.5)  # m: small children to the tallest adults
SUBJECT_MASS_RANGE = (5.0, 300.0)  # kg
# Body mass index mass / height^2 [kg/m^2]: height and mass each in range can still make no
# body. Below 10 no adult has survived and no child lies (the WHO growth charts' lowest
# centiles are near 12); above 60 lies beyond the severely obese participants of balance
# studies, where a segment table fitted to lean young adults (de Leva 1996: BMI 20-24) no
# longer describes the body. The bound refuses a height or a mass mistyped or misread, e.g. a
# decimal comma's "1,6" read as 1 m and 6 kg (BMI 6) or "1,75" as 1 m and 75 kg (BMI 75).
BMI_RANGE = (10.0, 60.0)  # kg/m^2
STRENGTH_RANGE = (0.0, 10.0)  # factor, > 0
# What a subject derives (a configuration's values that [subject] replaces).
SUBJECT_BODY_KEYS = (
    "foot_mass",
    "foot_length",
    "foot_inertia",
    "lower_mass",
    "lower_length",
    "lower_com",
    "lower_inertia",
    "upper_mass",
    "upper_length",
    "upper_com",
    "upper_inertia",
)
SUBJECT_CONTROLLER_KEYS = ("cop_bounds", "com_bounds")


@dataclass(frozen=True)
class Subject:
    """A person: stature, mass, sex, strength and (optionally) age.

    ``config(base)`` is ``base`` (None: the study's configuration) with this person's body from
    de Leva (1996) Table 4 (docs/model.md, "Subjects"): every segment's mass, length, CoM and
    pitch inertia, the foot, CoP and CoM bounds at the sole's ends under ``base``'s
    ``ankle_position``, and ``base``'s input bounds times ``mass / M_base`` (the base body's total
    mass: the study's 66.3 kg, the human bodies' 73 kg) times ``ankle_strength`` (input 1) or
    ``hip_strength`` (input 2). With an ``age``, the base is read as a young man's body
    (``sweeps/human.toml``) and the strength, rate of torque development, onset latency and step
    time are a person's of that age and sex (``model.ageing``; docs/model.md, "Age and sex");
    without one, the sex changes the segments only.

    Args:
        height: Stature [m], 0.5-2.5 (with a body mass index of 10-60 kg/m^2).
        mass: Body mass [kg], 5-300.
        sex: ``"male"`` or ``"female"`` (de Leva's table).
        ankle_strength: Factor on the mass-scaled ankle torque bound, in (0, 10].
        hip_strength: Factor on the mass-scaled hip torque bound, in (0, 10].
        age: Age [yr], 18-110, or None (no age: the base's strength and timing, scaled by mass).

    Raises:
        ParameterError: a value out of its range, naming it.

    Example:
        >>> base = mb.load_config("sweeps/human.toml")
        >>> config = mb.Subject(1.62, 58.0, "female", age=70).config(base)
    """

    height: float
    mass: float
    sex: str = "male"
    ankle_strength: float = 1.0
    hip_strength: float = 1.0
    age: float | None = None  # yr; None: the base's strength and timing, scaled by mass only

    def __post_init__(self) -> None:
        named = ("height", "mass", "ankle_strength", "hip_strength")
        for name in named + (("age",) if self.age is not None else ()):
            if not is_number(getattr(self, name)):
                fail("subject", name, "must be a number", getattr(self, name))
            object.__setattr__(self, name, float(getattr(self, name)))
        check_finite("subject", self)
        if self.age is not None:
            check_range("subject", self, ("age",), *AGE_RANGE, "yr")
        if self.sex not in SEXES:
            fail("subject", "sex", f"must be one of {SEXES}", self.sex)
        check_range("subject", self, ("height",), *HEIGHT_RANGE, "m")
        check_range("subject", self, ("mass",), *SUBJECT_MASS_RANGE, "kg")
        bmi = self.mass / self.height**2
        if not BMI_RANGE[0] <= bmi <= BMI_RANGE[1]:
            raise ParameterError(
                f"subject.mass = {self.mass:g} kg at subject.height = {self.height:g} m: body "
                f"mass index {bmi:.3g} kg/m^2, outside the plausible [{BMI_RANGE[0]:g}, "
                f"{BMI_RANGE[1]:g}]; check the height [m] and the mass [kg] (a decimal comma?)"
            )
        for name in ("ankle_strength", "hip_strength"):
            value = getattr(self, name)
            if not STRENGTH_RANGE[0] < value <= STRENGTH_RANGE[1]:
                fail(
                    "subject",
                    name,
                    f"must lie in ({STRENGTH_RANGE[0]:g}, "
                    f"{STRENGTH_RANGE[1]:g}] (a factor on the mass-scaled torque bounds)",
                    value,
                )

    def body_values(self) -> dict[str, float]:
        """The body's values this subject derives (``SUBJECT_BODY_KEYS``)."""
        return segments(self.height, self.mass, self.sex)

    def controller_values(
        self, base: ControllerParams, body: BodyParams
    ) -> dict[str, tuple[float, ...]]:
        """CoP and CoM bounds at the sole's edges (the ankle ``body.ankle_position`` of the
        foot's length from the heel) and ``base``'s input bounds, read as those of ``body``,
        scaled by mass (its input rates too, when it has them, by the same factors: an
        assumption, docs/model.md "Strength and timing")."""
        length = self.body_values()["foot_length"]
        edges = (-body.ankle_position * length, (1 - body.ankle_position) * length)
        scale = self.mass / body.total_mass
        factors = (scale * self.ankle_strength, scale * self.hip_strength)
        aged = self.aged()  # x 1.0 without an age: the mass-scaled values exactly
        low, high = base.input1_bounds
        values: dict[str, tuple[float, ...]] = {
            "cop_bounds": edges,
            "com_bounds": edges,
            "input1_bounds": (
                low * aged.plantarflexion * factors[0],
                high * aged.dorsiflexion * factors[0],
            ),
            "input2_bounds": tuple(v * (factors[1] * aged.hip) for v in base.input2_bounds),
        }
        if base.input_rates is not None:
            values["input_rates"] = tuple(
                r * (f * aged.rate) for r, f in zip(base.input_rates, factors)
            )
        return values

    def aged(self) -> Ageing:
        """What this subject's age and sex change (``model.ageing``; nothing without an age)."""
        return NO_AGEING if self.age is None else ageing(self.age, self.sex)

    def timing(self, base: Config) -> dict[str, dict[str, float]]:
        """The onset latency (on the physics step's grid) and the step's landing time of a
        subject with an age (``model.ageing``); empty without one."""
        if self.age is None:
            return {}
        aged = self.aged()
        dt = base.scenario.physics_dt
        delay = round(dt * round((base.scenario.controller_delay + aged.onset) / dt), 12)
        return {
            "scenario": {"controller_delay": delay},
            "body": {"step_time": base.body.step_time + aged.step_time},
        }

    def config(self, base: Config | None = None) -> Config:
        """``base`` (None: the defaults, the study's configuration) with this subject's body."""
        base = Config() if base is None else base
        timing = self.timing(base)
        return base.replace(
            body={**self.body_values(), **timing.get("body", {})},
            controller=self.controller_values(base.controller, base.body),
            **({"scenario": timing["scenario"]} if timing else {}),
        )

    def to_dict(self) -> dict[str, Any]:
        """The fields (``age`` only when given: records of subjects without one unchanged)."""
        record = dataclasses.asdict(self)
        if self.age is None:
            del record["age"]
        return record

    def describe(self) -> str:
        """``height=1.62,mass=58,sex=female`` (the --subject form; strengths when not 1, the
        age when given)."""
        parts = [f"height={self.height:g}", f"mass={self.mass:g}", f"sex={self.sex}"]
        parts += [
            f"{n}={getattr(self, n):g}"
            for n in ("ankle_strength", "hip_strength")
            if getattr(self, n) != 1.0
        ]
        if self.age is not None:
            parts.append(f"age={self.age:g}")
        return ",".join(parts)


def as_subject(value: Any) -> Subject:
    """A Subject from a Subject or a table of its fields (a TOML [subject])."""
    if isinstance(value, Subject):
        return value
    if not isinstance(value, dict):
        raise ParameterError(
            f"section 'subject' must be a table (height, mass, sex, "
            f"ankle_strength, hip_strength), got {value!r}"
        )
    known = [f.name for f in fields(Subject)]
    unknown = sorted(set(value) - set(known))
    if unknown:
        raise ParameterError(
            f"subject: unknown key(s) {', '.join(unknown)}; known keys: {', '.join(known)}"
        )
    missing = [name for name in ("height", "mass") if name not in value]
    if missing:
        raise ParameterError(
            f"subject: give {' and '.join(missing)} (known keys: {', '.join(known)})"
        )
    return Subject(**{k: plain(v) for k, v in value.items()})


def check_subject_conflicts(subject: Subject, sections: dict[str, Any]) -> None:
    """Refuse a value given beside ``subject`` in the same place that the subject derives
    (SUBJECT_BODY_KEYS, SUBJECT_CONTROLLER_KEYS), naming both."""
    derived = {"body": SUBJECT_BODY_KEYS, "controller": SUBJECT_CONTROLLER_KEYS}
    for section, keys in derived.items():
        given = sections.get(section)
        if not isinstance(given, dict):
            continue
        clash = [k for k in keys if k in given]
        if clash:
            key = clash[0]
            values = (
                subject.body_values()
                if section == "body"
                else {"cop_bounds": "the sole's edges", "com_bounds": "the sole's edges"}
            )
            derived_value = values[key]
            shown = f"{derived_value:.6g}" if isinstance(derived_value, float) else derived_value
            raise ParameterError(
                f"{section}.{key} = {given[key]!r} and subject {subject.describe()} (which "
                f"derives {section}.{key} = {shown}) both set it: give one of them (a later "
                "--set overrides a subject's value)"
            )


def parse_subject(text: str) -> Subject:
    """``--subject height=1.62,mass=58[,sex=female][,ankle_strength=0.6][,hip_strength=0.8]``
    as a Subject (ParameterError naming the part that is wrong)."""
    values: dict[str, Any] = {}
    for part in str(text).split(","):
        key, sep, raw = part.partition("=")
        key, raw = key.strip(), raw.strip()
        if not sep or not key or not raw:
            raise ParameterError(
                f"--subject {text!r}: {part.strip()!r} is not KEY=VALUE "
                "(e.g. height=1.62,mass=58,sex=female)"
            )
        if key in values:
            raise ParameterError(f"--subject {text!r}: {key} given twice")
        try:
            values[key] = _subject_value(key, raw)
        except ValueError:
            raise ParameterError(f"--subject {text!r}: {key}={raw!r} is not a number") from None
    try:
        return as_subject(values)
    except ParameterError as exc:
        raise ParameterError(f"--subject {text!r}: {exc}") from None


def _subject_value(key: str, raw: str) -> str | float:
    """A subject field's value from its text: ``sex`` in lower case (``Female`` is female), any
    other a number (ValueError where it is not one)."""
    return raw.lower() if key == "sex" else float(raw)


# A subjects CSV file's columns besides Subject's fields: the subject's id (cohorts name its
# folder after it) and free-text columns, read and ignored. Any other column is refused: a
# misspelt ``ankle_strenght`` would otherwise leave every strength at 1 without a word.
CSV_ID_COLUMN = "id"
CSV_TEXT_COLUMNS = ("note", "notes", "comment", "comments")


@dataclass(frozen=True)
class SubjectRow:
    """One subject of a CSV file: its line in the file, its id as written ("" when the row or
    the file gives none) and the Subject."""

    line: int
    id: str
    subject: Subject


def subjects_from_csv(path: str | Path) -> list[Subject]:
    """The subjects of a CSV file (:func:`subject_rows`), without their ids."""
    return [row.subject for row in subject_rows(path)]


def subject_rows(path: str | Path) -> list[SubjectRow]:
    """The subjects of a CSV file with a header: columns ``height`` and ``mass`` (required),
    ``sex``, ``ankle_strength``, ``hip_strength`` (optional; empty cells take the defaults),
    ``id`` (optional) and free text in ``note``/``notes``/``comment``/``comments`` (ignored).
    Column names are matched ignoring case and surrounding spaces; an Excel byte-order mark is
    skipped; lines starting with ``#`` are comments, skipped, and blank lines too. Refused,
    with a ParameterError naming the file, the line and the value: an unknown or repeated
    column, a row with more values than the header has columns (a decimal comma: ``1,62``),
    a value that is not a number, a subject out of its plausible ranges."""
    import csv

    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            rows = list(_csv_rows(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ParameterError(f"{path}: cannot be read as a CSV file ({exc})") from None
    if not rows:
        raise ParameterError(
            f"{path}: empty; give a header (such as id,height,mass,sex) and a row per subject"
        )
    columns = _subject_columns(path, *rows[0])
    if len(rows) == 1:
        raise ParameterError(f"{path}: holds a header and no subject")
    return [_subject_row(path, line, columns, cells) for line, cells in rows[1:]]


def _csv_rows(fh: Any) -> list[tuple[int, list[str]]]:
    """(line number, cells) of each row of a CSV file that holds something: lines starting
    with ``#`` (after spaces) are comments, left out before the CSV reader sees them."""
    import csv

    where = [0]

    def lines() -> Any:
        for number, text in enumerate(fh, start=1):
            if text.lstrip().startswith("#"):
                continue
            where[0] = number
            yield text

    return [
        (where[0], cells) for cells in csv.reader(lines()) if any(cell.strip() for cell in cells)
    ]


def _subject_columns(path: Path, line: int, header: list[str]) -> list[str]:
    """The header's column names, stripped and in lower case, checked: each known, once, and
    height and mass among them."""
    known = [CSV_ID_COLUMN, *(f.name for f in fields(Subject))]
    names = [h.strip().lower() for h in header]
    listed = f"known columns: {', '.join(known)} (and {', '.join(CSV_TEXT_COLUMNS)}: ignored)"
    unknown = [
        h.strip()
        for h, n in zip(header, names)
        if n and n not in known and n not in CSV_TEXT_COLUMNS
    ]
    if unknown:
        hint = (
            "; columns are separated by commas"
            if any(";" in u or "\t" in u for u in unknown)
            else ""
        )
        raise ParameterError(
            f"{path}, line {line}: unknown column(s) "
            f"{', '.join(repr(u) for u in unknown)}; {listed}{hint}"
        )
    twice = sorted({n for n in names if n and names.count(n) > 1})
    if twice:
        raise ParameterError(
            f"{path}, line {line}: column {twice[0]!r} is given twice (column names ignore case)"
        )
    missing = [n for n in ("height", "mass") if n not in names]
    if missing:
        raise ParameterError(
            f"{path}, line {line}: the header has no column "
            f"{' and no column '.join(missing)}; {listed}"
        )
    return names


def _subject_row(path: Path, line: int, columns: list[str], cells: list[str]) -> SubjectRow:
    """One data row as a SubjectRow (ParameterError naming the file, the line and the value)."""
    where = f"{path}, line {line}"
    if len(cells) > len(columns):
        raise ParameterError(
            f"{where}: {len(cells)} values for the header's {len(columns)} columns "
            f"({','.join(cells)}); a decimal comma? Write decimals with a point (1.62)"
        )
    values: dict[str, Any] = {}
    ident = ""
    for name, raw in zip(columns, cells):
        raw = raw.strip()
        if not raw or name in CSV_TEXT_COLUMNS:
            continue
        if not name:
            raise ParameterError(
                f"{where}: {raw!r} is in a column without a name; name it "
                "in the header or remove it"
            )
        if name == CSV_ID_COLUMN:
            ident = raw
            continue
        try:
            values[name] = _subject_value(name, raw)
        except ValueError:
            hint = " (a decimal comma? write a point)" if "," in raw else ""
            raise ParameterError(f"{where}: {name} = {raw!r} is not a number{hint}") from None
    try:
        return SubjectRow(line, ident, as_subject(values))
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None


def with_sections(config: Config, sections: dict[str, Any]) -> Config:
    """``config`` with ``sections`` (``Config.replace``'s arguments, as a TOML file's tables):
    a ``subject`` table (a Subject or a table of its fields) first puts that person's body on
    ``config``, then the other sections replace; a value the subject derives may not be given
    in them too (ParameterError naming both)."""
    sections = dict(sections)
    if "subject" not in sections:
        return config.replace(**sections)
    subject = as_subject(sections.pop("subject"))
    check_subject_conflicts(subject, sections)
    return subject.config(config).replace(**sections)
