"""MuJoCo model of the three-segment body, generated from BodyParams (docs/model.md, "Body").

The foot is free in the sagittal plane (slide x, slide z, pitch about y at the sole centre O)
and touches the floor through four load-cell spheres at the sole corners. The lower body hangs
on the ankle hinge, the upper body on the hip hinge; each hinge has a torque motor (gear 1).

With ``hip_servo_stiffness`` or ``hip_servo_damping`` > 0 (BodyParams) the hip hinge gets
MuJoCo's joint ``stiffness`` (springref 0) and ``damping``: a stiff position servo in the plant.

``mjcf(body, physics_dt)`` returns the MJCF text; ``build_model`` compiles it. With
``foot="fixed"`` the foot has no joints (welded flat to the world): that copy is what the
linearisation is checked against. The default model ships as ``data/balance.xml``.
"""

from __future__ import annotations

from importlib import resources
from typing import NamedTuple

import mujoco
import numpy as np

from ..runtime.version import check_mujoco
from .params import BodyParams

FOOT_JOINTS = ("foot_x", "foot_z", "foot_pitch")
LOAD_CELLS = ("cell_front_left", "cell_front_right", "cell_back_left", "cell_back_right")


def foot_diaginertia(b: BodyParams) -> tuple[float, float, float]:
    """The foot's (roll, pitch, yaw) inertias about its CoM: the slab's, with the pitch
    ``b.foot_pitch_inertia``."""
    roll, pitch, yaw = (
        b.foot_mass * (b.foot_width**2 + b.foot_thickness**2) / 12,
        b.foot_pitch_inertia,
        b.foot_mass * (b.foot_length**2 + b.foot_width**2) / 12,
    )
    if b.foot_inertia is not None:
        # A given pitch inertia (e.g. a subject's, below the slab's) with the slab's roll and
        # yaw can break MuJoCo's triangle inequality; only the pitch acts in the plane, so the
        # yaw or roll is moved where it is broken (1 % inside it, clear of rounding).
        if roll + pitch < yaw:
            yaw = 0.99 * (roll + pitch)
        if roll + yaw < pitch:
            roll = 1.01 * (pitch - yaw)
    return roll, pitch, yaw


def mjcf(body: BodyParams = BodyParams(), physics_dt: float = 0.002, foot: str = "free") -> str:
    """MJCF text of the body. ``foot`` is "free" (planar joints, contacts) or "fixed"."""
    if foot not in ("free", "fixed"):
        raise ValueError(f"foot must be 'free' or 'fixed', got {foot!r}")
    b = body
    r = b.contact_radius
    hx, hy = b.foot_length / 2, b.foot_width / 2
    foot_inertia = foot_diaginertia(b)
    # Rods: only the pitch inertia matters in the plane; the other axes get the same value
    # (a rod's roll inertia) and a small yaw value that keeps MuJoCo's triangle inequality.
    lower_i = (b.lower_pitch_inertia, b.lower_pitch_inertia, 1e-3 * b.lower_pitch_inertia)
    upper_i = (b.upper_pitch_inertia, b.upper_pitch_inertia, 1e-3 * b.upper_pitch_inertia)
    foot_joints = ""
    if foot == "free":
        foot_joints = (
            '      <joint name="foot_x" type="slide" axis="1 0 0"/>\n'
            '      <joint name="foot_z" type="slide" axis="0 0 1"/>\n'
            '      <joint name="foot_pitch" type="hinge" axis="0 1 0"/>\n'
        )
    # the sole's centre ahead of the ankle (0 for the study's centred foot: the same text)
    cx = (0.5 - b.ankle_position) * b.foot_length
    cells = "".join(
        f'      <geom name="{name}" class="load_cell" pos="{cx + sx * hx:.6g} {sy * hy:.6g} {r:.6g}"/>\n'
        for name, sx, sy in zip(LOAD_CELLS, (1, 1, -1, -1), (1, -1, 1, -1))
    )

    hip_servo = ""
    if b.hip_servo_stiffness > 0 or b.hip_servo_damping > 0:
        # the hip servo (BodyParams): passive spring about q_h = 0 plus viscous damping
        hip_servo = (
            f' stiffness="{b.hip_servo_stiffness:.9g}" springref="0"'
            f' damping="{b.hip_servo_damping:.9g}"'
        )

    def fmt(values: tuple[float, ...]) -> str:
        return " ".join(f"{v:.9g}" for v in values)

    return f"""<mujoco model="three_link_balance">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{physics_dt:.9g}" gravity="0 0 {-b.gravity:.9g}" integrator="Euler"/>
  <default>
    <geom contype="0" conaffinity="0" rgba="0.8 0.6 0.4 1"/>
    <default class="load_cell">
      <geom type="sphere" size="{r:.6g}" contype="1" conaffinity="0" condim="3"
            friction="{b.friction:.6g} 0.005 0.0001" rgba="0.9 0.2 0.2 1"/>
    </default>
  </default>
  <worldbody>
    <light pos="0 -3 3" dir="0 1 -1"/>
    <geom name="floor" type="plane" size="3 3 0.1" contype="0" conaffinity="1" condim="3"
          friction="{b.friction:.6g} 0.005 0.0001" rgba="0.85 0.85 0.85 1"/>
    <body name="foot" pos="0 0 0">
{foot_joints}      <inertial pos="0 0 {b.foot_thickness / 2:.9g}" mass="{b.foot_mass:.9g}" diaginertia="{fmt(foot_inertia)}"/>
      <geom name="sole" type="box" size="{hx:.6g} {hy:.6g} {b.foot_thickness / 2:.6g}" pos="{cx:.6g} 0 {b.foot_thickness / 2:.6g}" rgba="0.3 0.3 0.3 1"/>
{cells}      <body name="lower" pos="0 0 {b.ankle_height:.9g}">
        <joint name="ankle" type="hinge" axis="0 1 0"/>
        <inertial pos="0 0 {b.lower_com:.9g}" mass="{b.lower_mass:.9g}" diaginertia="{fmt(lower_i)}"/>
        <geom name="lower_rod" type="capsule" fromto="0 0 0 0 0 {b.lower_length:.9g}" size="0.04"/>
        <body name="upper" pos="0 0 {b.lower_length:.9g}">
          <joint name="hip" type="hinge" axis="0 1 0"{hip_servo}/>
          <inertial pos="0 0 {b.upper_com:.9g}" mass="{b.upper_mass:.9g}" diaginertia="{fmt(upper_i)}"/>
          <geom name="upper_rod" type="capsule" fromto="0 0 0 0 0 {b.upper_length:.9g}" size="0.05"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="ankle_motor" joint="ankle" gear="1"/>
    <motor name="hip_motor" joint="hip" gear="1"/>
  </actuator>
</mujoco>
"""


