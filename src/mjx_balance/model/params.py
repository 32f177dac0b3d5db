"""Body, controller and scenario parameters (docs/model.md) as frozen dataclasses.

Every number the package computes with comes from one of these three records. They are plain
frozen dataclasses (hashable, so they can be static arguments under ``jax.jit``), validated on
construction (each value's range, and the limits that link the records), and read from / written
to TOML (``config_files.py``) with the layout::

    [body]        # BodyParams
    [controller]  # ControllerParams
    [scenario]    # ScenarioParams

Conventions (docs/model.md, "Two conventions"): ``paper`` uses absolute segment tilts
x = [q1, q2, dq1, dq2] and generalised forces u = [tau1, tau2]; ``joint`` uses joint angles
x = [q_a, q_h, dq_a, dq_h] and motor torques u = [tau_ankle, tau_hip].
"""

from __future__ import annotations

import dataclasses
import logging
import math
import re
import numbers
import warnings
from dataclasses import dataclass, field, fields
from typing import Any, NoReturn

log = logging.getLogger(__name__)

CONVENTIONS = ("paper", "joint")
# the built-in values of controller.kind (control/law.py); any other is package.module:factory
CONTROLLER_KINDS = ("mpc", "lqr", "pd")

# Plausible ranges: outside them the physics or the numerics break, so a value there is refused
# rather than simulated (each message names the field and the range).
# - physics_dt <= 0.01 s: MuJoCo's contacts (default solref, time constant 0.02 s) need a time
#   step of at most half their time constant; with a longer step MuJoCo raises the time constant
#   to two steps (its "refsafe" rule), so the floor is no longer the modelled one, and at
#   physics_dt = 1 s every sweep cell diverges and the reference's OSQP fails.
# - Masses in [1e-3, 1e4] kg and lengths in [1e-3, 10] m: far beyond any human or humanoid at
#   both ends (the study's segments are 1.3-35 kg and 0.02-1 m). Below, MuJoCo refuses the model
#   (a 1e-12 kg foot: "mass and inertia of moving bodies must be larger than mjMINVAL"); the
#   smallest pitch inertia the ranges allow, 1e-3 kg (1e-3 m)^2 / 12 ~ 1e-10 kg m^2, is far above
#   that limit (1e-15). Above, OSQP finds the condensed QP non-convex (a 1e6-kg lower body) and
#   the forces overflow (1e308 kg ends in a numpy error). Bodies at the ends of both ranges
#   (each end, mixed ends, both conventions; 1-s reference runs) simulate without an error or a
#   MuJoCo warning.
# - gravity in [0.1, 100] m/s^2 (Jupiter's is 25, the Moon's 1.6): at 1e6 OSQP's factorisation
#   fails; at 1e-300 the body has no unstable mode left to control, the reference's OSQP fails
#   mid-run and the offset-free target has no posture-dependent constraint.
MAX_PHYSICS_DT = 0.01  # s
MAX_STEPS = 2**31 - 1  # physics steps of one window: an int32 count on the device
MASS_RANGE = (1e-3, 1e4)  # kg
LENGTH_RANGE = (1e-3, 10.0)  # m
ANKLE_POSITION_RANGE = (0.05, 0.95)  # fraction of the foot from the heel: the ankle on the sole
# The step of measures/capture.py: a step of 0 (no step) to 1.5 heights (beyond any person's
# lunge) and a swing from 0.05 s to 5 s (a step slower than that is no recovery step).
STEP_LENGTH_RANGE = (0.0, 1.5)  # fraction of the body's height
STEP_TIME_RANGE = (0.05, 5.0)  # s
# The default step (docs/model.md, "Stepping: capturability"): a forward step of 35 % of body
# height, the longest of the single recovery steps with which young and elderly women recovered
# from a forward lean (Hsiao-Wecksler & Robinovitch 2007, Clin Biomech 22:574-580: 15, 25, 35 %);
# 0.3 s from the perturbation to the foot's placement ("The stepping strategy needs at least
# 300 ms (30% of a stride) before foot placement", Hof et al. 2010, J Exp Biol 213:2655: 10
# young adults, mean age 20 years, lateral pushes while walking).
STEP_LENGTH = 0.35  # of the body's height
STEP_TIME = 0.3  # s
MAX_GRAVITY = 100.0  # m/s^2
MIN_GRAVITY = 0.1  # m/s^2
# - friction <= 2: the load cells are pyramidal-cone contacts, whose normal direction MuJoCo
#   softens as the friction coefficient grows. Measured with the reference at rest (no push,
#   2 s, default body): the foot sinks 0.27 mm at friction 1 and 1.4 mm at 2 and stays upright;
#   at 2.5 it sinks 3.1 mm and never settles, at 3.5 it sinks 12 mm and falls with no push.
#   Shoe soles on floors have 0.3-1.
MAX_FRICTION = 2.0
# - Segment pitch inertias (optional) in [1e-10, 1e4] kg m^2: the uniform shapes' values over
#   the mass and length ranges above span 1e-10 (1e-3 kg, 1e-3 m) to 1e4 * 10^2 / 12 ~ 8e3.
INERTIA_FIELDS = ("foot_inertia", "lower_inertia", "upper_inertia")
INERTIA_RANGE = (1e-10, 1e4)  # kg m^2


