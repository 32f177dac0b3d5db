"""The measurements read out of ``mjx.Data``: one home for what the closed loop, the outcome
rules and the C path read from an MJX state.

A sample is read after every physics step, at t = (i+1) dt (``physics.py`` says when positions
are current): the joint angles and rates, the load-cell CoP (:func:`load_cell_cop`), the
whole-body CoM and its velocity, the load-cell heights and the margins of stability, read with
the static addresses of :class:`Sensors`. ``arrays`` below is the closed loop's
``kernel.Arrays`` (its model ``mx``, rest state ``d0`` and convention map ``to_state``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from ..measures import outcomes
from ..model.mjcf import indices

if TYPE_CHECKING:  # (annotations only: the model and data types)
    from mujoco import mjx


class Sensors(NamedTuple):
    """Static (numpy) addresses for reading a sample out of mjx.Data."""

    joints_q: np.ndarray  # [2] qpos addresses of ankle, hip
    joints_v: np.ndarray  # [2] dof addresses of ankle, hip
    foot_pitch: int  # qpos address
    upper_body: int
    subtree: np.ndarray  # [k] bodies of the foot's subtree (the whole body)
    cells: np.ndarray  # [4] load-cell geoms
    cell_radius: np.ndarray  # [4]
    cell_contacts: np.ndarray  # [c] contacts that involve a load cell
    contact_efc: np.ndarray  # [c, w] their efc rows (pyramid edges)


def sensors(model: mujoco.MjModel, d0: mjx.Data) -> Sensors:
    """Addresses of ``model``; the contact layout (fixed in MJX) is read from ``d0``."""
    if model.opt.cone != mujoco.mjtCone.mjCONE_PYRAMIDAL:
        raise ValueError("the load-cell CoP reads pyramidal contact forces; use cone=pyramidal")
    ix = indices(model)
    contact = d0._impl.contact
    geom = np.asarray(contact.geom)
    dim = np.asarray(contact.dim)
    efc_address = np.asarray(contact.efc_address)
    cells = np.array(ix.cell_geoms)
    ids, rows = [], []
    for c in range(geom.shape[0]):
        if np.isin(geom[c], cells).any() and efc_address[c] >= 0:
            # pyramidal cone: 2 (condim - 1) edges whose sum is the normal force
            width = 1 if dim[c] == 1 else 2 * (int(dim[c]) - 1)
            ids.append(c)
            rows.append(efc_address[c] + np.arange(width))
    if not rows or len({len(r) for r in rows}) != 1:
        raise ValueError("expected load-cell contacts, all of one dimension")
    body_ids = np.arange(model.nbody)
    in_subtree = np.array([_is_descendant(model, b, ix.foot_body) for b in body_ids])
    return Sensors(
        joints_q=np.array([ix.ankle_qpos, ix.hip_qpos]),
        joints_v=np.array([ix.ankle_dof, ix.hip_dof]),
        foot_pitch=ix.foot_pitch,
        upper_body=ix.upper_body,
        subtree=body_ids[in_subtree],
        cells=cells,
        cell_radius=np.asarray(model.geom_size[cells, 0]),
        cell_contacts=np.array(ids),
        contact_efc=np.stack(rows),
    )


def _is_descendant(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body != root and body > 0:
        body = int(model.body_parentid[body])
    return body == root


def load_cell_cop(d: mjx.Data, sensors: Sensors) -> tuple[jax.Array, jax.Array]:
    """(CoP x, total normal force) of the load-cell contacts acting in ``d``.

    As ``metrics.load_cell_cop``: sum F_i x_i / sum F_i, F_i the normal force of a pyramidal
    contact (the sum of its edge forces, as ``mj_contactForce`` decodes it), x_i the contact
    point found by the step's collision. NaN when the load cells carry nothing.
    """
    normal = d._impl.efc_force[sensors.contact_efc].sum(axis=-1)
    x = d._impl.contact.pos[sensors.cell_contacts, 0]
    total = normal.sum()
    loaded = total > 0
    cop = jnp.where(loaded, (normal * x).sum() / jnp.where(loaded, total, 1.0), jnp.nan)
    return cop.astype(normal.dtype), total


def whole_body_com(mx: mjx.Model, d: mjx.Data, sensors: Sensors) -> jax.Array:
    """Horizontal CoM of the foot's subtree from the current body positions (subtree_com x)."""
    mass = mx.body_mass[sensors.subtree]
    return (mass * d.xipos[sensors.subtree, 0]).sum() / mass.sum()


def cell_heights(mx: mjx.Model, d: mjx.Data, sensors: Sensors) -> jax.Array:
    """Lowest point (centre z - radius) of each load-cell sphere [4]."""
    return d.geom_xpos[sensors.cells, 2] - mx.geom_size[sensors.cells, 0]


class Sample(NamedTuple):
    """What is read after one physics step (positions at t = (i+1) dt)."""

    q: jax.Array  # [2] joint angles (ankle, hip)
    dq: jax.Array  # [2] joint rates
    x: jax.Array  # [4] the convention state
    pitch: jax.Array  # foot pitch
    cell_low: jax.Array  # [4] lowest point of each load-cell sphere
    cop: jax.Array  # load-cell CoP x (NaN when unloaded)
    com: jax.Array  # whole-body CoM x
    magnitude: jax.Array  # largest |value| of qpos, qvel, qacc and ctrl (NaN if any is NaN)
    # (defaults: a sample built without them has NaN CoM velocity and margins)
    qvel: Any = None  # [nv] all rates (for the CoM velocity)
    com_vel: Any = math.nan  # whole-body CoM x velocity
    mos_toe: Any = math.nan  # margins of stability (outcomes.stability_margins)
    mos_heel: Any = math.nan
    xcom: Any = math.nan  # extrapolated CoM, the capture point (outcomes.stability_margins)