def build_model(
    body: BodyParams = BodyParams(), physics_dt: float = 0.002, foot: str = "free"
) -> mujoco.MjModel:
    """Compile the generated MJCF. Every physics path starts here or at ``rollout.physics``: a
    mismatched mujoco / mujoco-mjx pair is refused first (``runtime.version.check_mujoco``)."""
    check_mujoco()
    return mujoco.MjModel.from_xml_string(mjcf(body, physics_dt, foot))


def default_model_path() -> str:
    """Path of the shipped default model (opens in MuJoCo's viewer)."""
    return str(resources.files("mjx_balance") / "data" / "balance.xml")


class Indices(NamedTuple):
    """Addresses into qpos/qvel/bodies/geoms of a free-foot model."""

    foot_x: int
    foot_z: int
    foot_pitch: int
    ankle_qpos: int
    hip_qpos: int
    ankle_dof: int
    hip_dof: int
    foot_body: int
    lower_body: int
    upper_body: int
    floor_geom: int
    cell_geoms: tuple[int, ...]


def indices(model: mujoco.MjModel) -> Indices:
    def jnt(name: str) -> int:
        return int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])

    def dof(name: str) -> int:
        return int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])

    def bid(name: str) -> int:
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))

    def gid(name: str) -> int:
        return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name))

    return Indices(
        foot_x=jnt("foot_x"),
        foot_z=jnt("foot_z"),
        foot_pitch=jnt("foot_pitch"),
        ankle_qpos=jnt("ankle"),
        hip_qpos=jnt("hip"),
        ankle_dof=dof("ankle"),
        hip_dof=dof("hip"),
        foot_body=bid("foot"),
        lower_body=bid("lower"),
        upper_body=bid("upper"),
        floor_geom=gid("floor"),
        cell_geoms=tuple(gid(n) for n in LOAD_CELLS),
    )


def settled_rest(model: mujoco.MjModel, seconds: float = 1.0) -> np.ndarray:
    """qpos of upright rest after the contact has settled: ``seconds`` of MuJoCo C with zero
    torques from qpos = 0, where the foot merely touches the floor (its load cells carry no
    force yet; the sole then sinks 0.27 mm into the soft contact within ~0.1 s).

    A scenario that starts away from rest (``reference.simulate_scenario(initial=...)``, the
    batched engine's initial states: the recovery basin) starts with this foot, so that the
    controller's first torques act on a loaded foot; from qpos = 0 they would spin the unloaded
    foot (1.3 kg) in the first steps. Push scenarios keep starting at qpos = 0."""
    data = mujoco.MjData(model)
    for _ in range(int(round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
    return data.qpos.copy()