def push_steps(durations: Any, physics_dt: float) -> Any:
    """n_push = ceil(T / dt - 1e-9) physics steps with a push of ``durations`` [s] on (float64
    on the host, int32 array): the one rounding every path, the reference and the capture
    columns use."""
    import numpy as np  # lazy: `import mjx_balance` stays light (tests/api/test_api.py)

    return np.ceil(np.asarray(durations, np.float64) / physics_dt - 1e-9).astype(np.int32)


class ParameterError(ValueError):
    """A parameter value breaks a rule (a ``ValueError``).

    The message names the field and the rule, on one line: a line break in it (a library's
    message quoted in it) becomes a space, so the command line's one-line refusal stays one line.

    Args:
        message: What is wrong, naming the field and the rule.
        args: Further arguments, as ``ValueError``'s.
    """

    def __init__(self, message: Any = "", *args: Any) -> None:
        text = str(message)
        if "\n" in text or "\r" in text:
            text = " ".join(part.strip() for part in text.splitlines() if part.strip())
        super().__init__(text, *args)


class ParameterWarning(UserWarning):
    """A configuration that runs but holds a limit that can never bind (``config_warnings``)."""


def fail(record: str, name: str, rule: str, value: Any) -> NoReturn:
    raise ParameterError(f"{record}.{name} = {value!r}: {rule}")


def is_number(value: Any) -> bool:
    """A real number; a bool is not one (TOML's ``true`` must not pass as 1)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


# A number as a user writes one: decimal digits (ASCII) with an optional sign, point and
# exponent, or inf / nan (refused as not finite where they must be). Python's float() also
# reads "50_0" (as 500), other scripts' digits and "infinity"; those are refused, so that one
# text means one number everywhere it is read (grids, pairs, explore's queries).
NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:inf|nan)", re.I)


def read_number(text: str, name: str) -> float:
    """``text`` (spaces around it ignored) as a number written as :data:`NUMBER` reads one;
    otherwise a ParameterError whose one line names ``name`` and the text."""
    text = str(text).strip()
    if not NUMBER.fullmatch(text):
        raise ParameterError(f"{name}: {text!r} is not a number")
    return float(text)


def finite_number(text: str, name: str) -> float:
    """``text`` (spaces around it ignored) as a finite number; otherwise a ParameterError whose
    one line names ``name`` and the text."""
    text = str(text).strip()
    value = read_number(text, name)
    if not math.isfinite(value):
        raise ParameterError(f"{name}: must be a finite number, got {text!r}")
    return value


def as_table(record: str, name: str, value: Any) -> tuple:
    """A table field's value (a dict, or (name, value) pairs) as sorted (name, value) pairs,
    each value a number, a bool, a string or a list of numbers (kept as a tuple): hashable,
    so a configuration stays a key."""
    items = value.items() if isinstance(value, dict) else value
    try:
        pairs = [(k, v) for k, v in items]
    except (TypeError, ValueError):
        fail(record, name, "must be a table of names and values", value)
    out = []
    for key, item in pairs:
        if isinstance(item, (list, tuple)) and all(is_number(v) for v in item):
            item = tuple(item)
        elif not isinstance(item, (bool, str)) and not is_number(item):
            rule = f"{key}: must be a number, true/false, a string or a list of numbers"
            fail(record, name, rule, value)
        if not isinstance(key, str) or not key.isidentifier():
            fail(record, name, f"{key!r}: names must be Python identifiers", value)
        out.append((key, item))
    return tuple(sorted(out))


def _check_kind(ctrl: Any) -> None:
    """The controller's kind is a built-in one or 'package.module:factory'; options belong to
    a factory; offset-free is the MPC's own (control/law.py)."""
    kind = ctrl.kind
    module, sep, name = kind.partition(":")
    if kind not in CONTROLLER_KINDS and not (sep and module.strip() and name.strip()):
        built_in = ", ".join(CONTROLLER_KINDS)
        fail("controller", "kind", f"must be {built_in} or 'package.module:factory'", kind)
    if ctrl.options and not sep:
        rule = f"are a factory's arguments; kind {kind!r} takes none"
        fail("controller", "options", rule, dict(ctrl.options))
    if kind != "mpc" and ctrl.offset_free:
        fail("controller", "offset_free", f"is the MPC's observer; kind {kind!r} has none", True)


def _check_types(record: str, obj: Any) -> None:
    """Each field holds what its default is: a number (never a bool), a list of numbers (no
    nested lists, no bools, no strings), a bool or a string."""
    for f in fields(obj):
        value, default = getattr(obj, f.name), f.default
        if f.metadata.get("table"):
            continue  # (as_table checked it)
        if isinstance(default, bool):
            if not isinstance(value, bool):
                fail(record, f.name, "must be true or false", value)
        elif isinstance(default, str):
            if not isinstance(value, str):
                fail(record, f.name, "must be a string", value)
        elif isinstance(default, tuple):
            if not isinstance(value, (list, tuple)) or not all(is_number(v) for v in value):
                fail(record, f.name, "must be a list of numbers", value)
        elif isinstance(default, (int, float)) and not is_number(value):
            fail(record, f.name, "must be a number", value)
        elif default is None and value is not None and f.metadata.get("pair"):
            if not isinstance(value, (list, tuple)) or not all(is_number(v) for v in value):
                fail(record, f.name, "must be a list of numbers (or left out)", value)
        elif default is None and value is not None and not is_number(value):
            fail(record, f.name, "must be a number (or left out)", value)


def check_range(
    record: str, obj: Any, names: tuple[str, ...], low: float, high: float, unit: str
) -> None:
    for name in names:
        value = getattr(obj, name)
        if not low <= value <= high:
            fail(record, name, f"must lie in [{low:g}, {high:g}] {unit} (plausible range)", value)