def joints(sensors: Sensors, d: mjx.Data) -> tuple[jax.Array, jax.Array]:
    """Joint angles and rates (ankle, hip)."""
    return d.qpos[sensors.joints_q], d.qvel[sensors.joints_v]


def state(arrays: Any, q: jax.Array, dq: jax.Array) -> jax.Array:
    """The convention state x [4] of joint angles and rates."""
    return jnp.concatenate([arrays.to_state @ q, arrays.to_state @ dq])


def measure(arrays: Any, sensors: Sensors, d: mjx.Data) -> Sample:
    """The sample of ``d`` right after :func:`physics.advance` (positions at the new time)."""
    return with_positions(measure_step(arrays, sensors, d), arrays, sensors, d)


def measure_step(arrays: Any, sensors: Sensors, d: mjx.Data) -> Sample:
    """The sample of ``d`` right after :func:`physics.step`, without what needs the positions at
    the new time (``cell_low`` and ``com`` are NaN; :func:`with_positions` fills them in)."""
    q, dq = joints(sensors, d)
    cop, _ = load_cell_cop(d, sensors)
    nan = jnp.full((), jnp.nan, d.qpos.dtype)
    return Sample(
        q=q,
        dq=dq,
        x=state(arrays, q, dq),
        pitch=d.qpos[sensors.foot_pitch],
        cell_low=jnp.full((sensors.cells.shape[0],), nan),
        cop=cop,
        com=nan,
        magnitude=jnp.max(jnp.abs(jnp.concatenate([d.qpos, d.qvel, d.qacc, d.ctrl]))),
        qvel=d.qvel,
        com_vel=nan,
        mos_toe=nan,
        mos_heel=nan,
    )


def with_positions(s: Sample, arrays: Any, sensors: Sensors, d: mjx.Data) -> Sample:
    """``s`` with the load-cell heights, the CoM, its velocity (from ``s.qvel``) and the
    margins of stability of the body and geom positions in ``d``."""
    com = whole_body_com(arrays.mx, d, sensors)
    com_vel = com_velocity(arrays.mx, d, sensors, s.qvel)
    xcom, mos_toe, mos_heel = margins(arrays, sensors, com, com_vel, d.geom_xpos[sensors.cells, 0])
    return s._replace(
        cell_low=cell_heights(arrays.mx, d, sensors),
        com=com,
        com_vel=com_vel,
        mos_toe=mos_toe,
        mos_heel=mos_heel,
        xcom=xcom,
    )


def com_velocity(mx: mjx.Model, d: mjx.Data, sensors: Sensors, qvel: jax.Array) -> jax.Array:
    """Horizontal velocity of the whole-body CoM (the foot's subtree): sum over its bodies of
    m_b J_b qvel / M, J_b the Jacobian of the body's CoM (xipos) from the joint axes and
    anchors of the positions in ``d`` (``mjx.kinematics``), as ``mj_jacSubtreeCom`` times
    qvel in the reference. Slide and hinge joints only."""
    bodies = np.asarray(sensors.subtree)
    mass = mx.body_mass[bodies]
    total = jnp.zeros((), qvel.dtype)
    for j in range(int(mx.njnt)):
        moved = np.array([_moves(mx, int(mx.jnt_bodyid[j]), int(b)) for b in bodies])
        if not moved.any():
            continue
        dof, kind = int(mx.jnt_dofadr[j]), int(mx.jnt_type[j])
        weight = mass[moved]
        if kind == int(mujoco.mjtJoint.mjJNT_SLIDE):
            velocity = d.xaxis[j] * weight.sum()
        elif kind == int(mujoco.mjtJoint.mjJNT_HINGE):
            lever = (weight[:, None] * (d.xipos[bodies[moved]] - d.xanchor[j])).sum(axis=0)
            velocity = jnp.cross(d.xaxis[j], lever)
        else:
            raise ValueError("the CoM velocity supports slide and hinge joints only")
        total = total + velocity[0] * qvel[dof]
    return (total / mass.sum()).astype(qvel.dtype)


def _moves(mx: mjx.Model, joint_body: int, body: int) -> bool:
    """Whether a joint of ``joint_body`` moves ``body`` (it is that body or a descendant)."""
    while body != joint_body and body > 0:
        body = int(mx.body_parentid[body])
    return body == joint_body


def pendulum_frequency(arrays: Any, sensors: Sensors) -> jax.Array:
    """omega0 = sqrt(g / l), l the whole-body CoM's height above the ankle axis at upright
    rest (``arrays.d0``), as ``metrics.pendulum_frequency``."""
    mass = arrays.mx.body_mass[sensors.subtree]
    com_z = (mass * arrays.d0.xipos[sensors.subtree, 2]).sum() / mass.sum()
    ankle = int(arrays.mx.dof_jntid[int(sensors.joints_v[0])])
    return jnp.sqrt(jnp.abs(arrays.mx.opt.gravity[2]) / (com_z - arrays.d0.xanchor[ankle, 2]))


def margins(
    arrays: Any, sensors: Sensors, com: jax.Array, com_vel: jax.Array, cell_x: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(XcoM, toe margin, heel margin) of a sample from its CoM, CoM velocity and the load-cell
    centres' x [4] (outcomes.support_edges, outcomes.stability_margins)."""
    heel, toe = outcomes.support_edges(jnp, cell_x)
    dtype = com.dtype
    return tuple(
        v.astype(dtype)
        for v in outcomes.stability_margins(
            jnp, com, com_vel, heel, toe, pendulum_frequency(arrays, sensors).astype(dtype)
        )
    )