def check_finite(record: str, obj: Any) -> None:
    for f in fields(obj):
        value = getattr(obj, f.name)
        items = value if isinstance(value, tuple) else (value,)
        for v in items:
            if is_number(v) and not math.isfinite(v):
                fail(record, f.name, "must be a finite number", value)


def _check_positive(record: str, obj: Any, names: tuple[str, ...]) -> None:
    for name in names:
        value = getattr(obj, name)
        if not value > 0:
            fail(record, name, "must be > 0", value)


def _check_bounds(record: str, name: str, bounds: tuple[float, float]) -> None:
    if len(bounds) != 2:
        fail(record, name, "must be a pair [lower, upper]", bounds)
    if bounds[0] > bounds[1]:
        fail(record, name, "lower bound must not exceed upper bound", bounds)


@dataclass(frozen=True)
class BodyParams:
    """The three-segment body (docs/model.md, "Body": the study's Table 1). SI units."""

    foot_mass: float = 1.3
    foot_length: float = 0.30  # sole length; load cells at x = ±foot_length/2
    foot_width: float = 0.10  # load cells at y = ±foot_width/2
    foot_thickness: float = 0.02  # slab height; the foot's CoM sits half of it above the sole
    lower_mass: float = 30.0
    lower_length: float = 1.0
    lower_com: float = 0.5  # CoM distance above the ankle
    upper_mass: float = 35.0
    upper_length: float = 0.6
    upper_com: float = 0.3  # CoM distance above the hip
    ankle_height: float = 0.0  # ankle above the sole (the study's equations: 0)
    gravity: float = 9.81
    friction: float = 1.0  # sole–floor Coulomb friction coefficient
    contact_radius: float = 0.005  # radius of the four load-cell spheres
    # A stiff position servo at the hip, part of the plant: a passive spring-damper holding
    # q_h at 0 (generalised force -K q_h - D dq_h on the hip joint), so that the hip motor
    # can be switched off (ankle-only strategy). 0 = no servo (the default model).
    hip_servo_stiffness: float = 0.0  # K [N m/rad]
    hip_servo_damping: float = 0.0  # D [N m s/rad]
    # Pitch inertias about each segment's CoM [kg m^2]. None (the default, and what a TOML
    # file without them means): the uniform shapes of the study's Table 1, m L^2 / 12 for the
    # rods and m (L^2 + t^2) / 12 for the foot slab (the *_pitch_inertia properties). A None
    # field is left out of the configuration's TOML and manifest, so a configuration without
    # them is recorded, compared and resumed as before they existed.
    foot_inertia: float | None = None
    lower_inertia: float | None = None
    upper_inertia: float | None = None
    # Where the ankle sits along the sole: its distance from the heel as a fraction of
    # foot_length (docs/model.md, "Strength and timing"). 0.5, the study's foot, centred on the
    # ankle; a person's ankle sits nearer the heel. The sole and its load cells move, the foot's
    # CoM stays below the ankle (where the study's linear CoM puts it).
    ankle_position: float = field(default=0.5, metadata={"omit_default": True})
    # The step the feet-in-place body could take (docs/model.md, "Stepping: capturability";
    # measures/capture.py): the longest step, ankle to ankle, as a fraction of the body's height
    # (so a subject's scales with its height), and the shortest time from the decision to step
    # to the foot's landing. The defaults are young adults' (STEP_LENGTH, STEP_TIME: sources).
    step_length: float = field(default=STEP_LENGTH, metadata={"omit_default": True})
    step_time: float = field(default=STEP_TIME, metadata={"omit_default": True})

    def __post_init__(self) -> None:
        _check_types("body", self)
        check_finite("body", self)
        _check_positive(
            "body",
            self,
            (
                "foot_mass",
                "foot_length",
                "foot_width",
                "foot_thickness",
                "lower_mass",
                "lower_length",
                "upper_mass",
                "upper_length",
                "gravity",
                "friction",
                "contact_radius",
            ),
        )
        check_range("body", self, ("foot_mass", "lower_mass", "upper_mass"), *MASS_RANGE, "kg")
        check_range(
            "body",
            self,
            (
                "foot_length",
                "foot_width",
                "foot_thickness",
                "lower_length",
                "upper_length",
                "contact_radius",
            ),
            *LENGTH_RANGE,
            "m",
        )
        if self.friction > MAX_FRICTION:
            fail(
                "body",
                "friction",
                f"must be <= {MAX_FRICTION:g} (above it the pyramidal contact softens the "
                "floor until the body cannot stand at rest)",
                self.friction,
            )
        if not MIN_GRAVITY <= self.gravity <= MAX_GRAVITY:
            fail(
                "body",
                "gravity",
                f"must lie in [{MIN_GRAVITY:g}, {MAX_GRAVITY:g}] m/s^2 (plausible range)",
                self.gravity,
            )
        for name, length in (("lower_com", self.lower_length), ("upper_com", self.upper_length)):
            value = getattr(self, name)
            if not 0 <= value <= length:
                fail("body", name, f"must lie on the segment, in [0, {length}]", value)
        if not ANKLE_POSITION_RANGE[0] <= self.ankle_position <= ANKLE_POSITION_RANGE[1]:
            fail(
                "body",
                "ankle_position",
                f"must lie in [{ANKLE_POSITION_RANGE[0]:g}, {ANKLE_POSITION_RANGE[1]:g}] (the "
                "ankle's distance from the heel, a fraction of foot_length)",
                self.ankle_position,
            )
        self._check_step()
        if not 0 <= self.ankle_height <= LENGTH_RANGE[1]:
            fail(
                "body", "ankle_height", f"must lie in [0, {LENGTH_RANGE[1]:g}] m", self.ankle_height
            )
        for name in ("hip_servo_stiffness", "hip_servo_damping"):
            if not getattr(self, name) >= 0:
                fail("body", name, "must be >= 0", getattr(self, name))
        for name in INERTIA_FIELDS:
            value = getattr(self, name)
            if value is not None and not INERTIA_RANGE[0] <= value <= INERTIA_RANGE[1]:
                fail(
                    "body",
                    name,
                    f"must lie in [{INERTIA_RANGE[0]:g}, {INERTIA_RANGE[1]:g}] "
                    "kg m^2 (plausible range), or be left out for the uniform shape's",
                    value,
                )

    def _check_step(self) -> None:
        """The step's length and time within their ranges (STEP_LENGTH_RANGE, STEP_TIME_RANGE)."""
        if not STEP_LENGTH_RANGE[0] <= self.step_length <= STEP_LENGTH_RANGE[1]:
            fail(
                "body",
                "step_length",
                f"must lie in [{STEP_LENGTH_RANGE[0]:g}, {STEP_LENGTH_RANGE[1]:g}] (the longest "
                "step, ankle to ankle, a fraction of the body's height)",
                self.step_length,
            )
        if not STEP_TIME_RANGE[0] <= self.step_time <= STEP_TIME_RANGE[1]:
            fail(
                "body",
                "step_time",
                f"must lie in [{STEP_TIME_RANGE[0]:g}, {STEP_TIME_RANGE[1]:g}] s (from the "
                "decision to step to the foot's landing)",
                self.step_time,
            )

    @property
    def total_mass(self) -> float:
        return self.foot_mass + self.lower_mass + self.upper_mass

    @property
    def height(self) -> float:
        """The upright body's height from the sole to the top of the upper body [m]."""
        return self.ankle_height + self.lower_length + self.upper_length

    @property
    def lower_pitch_inertia(self) -> float:
        """Pitch inertia of the lower body about its CoM: ``lower_inertia``, or a uniform rod's
        m L^2 / 12 when it is None."""
        if self.lower_inertia is not None:
            return self.lower_inertia
        return self.lower_mass * self.lower_length**2 / 12.0

    @property
    def upper_pitch_inertia(self) -> float:
        """``upper_inertia``, or a uniform rod's m L^2 / 12 when it is None."""
        if self.upper_inertia is not None:
            return self.upper_inertia
        return self.upper_mass * self.upper_length**2 / 12.0

    @property
    def sole_edges(self) -> tuple[float, float]:
        """(heel, toe): the sole's ends ahead of the ankle [m] (the heel's is negative)."""
        heel = -self.ankle_position * self.foot_length
        return heel, heel + self.foot_length

    @property
    def foot_pitch_inertia(self) -> float:
        """Pitch inertia of the foot about its CoM: ``foot_inertia``, or the slab's
        m (L^2 + t^2) / 12 when it is None."""
        if self.foot_inertia is not None:
            return self.foot_inertia
        return self.foot_mass * (self.foot_length**2 + self.foot_thickness**2) / 12.0


INFEASIBLE_MODES = ("capped", "exact_penalty")


@dataclass(frozen=True)
class ControllerParams:
    """The constrained MPC (docs/model.md, "Two conventions" and "The MPC") and its solver
    settings.

    Weights are diagonals: Q = diag(q_diag), R = diag(r_diag). Bounds are [lower, upper] pairs
    in the chosen convention's variables.
    """

    convention: str = "paper"
    horizon: int = 20
    q_diag: tuple[float, ...] = (1e3, 1e3, 1e3, 1e3)
    r_diag: tuple[float, ...] = (1e-1, 1e-4)  # 1e-4 * diag(1000, 1)
    input1_bounds: tuple[float, float] = (-20.0, 20.0)  # tau1 (paper) or tau_ankle (joint)
    input2_bounds: tuple[float, float] = (-100.0, 100.0)  # tau2 (paper) or tau_hip (joint)
    # How fast each input may change, N m/s [input 1, input 2] (docs/model.md, "Strength and
    # timing"): |u_k - u_{k-1}| <= rate * control_dt, a constraint on the applied input's
    # change in the QP and the same limit on the actuator. None (left out): no limit, the
    # study's controller.
    input_rates: tuple[float, float] | None = field(default=None, metadata={"pair": True})
    state1_bounds: tuple[float, float] = (-0.26, 0.5)  # q1 (paper) or q_a (joint), rad
    state2_bounds: tuple[float, float] = (-0.35, 1.4)  # q2 (paper) or q_h (joint), rad
    cop_bounds: tuple[float, float] = (-0.15, 0.15)  # m
    com_bounds: tuple[float, float] = (-0.15, 0.15)  # m
    # Reference QP solver (OSQP).
    osqp_eps: float = 1e-8
    osqp_max_iter: int = 20000
    # Batched ADMM solver (admm.py); static under jit. Defaults measured on closed-loop states
    # (`mjx-balance bench solver`, tests/control/test_admm.py): with H whitened, rho = 0.07
    # (x3 on input rows, x30 on CoP rows, admm.ADMMSettings.rho_scale), alpha = 1.8 and warm
    # starts reach 1e-3 of each torque range against OSQP at 1e-9 on every solve of the bench
    # states (5650 paper, 4583 joint);
    # rho 0.05..0.15, alpha 1.6/1.8 and CoP factors 10..50 were compared: this pair needs the
    # fewest iterations (mean 43 paper, 53 joint) with a 2x margin on the error. The cap is 100
    # so that those solves also meet eps and report SOLVED (at 60, ~15% of them after large
    # pushes still report MAX_ITER; at 100, 0.3% paper, 1.9% joint). sigma = 0 because H is
    # positive definite (saves a product per iteration); eps_rel 3e-6 because 1e-5 stops some
    # solves short of that accuracy;
    # eps_abs 1e-7 so that near-upright states (tiny q) are solved to the same relative accuracy.
    admm_rho: float = 0.07
    admm_sigma: float = 0.0
    admm_alpha: float = 1.8
    admm_max_iter: int = 100
    admm_check_every: int = 10
    admm_eps_abs: float = 1e-7
    admm_eps_rel: float = 3e-6
    # Stop a solve at the first check where OSQP's primal infeasibility certificate holds
    # instead of iterating to the cap. Off by default: the shared definitions run an infeasible
    # QP to the cap and use its last iterate, as the reference's OSQP does.
    admm_stop_on_infeasible: bool = False
    # What the controller does with a QP that has no solution (docs/model.md, "Solvers").
    # "capped": the study's shared definition, the solver's iterate after its iteration cap
    # (OSQP's max_iter in the reference, admm_max_iter in the batched path). "exact_penalty":
    # the state, CoP and CoM rows get an exact l1 penalty (inputs stay hard) with the weights
    # below, above every multiplier of a solvable QP, so that a solvable QP keeps exactly its
    # hard solution and an infeasible one gets the least-violation solution, which both
    # solvers reach by convergence instead of at a cap.
    infeasible: str = "capped"
    # l1 weights of the state, CoP and CoM rows [cost per rad, per m, per m]. Measured on the
    # solver benchmark's closed-loop states (bench.states, OSQP at 1e-9): the largest multiplier
    # of a solved QP is 1.76e4 on a CoP row (paper convention), 0 on the state and CoM rows
    # (in the joint convention only input rows are active); 1e5 is above all of them.
    penalty_weights: tuple[float, float, float] = (1e5, 1e5, 1e5)
    # Delay compensation: predict the current state from the delayed measurement with the
    # linear model and the inputs already applied (linear.delay_predictor), then solve the MPC
    # for it. Off: the MPC acts on the delayed measurement (the study's controller).
    delay_compensation: bool = False
    # Offset-free MPC (offset_free.py): a disturbance observer and a steady-state target that
    # cancels the estimated disturbance (a sustained push) within every bound. Off: the study's
    # controller, which regulates to upright and leans with a sustained push.
    offset_free: bool = False
    # The observer's pole per control period: the estimate's error shrinks by this factor each
    # period in the linear plant (0.8 at 10 ms: time constant -0.01 / ln 0.8 = 45 ms).
    observer_pole: float = 0.8
    # The fraction of each input's half-range the steady-state target leaves free around
    # itself (its input bounds are pulled in by it): room for the MPC to act about the target.
    # A lean target with an input on its bound leaves the MPC no authority one way and is not
    # a stable operating point (measured in the linear plant: 0 and 0.1 diverge, 0.2 and 0.3
    # settle; tests/control/test_offset_free.py, docs/model.md).
    target_margin: float = 0.2
    # Which controller balances the body (control/law.py, docs/model.md "Bring your own
    # controller"): "mpc" (this record's MPC), "lqr", "pd", or "package.module:factory", a
    # user's function; ``options``: the keyword arguments of a factory's call (the TOML table
    # [controller.options]), as sorted (name, value) pairs. Both left out of a configuration's
    # files at their defaults, so the MPC's folders read as before.
    kind: str = field(default="mpc", metadata={"omit_default": True})
    options: tuple = field(default=(), metadata={"omit_default": True, "table": True})

    def __post_init__(self) -> None:
        object.__setattr__(self, "options", as_table("controller", "options", self.options))
        _check_types("controller", self)
        object.__setattr__(self, "q_diag", tuple(float(v) for v in self.q_diag))
        object.__setattr__(self, "r_diag", tuple(float(v) for v in self.r_diag))
        for name in (
            "input1_bounds",
            "input2_bounds",
            "state1_bounds",
            "state2_bounds",
            "cop_bounds",
            "com_bounds",
            "penalty_weights",
        ):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        if self.input_rates is not None:
            object.__setattr__(self, "input_rates", tuple(float(v) for v in self.input_rates))
        check_finite("controller", self)
        if self.input_rates is not None and (
            len(self.input_rates) != 2 or not min(self.input_rates) > 0
        ):
            fail(
                "controller",
                "input_rates",
                "must be 2 positive numbers, N m/s (or left out: no limit)",
                self.input_rates,
            )
        if self.convention not in CONVENTIONS:
            fail("controller", "convention", f"must be one of {CONVENTIONS}", self.convention)
        if not isinstance(self.horizon, int) or self.horizon < 1:
            fail("controller", "horizon", "must be an integer >= 1", self.horizon)
        _check_kind(self)
        if len(self.q_diag) != 4 or min(self.q_diag) < 0:
            fail("controller", "q_diag", "must be 4 non-negative numbers", self.q_diag)
        if len(self.r_diag) != 2 or min(self.r_diag) <= 0:
            fail("controller", "r_diag", "must be 2 positive numbers", self.r_diag)
        for name in (
            "input1_bounds",
            "input2_bounds",
            "state1_bounds",
            "state2_bounds",
            "cop_bounds",
            "com_bounds",
        ):
            _check_bounds("controller", name, getattr(self, name))
        _check_positive(
            "controller", self, ("osqp_eps", "admm_rho", "admm_eps_abs", "admm_eps_rel")
        )
        if not self.admm_sigma >= 0:
            fail("controller", "admm_sigma", "must be >= 0", self.admm_sigma)
        if not 0 < self.admm_alpha < 2:
            fail("controller", "admm_alpha", "must lie in (0, 2)", self.admm_alpha)
        for name in ("osqp_max_iter", "admm_max_iter", "admm_check_every"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                fail("controller", name, "must be an integer >= 1", value)
        if self.infeasible not in INFEASIBLE_MODES:
            fail("controller", "infeasible", f"must be one of {INFEASIBLE_MODES}", self.infeasible)
        if len(self.penalty_weights) != 3 or not min(self.penalty_weights) > 0:
            fail(
                "controller",
                "penalty_weights",
                "must be 3 positive numbers (state, CoP, CoM rows)",
                self.penalty_weights,
            )
        if not 0 <= self.target_margin < 1:
            fail(
                "controller",
                "target_margin",
                "must lie in [0, 1) (a fraction of each input's half-range)",
                self.target_margin,
            )
        if not 0 <= self.observer_pole < 1:
            fail(
                "controller",
                "observer_pole",
                "must lie in [0, 1) (the observer's pole per control period; 0: deadbeat)",
                self.observer_pole,
            )

    @property
    def input_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (self.input1_bounds, self.input2_bounds)

    @property
    def state_bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (self.state1_bounds, self.state2_bounds)

    def rate_steps(self, control_dt: float) -> tuple[float, float]:
        """The most each input may change in one control period (N m): input_rates *
        control_dt, inf without a limit."""
        if self.input_rates is None:
            return (math.inf, math.inf)
        return (self.input_rates[0] * control_dt, self.input_rates[1] * control_dt)


@dataclass(frozen=True)
class ScenarioParams:
    """The push protocol and outcome thresholds (docs/model.md, "The push protocol" and "Samples
    and outcome rules")."""

    force: float = 0.0  # N, + forward
    duration: float = 0.1  # s
    t_end: float = 12.0  # s after push onset
    physics_dt: float = 0.002  # s
    control_dt: float = 0.01  # s
    push_body: str = "upper"  # "upper": the upper body's CoM; "hip": at the hip joint
    # Outcome thresholds.
    foot_pitch_limit: float = 0.05  # rad
    foot_lift_limit: float = 0.005  # m
    bound_violation_limit: float = 0.05  # rad beyond a state bound
    lower_tilt_limit: float = 0.5  # rad
    settle_angle_tol: float = 0.01  # rad
    settle_rate_tol: float = 0.05  # rad/s
    controller_delay: float = 0.0  # s; the controller sees the state this late
    # s; the measurement is really this much later than controller_delay, which is what a
    # delay-compensated controller assumes (mismatch studies; 0: it knows its delay exactly)
    delay_error: float = 0.0
    # A run from an initial state (lean and release, the basin) starts with relaxed muscles:
    # the controller's measurements before t = 0 are upright rest, so it first acts on the
    # released state one controller_delay later (the onset latency; its inputs start from 0,
    # as every run's). False: it has seen the initial state all along (a push starts from rest,
    # where the two are one). Left out of a configuration's files when false.
    relaxed_start: bool = field(default=False, metadata={"omit_default": True})
    # A push that rises linearly from 0 to its force over push_ramp seconds, then holds (a pull
    # loaded gradually, as a spring-scale test's; people's protocols, docs/people.md). 0: a
    # step, the study's push. Data of the compiled program; left out of files when 0.
    push_ramp: float = field(default=0.0, metadata={"omit_default": True})

    def __post_init__(self) -> None:
        _check_types("scenario", self)
        check_finite("scenario", self)
        _check_positive(
            "scenario",
            self,
            (
                "t_end",
                "physics_dt",
                "control_dt",
                "foot_pitch_limit",
                "foot_lift_limit",
                "bound_violation_limit",
                "lower_tilt_limit",
                "settle_angle_tol",
                "settle_rate_tol",
            ),
        )
        if self.physics_dt > MAX_PHYSICS_DT:
            fail(
                "scenario",
                "physics_dt",
                f"must be <= {MAX_PHYSICS_DT:g} s (half the contact time constant, 0.02 s, "
                "for a stable contact)",
                self.physics_dt,
            )
        if self.duration < 0:
            fail("scenario", "duration", "must be >= 0", self.duration)
        if self.duration > self.t_end:
            fail("scenario", "duration", f"must not exceed t_end = {self.t_end}", self.duration)
        if not 0 <= self.push_ramp <= self.t_end:
            fail(
                "scenario", "push_ramp", f"must lie in [0, t_end = {self.t_end}] s", self.push_ramp
            )
        self._check_steps()
        if self.push_body not in ("upper", "hip"):
            fail("scenario", "push_body", "must be 'upper' or 'hip'", self.push_body)
        self._check_delay()

    def _check_steps(self) -> None:
        """Check the window's step counts: within int32, whole multiples of the time steps."""
        # Step counts are int32 on the device: a window of more steps cannot be indexed (and
        # 1e308 s would overflow Python's round() below).
        for name in ("t_end", "controller_delay"):
            if getattr(self, name) / self.physics_dt > MAX_STEPS:
                fail(
                    "scenario",
                    name,
                    f"must be at most {MAX_STEPS:,} physics steps "
                    f"(physics_dt = {self.physics_dt:g} s)",
                    getattr(self, name),
                )
        if self.controller_delay >= self.t_end:
            fail(
                "scenario",
                "controller_delay",
                f"must be shorter than t_end = {self.t_end:g} "
                "s (the controller would never see a measurement)",
                self.controller_delay,
            )
        ratio = self.control_dt / self.physics_dt
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            fail(
                "scenario",
                "control_dt",
                f"must be a whole multiple of physics_dt = {self.physics_dt}",
                self.control_dt,
            )
        steps = self.t_end / self.control_dt
        if abs(steps - round(steps)) > 1e-6:
            fail(
                "scenario",
                "t_end",
                f"must be a whole multiple of control_dt = {self.control_dt}",
                self.t_end,
            )

    def _check_delay(self) -> None:
        """Check the controller's delay and its error: whole physics steps, not negative."""
        if self.controller_delay < 0:
            fail("scenario", "controller_delay", "must be >= 0", self.controller_delay)
        for name in ("controller_delay", "delay_error"):
            steps = getattr(self, name) / self.physics_dt
            if abs(steps - round(steps)) > 1e-6:
                fail(
                    "scenario",
                    name,
                    f"must be a whole multiple of physics_dt = {self.physics_dt}",
                    getattr(self, name),
                )
        if self.controller_delay + self.delay_error < -1e-12:
            fail(
                "scenario",
                "delay_error",
                "must be >= -controller_delay (the measurement cannot come from the future)",
                self.delay_error,
            )

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return int(round(self.control_dt / self.physics_dt))

    @property
    def n_control(self) -> int:
        """Control periods in one scenario."""
        return int(round(self.t_end / self.control_dt))

    @property
    def ramp_steps(self) -> int:
        """Physics steps over which a push rises to its force (0: a step)."""
        return int(round(self.push_ramp / self.physics_dt))

    def ramp_factor(self, i: int) -> float:
        """The share of the force a push applies at physics step i (i = 0 first): (i + 1) / the
        ramp's steps, at most 1 (1 throughout without a ramp)."""
        return 1.0 if self.ramp_steps == 0 else min((i + 1) / self.ramp_steps, 1.0)

    @property
    def delay_steps(self) -> int:
        """How old the controller's measurement really is, in physics steps (controller_delay
        + delay_error)."""
        return int(round((self.controller_delay + self.delay_error) / self.physics_dt))

    @property
    def assumed_delay_steps(self) -> int:
        """The delay a compensating controller predicts over (controller_delay), in steps."""
        return int(round(self.controller_delay / self.physics_dt))


@dataclass(frozen=True)
class Config:
    """Everything one run needs: the body, the controller and the scenario.

    Frozen: ``.replace(body={...}, controller={...}, scenario={...})`` returns a changed copy
    with every value checked; ``to_dict()`` gives the nested plain values (docs/model.md).

    Attributes:
        body: The body (``BodyParams``): segments, foot, contact, strength's stepping data.
        controller: The MPC (``ControllerParams``): convention, horizon, weights, bounds,
            solver.
        scenario: The push and the run (``ScenarioParams``): window, time steps, delay, push
            point.
    """

    body: BodyParams = field(default_factory=BodyParams)
    controller: ControllerParams = field(default_factory=ControllerParams)
    scenario: ScenarioParams = field(default_factory=ScenarioParams)

    def __post_init__(self) -> None:
        check_linked_limits(self)
        if self.controller.offset_free and self.scenario.delay_steps > 0:
            raise ParameterError(
                "controller.offset_free = true with scenario.controller_delay (or delay_error) "
                "> 0 is not supported: the observer compares each measurement with the model's "
                "prediction from the previous one and the input applied since, which a delayed "
                "measurement does not match; set controller_delay = 0 or offset_free = false"
            )

    def replace(self, **sections: Any) -> "Config":
        """Return a copy with fields replaced, e.g. ``cfg.replace(controller={"horizon": 10})``.
        A person's body goes on a configuration through ``Subject.config`` (model/subject.py;
        ``subject.with_sections`` takes a ``subject`` table beside the sections)."""
        updated = {}
        for name, changes in sections.items():
            if name not in ("body", "controller", "scenario"):
                raise ParameterError(f"unknown section {name!r}")
            current = getattr(self, name)
            updated[name] = build_section(
                type(current), name, {**dataclasses.asdict(current), **changes}
            )
        return dataclasses.replace(self, **updated)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """The configuration as nested plain values; an optional field left at None (e.g.
        ``body.lower_inertia``) is left out, as in a TOML file that does not give it, and so is
        a field marked ``omit_default`` at its default (a setting added later: the files and
        folders of configurations that do not use it read as before)."""
        out = {}
        for name in ("body", "controller", "scenario"):
            section = getattr(self, name)
            out[name] = {
                f.name: (
                    {k: (list(t) if isinstance(t, tuple) else t) for k, t in v}
                    if f.metadata.get("table")
                    else (list(v) if isinstance(v, tuple) else v)
                )
                for f in fields(section)
                if (v := getattr(section, f.name)) is not None
                and not (f.metadata.get("omit_default") and v == f.default)
            }
        return out


# -- linked limits --------------------------------------------------------------------------
# Rules between values of different records, checked for every configuration (Config's
# construction): a contradiction is an error naming both values; a limit that can never bind
# is a warning (ParameterWarning, the log, and the output folder's manifest, config_warnings).
EDGE_TOL = 1e-9  # m: a bound this close to the sole's edge counts as on it (float error)
# the bounds whose quantity is 0 at upright rest (inputs and the convention's angles)
REST_INSIDE = (
    ("input1_bounds", "N m"),
    ("input2_bounds", "N m"),
    ("state1_bounds", "rad"),
    ("state2_bounds", "rad"),
)


def check_linked_limits(config: Config) -> None:
    """Refuse a configuration whose limits contradict each other (the message names both
    values) and warn for a limit that can never bind (:func:`config_warnings`)."""
    body, ctrl = config.body, config.controller
    heel, toe = body.sole_edges
    for name, what in (("cop_bounds", "CoP"), ("com_bounds", "CoM")):
        low, high = getattr(ctrl, name)
        if low > toe + EDGE_TOL or high < heel - EDGE_TOL:
            raise ParameterError(
                f"controller.{name} = [{low:g}, {high:g}] m lies wholly outside the sole of "
                f"body.foot_length = {body.foot_length:g} m ({sole_text(body)}): the "
                f"upright body's {what} (x = 0) breaks it at rest, so no run means anything; "
                f"bring the bounds onto the sole or lengthen the foot"
            )
    for name, unit in REST_INSIDE:
        low, high = getattr(ctrl, name)
        if not low <= 0 <= high:
            raise ParameterError(
                f"controller.{name} = [{low:g}, {high:g}] {unit} excludes 0, its value at the "
                "upright rest the model is linearised about: the body cannot stand at rest "
                "under it, so no run means anything; give it a range that contains 0"
            )
    (a1, b1), (a2, b2) = ctrl.input1_bounds, ctrl.input2_bounds
    if a1 == b1 and a2 == b2:
        raise ParameterError(
            f"controller.input1_bounds = [{a1:g}, {b1:g}] N m and controller.input2_bounds = "
            f"[{a2:g}, {b2:g}] N m: neither input has any range, so the controller cannot act "
            "on any push; give at least one of them a range"
        )
    for message in config_warnings(config):
        warn_parameter(message)


def sole_text(body: BodyParams) -> str:
    """ "its edges at +-0.15 m" (the study's centred foot) or "heel at -0.05 m, toe at 0.2 m"."""
    heel, toe = body.sole_edges
    if body.ankle_position == 0.5:
        return f"its edges at +-{toe:g} m"
    return f"heel at {heel:g} m, toe at {toe:g} m from the ankle"


def config_warnings(config: Config) -> list[str]:
    """The limits of ``config`` that can never bind, one sentence each (empty: none). Recorded
    in an output folder's manifest (``config_warnings``)."""
    body, ctrl = config.body, config.controller
    heel, toe = body.sole_edges
    low, high = ctrl.cop_bounds
    out = []
    if low < heel - EDGE_TOL or high > toe + EDGE_TOL:
        out.append(
            f"controller.cop_bounds = [{low:g}, {high:g}] m reaches beyond the sole of "
            f"body.foot_length = {body.foot_length:g} m ({sole_text(body)}): "
            "the CoP cannot leave the sole (the foot tips first), so the bound can never "
            "bind beyond the edge"
        )
    return out


_WARNED: set[str] = set()


def warn_parameter(message: str) -> None:
    """A ParameterWarning, and the same sentence in the log once (per process, or per command
    line: :func:`forget_warnings`)."""
    warnings.warn(message, ParameterWarning, stacklevel=4)
    if message not in _WARNED:
        _WARNED.add(message)
        log.warning("warning: %s", message)


def forget_warnings() -> None:
    """Log each never-binding limit again the next time it is found (the command line calls
    this as each command starts, so that every command says its own)."""
    _WARNED.clear()


SECTIONS = {"body": BodyParams, "controller": ControllerParams, "scenario": ScenarioParams}


def plain(value: Any) -> Any:
    """A NumPy scalar (or a list or array of them) as the Python value it holds, so that a
    configuration built from arrays is read as the same numbers (numpy is not imported)."""
    if type(value).__module__ == "numpy" and hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return type(value)(plain(v) for v in value)
    return value


def build_section(cls: type, section: str, values: dict[str, Any]) -> Any:
    values = {key: plain(value) for key, value in values.items()}
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ParameterError(
            f"{section}: unknown key(s) {', '.join(unknown)}; known keys: {', '.join(known)}"
        )
    coerced = {}
    for key, value in values.items():
        default = known[key].default
        if known[key].metadata.get("table"):
            value = as_table(section, key, value)
        elif isinstance(default, tuple) or (
            default is None and value is not None and known[key].metadata.get("pair")
        ):
            if not isinstance(value, (list, tuple)):
                raise ParameterError(f"{section}.{key} = {value!r}: must be a list of numbers")
            value = tuple(value)
        elif isinstance(default, bool):
            if not isinstance(value, bool):
                raise ParameterError(f"{section}.{key} = {value!r}: must be true or false")
        elif isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        elif isinstance(default, (int, float)) and not isinstance(default, bool):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParameterError(f"{section}.{key} = {value!r}: must be a number")
        elif isinstance(default, str) and not isinstance(value, str):
            raise ParameterError(f"{section}.{key} = {value!r}: must be a string")
        elif default is None and value is not None:
            if not is_number(value):
                raise ParameterError(f"{section}.{key} = {value!r}: must be a number")
            value = float(value)
        coerced[key] = value
    return cls(**coerced)
