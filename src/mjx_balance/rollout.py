"""Batched closed loop: MJX physics + the batched ADMM MPC, one fused ``lax.scan`` per scenario.

One scenario (shared definitions, ``metrics.py``) is a pure function of (force, push steps):

    for k in 0..n_control-1:                       # outer lax.scan, control periods
        x_k = state_from_joints(measured joints)   # ``controller_delay`` earlier if set
        u_k = admm_solve(x_k, warm_k)              # warm_{k+1} = its shifted solution
        for j in 0..substeps-1:                    # inner lax.scan, physics steps i = k S + j
            xfrc_applied[upper] = [F, 0, 0, ...] if i < n_push
            mjx.step; mjx.kinematics               # positions at t = (i+1) dt
            sample -> accumulators                 # masked from the first fall sample on

The per-scenario summary (outcome, settle/fall step, peaks, CoP/CoM extremes, saturation
counts, energies, solver statistics) lives in the scan carry (:class:`Accumulators`), so a batch
never stores trajectories unless asked (``trajectories=True``). Batching is one ``jax.vmap`` in
:meth:`BatchRunner._batched`; everything else is written for a single scenario.

Fall / divergence. From the first fall sample (or non-finite value) on, nothing accumulates. The
scenario keeps stepping (a batch runs in lock-step), but at the next control instant its physics
state is reset to upright rest and the controller is fed x = 0 from a cold start, so a dead
scenario costs no extra ADMM or contact-solver iterations (``while_loop`` under ``vmap`` runs
until the slowest element is done) and cannot produce NaN.

Times are carried as integer step indices and turned into seconds on the host in float64, so
``fall_time`` and ``settle_time`` are exactly (i + 1) dt as in the reference.

MJX options (:data:`MJX_OPTIONS`), chosen for speed on the CPU and justified by the agreement
tests in tests/test_rollout.py:

- Newton solver (MuJoCo's default, so the reference uses it too) with ``iterations = 4`` and
  ``ls_iterations = 8``. The contact problem is four sphere-plane contacts on a five-dof chain,
  warm-started from the previous step's accelerations; the C solver needs 1.06 iterations on
  average and at most 3 on a rocking-foot open-loop test (tests/test_rollout.py). With 3 or
  more iterations MJX matches ``mj_step`` as closely as with 100 (float32 rounding dominates);
  with 2 the rocking foot drifts by 0.2 rad in the hip within 1 s. The tolerance stays at
  MuJoCo's 1e-8, which float32 never meets, so every step runs the capped 4 iterations (under
  ``vmap`` the loop runs for the slowest element anyway); the 100-iteration default would cost
  ~2x for no gain.
- pyramidal friction cone (MuJoCo's default; the elliptic cone is ~2x slower in MJX).
- disabled: Euler damping, springs, dampers, friction loss, joint limits, equality constraints,
  control clamping -- the model has none of them, so these flags only skip dead code (springs,
  dampers and Euler damping stay on for a body with the hip servo, which has them).

Throughput measured on the 2-core CPU (shared with other jobs at the time, so +-40 %), 12-s
scenarios with pushes of 0-150 N for 0.05-0.3 s: 3-5 scenarios/s at batches of 64, 256 and
1024; compile 30-65 s per batch size. MJX physics alone runs 40-55k steps/s whatever the batch
(~7 scenarios/s); at batch 64 capping the ADMM at one 10-iteration chunk halves the run time,
so physics and controller take about half each. The controller's share comes from ``vmap``:
each control period's ADMM ``while_loop`` runs until the slowest scenario of the batch stops
(200 iterations whenever one of them faces an infeasible QP), while the mean over scenarios is
13-24 iterations per period.

Build and compile. The rest state comes from ``mj_forward`` in C (:func:`rest_data`; a jitted
``mjx.forward`` cost a 13-18 s compile per runner), so a runner is built in under a second.
The model, QP and ADMM data are traced arguments of the compiled function, which is cached per
shape key (:meth:`BatchRunner.compiled`): configurations that differ only in numbers (body,
convention, weights, bounds) share one compile. Several local devices: each batch is split over
them (:meth:`BatchRunner._batched`, shard_map over a 1-D mesh). Figures: BENCHMARKS.md.
"""

from __future__ import annotations

import contextlib
import functools
import io
import math
import time as _time
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pandas as pd

# mujoco.mjx prints "Failed to import warp" when its GPU-only Warp backend is not installed;
# the JAX implementation used here does not need it, so keep that line off the user's screen.
with contextlib.redirect_stdout(io.StringIO()):
    from mujoco import mjx

from . import admm as admm_mod
from . import metrics
from .linear import S as JOINT_TO_ABS
from .model import build_model, indices
from .params import Config
from .qp import build_qp

MJX_OPTIONS: dict[str, Any] = {
    "solver": int(mujoco.mjtSolver.mjSOL_NEWTON),
    "iterations": 4,
    "ls_iterations": 8,
    "cone": int(mujoco.mjtCone.mjCONE_PYRAMIDAL),
}

_DISABLE = (
    mujoco.mjtDisableBit.mjDSBL_EULERDAMP | mujoco.mjtDisableBit.mjDSBL_SPRING
    | mujoco.mjtDisableBit.mjDSBL_DAMPER
    | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS | mujoco.mjtDisableBit.mjDSBL_LIMIT
    | mujoco.mjtDisableBit.mjDSBL_EQUALITY | mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
)


# --------------------------------------------------------------------------------------------
# Model and dtype


def cast_floats(tree: Any, dtype) -> Any:
    """Cast every floating leaf (jax or numpy array) of a pytree to ``dtype``; others unchanged."""

    def cast(x):
        if isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jnp.floating):
            return x.astype(dtype)
        if isinstance(x, np.ndarray) and np.issubdtype(x.dtype, np.floating):
            return x.astype(dtype)
        return x

    return jax.tree_util.tree_map(cast, tree)


def mj_model(config: Config, options: dict[str, Any] | None = None) -> mujoco.MjModel:
    """The free-foot MuJoCo model of ``config`` with the MJX options applied (C side too)."""
    model = build_model(config.body, config.scenario.physics_dt, foot="free")
    opts = dict(MJX_OPTIONS if options is None else options)
    for name, value in opts.items():
        setattr(model.opt, name, value)
    disable = _DISABLE
    if (model.jnt_stiffness != 0).any() or (model.dof_damping != 0).any():
        # a body with the hip servo (BodyParams): keep its spring and damper, and Euler's
        # implicit damping, exactly as mj_step in the reference runs them
        disable &= ~(mujoco.mjtDisableBit.mjDSBL_EULERDAMP | mujoco.mjtDisableBit.mjDSBL_SPRING
                     | mujoco.mjtDisableBit.mjDSBL_DAMPER)
    model.opt.disableflags |= int(disable)
    return model


def mjx_model(model: mujoco.MjModel, dtype=jnp.float32) -> mjx.Model:
    """``mjx.put_model`` with every floating field cast to ``dtype``."""
    return cast_floats(mjx.put_model(model, impl="jax"), dtype)


def rest_data(model: mujoco.MjModel, dtype=jnp.float32) -> mjx.Data:
    """Upright rest (qpos = qvel = 0) with positions computed: ``mj_forward`` in C, then
    ``mjx.put_data``.

    Computing it with a jitted ``mjx.forward`` instead cost a 13-18 s compile per
    configuration (measured, 2-core CPU) for one call. The two differ only in fields that every
    ``mjx.step`` recomputes before use (the factor ``qLD`` and ``efc_D`` are laid out
    differently); one ``mjx.step`` from either gives bit-identical data (checked when this was
    changed), and the contact layout read by :func:`sensors` is the same.
    """
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    d = cast_floats(mjx.put_data(model, data, impl="jax"), dtype)
    # mjx.step builds some integer fields (the contacts' geom ids) in JAX's default integer width
    # (int64 under jax_enable_x64) where put_data writes int32: give every integer leaf the type
    # the step returns (traced abstractly, nothing compiled), so the state is a valid scan carry
    # either way. (Floating leaves are cast back to ``dtype`` after every step.)
    stepped = jax.eval_shape(mjx.step, mjx_model(model, dtype), d)

    def match(x, s):
        if jnp.issubdtype(x.dtype, jnp.integer) and x.dtype != s.dtype:
            return x.astype(s.dtype)
        return x

    return jax.tree_util.tree_map(match, d, stepped)


# --------------------------------------------------------------------------------------------
# Reading a sample out of mjx.Data


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
        foot_pitch=ix.foot_pitch, upper_body=ix.upper_body,
        subtree=body_ids[in_subtree], cells=cells,
        cell_radius=np.asarray(model.geom_size[cells, 0]),
        cell_contacts=np.array(ids), contact_efc=np.stack(rows),
    )


def _is_descendant(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body != root and body > 0:
        body = int(model.body_parentid[body])
    return body == root


def load_cell_cop(d: mjx.Data, sn: Sensors) -> tuple[jax.Array, jax.Array]:
    """(CoP x, total normal force) of the load-cell contacts acting in ``d``.

    As ``metrics.load_cell_cop``: sum F_i x_i / sum F_i, F_i the normal force of a pyramidal
    contact (the sum of its edge forces, as ``mj_contactForce`` decodes it), x_i the contact
    point found by the step's collision. NaN when the load cells carry nothing.
    """
    normal = d._impl.efc_force[sn.contact_efc].sum(axis=-1)
    x = d._impl.contact.pos[sn.cell_contacts, 0]
    total = normal.sum()
    loaded = total > 0
    cop = jnp.where(loaded, (normal * x).sum() / jnp.where(loaded, total, 1.0), jnp.nan)
    return cop.astype(normal.dtype), total


def whole_body_com(mx: mjx.Model, d: mjx.Data, sn: Sensors) -> jax.Array:
    """Horizontal CoM of the foot's subtree from the current body positions (subtree_com x)."""
    mass = mx.body_mass[sn.subtree]
    return (mass * d.xipos[sn.subtree, 0]).sum() / mass.sum()


def cell_heights(mx: mjx.Model, d: mjx.Data, sn: Sensors) -> jax.Array:
    """Lowest point (centre z - radius) of each load-cell sphere [4]."""
    return d.geom_xpos[sn.cells, 2] - mx.geom_size[sn.cells, 0]


def advance(mx: mjx.Model, sn: Sensors, d: mjx.Data, torques: jax.Array, force: jax.Array,
            push_at_hip: bool = False) -> mjx.Data:
    """One physics step with motor ``torques`` [2] and the push ``force`` [] (N, along x).

    The push acts on the upper body through ``xfrc_applied`` (a wrench at its CoM, xipos); at
    the hip it is the same force plus the moment (xpos - xipos) x F. After ``mjx.step`` the
    positions are refreshed (``mjx.kinematics``), so body/geom positions are those at the new
    time while the contacts and constraint forces stay those that acted during the step (as
    the reference leaves them after ``mj_step`` + ``mj_kinematics``).
    """
    dtype = d.qpos.dtype
    push = jnp.zeros(d.xfrc_applied.shape, dtype).at[sn.upper_body, 0].set(force)
    if push_at_hip:
        r = d.xpos[sn.upper_body] - d.xipos[sn.upper_body]
        moment = jnp.cross(r, jnp.stack([force, 0 * force, 0 * force]).astype(dtype))
        push = push.at[sn.upper_body, 3:].set(moment)
    d = d.replace(ctrl=torques.astype(dtype), xfrc_applied=push)
    d = mjx.step(mx, d)
    d = mjx.kinematics(mx, d)
    return cast_floats(d, dtype)


def open_loop(mx: mjx.Model, sn: Sensors, d0: mjx.Data, torques: jax.Array, force: jax.Array,
              n_push: jax.Array, push_at_hip: bool = False) -> dict[str, jax.Array]:
    """Physics only: motor ``torques`` [n, 2] applied at steps i = 0..n-1, the push on for
    i < n_push. Returns per-step samples at t = (i+1) dt: qpos [n, nq], qvel [n, nv], cop [n],
    com [n], cell_low [n, 4]. Jit with ``sn`` and ``push_at_hip`` static."""
    dtype = d0.qpos.dtype
    force = jnp.asarray(force, dtype)

    def body(d, inputs):
        i, tau = inputs
        d = advance(mx, sn, d, tau, jnp.where(i < n_push, force, 0 * force), push_at_hip)
        cop, _ = load_cell_cop(d, sn)
        return d, dict(qpos=d.qpos, qvel=d.qvel, cop=cop, com=whole_body_com(mx, d, sn),
                       cell_low=cell_heights(mx, d, sn))

    steps = jnp.arange(torques.shape[0], dtype=jnp.int32)
    return jax.lax.scan(body, d0, (steps, jnp.asarray(torques, dtype)))[1]


# --------------------------------------------------------------------------------------------
# One scenario


class Accumulators(NamedTuple):
    """The running summary of one scenario (scalars; steps are physics-step indices i)."""

    alive: jax.Array  # bool: not fallen and not diverged
    fell: jax.Array  # bool
    fall_step: jax.Array  # int32, -1 unless fell
    diverged: jax.Array  # bool
    last_outside: jax.Array  # int32, last step outside the settle band (-1: never)
    in_band: jax.Array  # bool, the latest sample is in the settle band
    peak_ankle: jax.Array
    peak_hip: jax.Array
    peak_foot_pitch: jax.Array
    cop_min: jax.Array
    cop_max: jax.Array
    com_min: jax.Array
    com_max: jax.Array
    peak_tau_ankle: jax.Array
    peak_tau_hip: jax.Array
    energy_ankle: jax.Array
    energy_hip: jax.Array
    work_ankle: jax.Array
    work_hip: jax.Array
    energy_u1: jax.Array
    energy_u2: jax.Array
    max_bound_violation: jax.Array
    control_periods: jax.Array  # int32, periods counted (started before the fall)
    saturated_ankle: jax.Array  # int32, counted periods with u[0] at a bound
    saturated_hip: jax.Array  # int32
    nonconverged_solves: jax.Array  # int32
    max_residual: jax.Array
    admm_iterations: jax.Array  # int32, total over counted periods

    @staticmethod
    def initial(dtype) -> "Accumulators":
        def f(v):
            return jnp.asarray(v, dtype)

        i0 = jnp.zeros((), jnp.int32)
        inf = math.inf
        return Accumulators(
            alive=jnp.asarray(True), fell=jnp.asarray(False), fall_step=i0 - 1,
            diverged=jnp.asarray(False), last_outside=i0 - 1, in_band=jnp.asarray(True),
            peak_ankle=f(-inf), peak_hip=f(-inf), peak_foot_pitch=f(-inf),
            cop_min=f(inf), cop_max=f(-inf), com_min=f(inf), com_max=f(-inf),
            peak_tau_ankle=f(-inf), peak_tau_hip=f(-inf),
            energy_ankle=f(0), energy_hip=f(0), work_ankle=f(0), work_hip=f(0),
            energy_u1=f(0), energy_u2=f(0), max_bound_violation=f(0),
            control_periods=i0, saturated_ankle=i0, saturated_hip=i0,
            nonconverged_solves=i0, max_residual=f(-inf), admm_iterations=i0,
        )


class Static(NamedTuple):
    """Everything about a configuration that is fixed under jit (hashable numbers/flags)."""

    n_control: int
    substeps: int
    delay_steps: int
    push_at_hip: bool
    settings: admm_mod.ADMMSettings
    trajectories: bool
    # thresholds and bounds (python floats)
    foot_pitch_limit: float
    foot_lift_limit: float
    bound_violation_limit: float
    lower_tilt_limit: float
    settle_angle_tol: float
    settle_rate_tol: float
    state_lower: tuple[float, float]
    state_upper: tuple[float, float]
    input_lower: tuple[float, float]
    input_upper: tuple[float, float]


class Arrays(NamedTuple):
    """Per-configuration arrays shared by every scenario of a batch (not vmapped)."""

    mx: mjx.Model
    d0: mjx.Data  # upright rest
    qp: admm_mod.ADMMData
    to_state: jax.Array  # [2, 2] convention positions y = to_state @ [q_a, q_h]
    torque_map: jax.Array  # [2, 2] [tau_ankle, tau_hip] = torque_map @ u


class Carry(NamedTuple):
    d: mjx.Data
    warm: admm_mod.ADMMWarm
    history: jax.Array  # [delay+1, 4] joint (q, dq), newest first
    q_prev: jax.Array  # [2] joint angles at the previous sample
    x_prev: jax.Array  # [4] convention state at the previous sample
    acc: Accumulators


def _select(pred: jax.Array, a: Any, b: Any) -> Any:
    return jax.tree_util.tree_map(lambda u, v: jnp.where(pred, u, v), a, b)


def scenario(ar: Arrays, sn: Sensors, st: Static, force: jax.Array,
             n_push: jax.Array) -> tuple[Accumulators, dict[str, jax.Array] | None]:
    """Run one scenario; pure, jit-able (``sn``, ``st`` static). force: [] N; n_push: [] int.

    Returns the final accumulators and, with ``st.trajectories``, per-physics-step series
    (qpos [n, nq], qvel [n, nv], tau [n, 2], u [n, 2], cop [n], com [n]; sample i is at
    t = (i+1) dt; NaN after the fall sample).
    """
    dtype = ar.d0.qpos.dtype
    force = jnp.asarray(force, dtype)
    n_push = jnp.asarray(n_push, jnp.int32)
    S = st.substeps
    s_lo = jnp.asarray(st.state_lower, dtype)
    s_hi = jnp.asarray(st.state_upper, dtype)
    u_lo = jnp.asarray(st.input_lower, dtype)
    u_hi = jnp.asarray(st.input_upper, dtype)
    sat_tol = metrics.SATURATION_TOL * (u_hi - u_lo)
    zero_warm = admm_mod.initial_warm(ar.qp)

    def joints(d):
        return d.qpos[sn.joints_q], d.qvel[sn.joints_v]

    def state(q, dq):
        return jnp.concatenate([ar.to_state @ q, ar.to_state @ dq])

    def physics_step(carry: Carry, i: jax.Array, torques: jax.Array, u: jax.Array):
        d, acc = carry.d, carry.acc
        f = jnp.where(i < n_push, force, jnp.zeros((), dtype))
        d = advance(ar.mx, sn, d, torques, f, st.push_at_hip)
        q, dq = joints(d)
        x = state(q, dq)
        pitch = d.qpos[sn.foot_pitch]
        low = cell_heights(ar.mx, d, sn)
        cop, _ = load_cell_cop(d, sn)
        com = whole_body_com(ar.mx, d, sn)
        excess = jnp.max(jnp.maximum(jnp.maximum(s_lo - x[:2], x[:2] - s_hi), 0))

        finite = (jnp.isfinite(q).all() & jnp.isfinite(dq).all() & jnp.isfinite(x).all()
                  & jnp.isfinite(torques).all())
        ok = acc.alive & finite
        falls = ((jnp.abs(pitch) > st.foot_pitch_limit) | (jnp.max(low) > st.foot_lift_limit)
                 | (excess > st.bound_violation_limit)
                 | (jnp.abs(pitch + q[0]) > st.lower_tilt_limit))
        band = ((jnp.abs(q) <= st.settle_angle_tol).all()
                & (jnp.abs(dq) <= st.settle_rate_tol).all())
        newly_fell = ok & falls

        def upd(old, new):
            return jnp.where(ok, new, old)

        power = torques * (q - carry.q_prev)
        power_u = u * (x[:2] - carry.x_prev[:2])
        loaded = ok & jnp.isfinite(cop)
        acc = acc._replace(
            alive=ok & ~falls,
            fell=acc.fell | newly_fell,
            fall_step=jnp.where(newly_fell, i, acc.fall_step),
            diverged=acc.diverged | (acc.alive & ~finite),
            last_outside=jnp.where(ok & ~band, i, acc.last_outside),
            in_band=band,
            peak_ankle=upd(acc.peak_ankle, jnp.maximum(acc.peak_ankle, jnp.abs(q[0]))),
            peak_hip=upd(acc.peak_hip, jnp.maximum(acc.peak_hip, jnp.abs(q[1]))),
            peak_foot_pitch=upd(acc.peak_foot_pitch,
                                jnp.maximum(acc.peak_foot_pitch, jnp.abs(pitch))),
            cop_min=jnp.where(loaded, jnp.minimum(acc.cop_min, cop), acc.cop_min),
            cop_max=jnp.where(loaded, jnp.maximum(acc.cop_max, cop), acc.cop_max),
            com_min=upd(acc.com_min, jnp.minimum(acc.com_min, com)),
            com_max=upd(acc.com_max, jnp.maximum(acc.com_max, com)),
            peak_tau_ankle=upd(acc.peak_tau_ankle,
                               jnp.maximum(acc.peak_tau_ankle, jnp.abs(torques[0]))),
            peak_tau_hip=upd(acc.peak_tau_hip, jnp.maximum(acc.peak_tau_hip, jnp.abs(torques[1]))),
            energy_ankle=upd(acc.energy_ankle, acc.energy_ankle + jnp.abs(power[0])),
            energy_hip=upd(acc.energy_hip, acc.energy_hip + jnp.abs(power[1])),
            work_ankle=upd(acc.work_ankle, acc.work_ankle + power[0]),
            work_hip=upd(acc.work_hip, acc.work_hip + power[1]),
            energy_u1=upd(acc.energy_u1, acc.energy_u1 + jnp.abs(power_u[0])),
            energy_u2=upd(acc.energy_u2, acc.energy_u2 + jnp.abs(power_u[1])),
            max_bound_violation=upd(acc.max_bound_violation,
                                    jnp.maximum(acc.max_bound_violation, excess)),
        )
        history = jnp.concatenate([jnp.concatenate([q, dq])[None], carry.history[:-1]])
        carry = Carry(d=d, warm=carry.warm, history=history, q_prev=q, x_prev=x, acc=acc)
        out = None
        if st.trajectories:  # NaN after the fall sample (the run is reset there)
            out = dict(qpos=d.qpos, qvel=d.qvel, tau=torques, u=u, cop=cop, com=com)
            out = {k: jnp.where(carry.acc.alive, v, jnp.nan).astype(dtype) for k, v in out.items()}
        return carry, out

    q0, dq0 = joints(ar.d0)
    history0 = jnp.tile(jnp.concatenate([q0, dq0])[None], (st.delay_steps + 1, 1))

    def control_period(carry: Carry, k: jax.Array):
        acc = carry.acc
        alive = acc.alive
        # A dead scenario restarts from rest with a cold controller (see the module docstring).
        d = _select(alive, carry.d, ar.d0)
        warm = _select(alive, carry.warm, zero_warm)
        measured = carry.history[st.delay_steps]
        x_meas = jnp.where(alive, state(measured[:2], measured[2:]), jnp.zeros(4, dtype))
        res = admm_mod.admm_solve(ar.qp, x_meas, warm, st.settings)
        u = res.u0.astype(dtype)
        torques = ar.torque_map @ u
        finite = jnp.isfinite(u).all() & jnp.isfinite(torques).all()
        counted = alive
        saturated = (u <= u_lo + sat_tol) | (u >= u_hi - sat_tol)
        residual_ok = counted & jnp.isfinite(res.prim_res)
        acc = acc._replace(
            alive=alive & finite,
            diverged=acc.diverged | (counted & ~finite),
            control_periods=acc.control_periods + counted,
            saturated_ankle=acc.saturated_ankle + (counted & saturated[0]),
            saturated_hip=acc.saturated_hip + (counted & saturated[1]),
            nonconverged_solves=(acc.nonconverged_solves
                                 + (counted & (res.status != admm_mod.SOLVED))),
            max_residual=jnp.where(residual_ok,
                                   jnp.maximum(acc.max_residual, res.prim_res.astype(dtype)),
                                   acc.max_residual),
            admm_iterations=acc.admm_iterations + jnp.where(counted, res.iters, 0),
        )
        u = jnp.where(finite, u, jnp.zeros_like(u))
        torques = jnp.where(finite, torques, jnp.zeros_like(torques))
        warm = admm_mod.ADMMWarm(*(w.astype(dtype) for w in res.warm_next))
        history = jnp.where(alive, carry.history, history0)
        carry = carry._replace(d=d, warm=warm, history=history, acc=acc)

        def sub(c, j):
            return physics_step(c, k * S + j, torques, u)

        return jax.lax.scan(sub, carry, jnp.arange(S, dtype=jnp.int32))

    carry = Carry(d=ar.d0, warm=zero_warm, history=history0, q_prev=q0, x_prev=state(q0, dq0),
                  acc=Accumulators.initial(dtype))
    carry, series = jax.lax.scan(control_period, carry,
                                 jnp.arange(st.n_control, dtype=jnp.int32))
    if series is not None:
        series = {k: v.reshape((st.n_control * S,) + v.shape[2:]) for k, v in series.items()}
    return carry.acc, series


# --------------------------------------------------------------------------------------------
# The batch runner (host side)


def push_steps(durations: np.ndarray, physics_dt: float) -> np.ndarray:
    """n_push = ceil(T / dt - 1e-9) physics steps with the push on (float64 on the host)."""
    return np.ceil(np.asarray(durations, np.float64) / physics_dt - 1e-9).astype(np.int32)


def _bucket(n: int, minimum: int = 8) -> int:
    """Padded batch size: the next power of two (>= minimum), so few sizes are compiled."""
    return max(minimum, 1 << max(0, math.ceil(math.log2(max(n, 1)))))


# Compiled batch functions shared by every BatchRunner of this process, keyed by
# BatchRunner._shape_key (all that is baked into the executable).
_COMPILED: dict[tuple, Any] = {}


class BatchRunner:
    """Closed-loop scenarios of one configuration, batched (MJX physics + ADMM MPC).

    The MuJoCo model, the QP and the ADMM matrices are built once; one compiled function per
    padded batch size (the next power of two, at least 8; padding cells are F = 0, T = 0).
    With several local JAX devices (``devices``, default ``jax.local_devices()``) each batch
    is split over them along the scenario axis (a 1-D mesh, NamedSharding, shard_map).
    """

    def __init__(self, config: Config, *, dtype=jnp.float32, trajectories: bool = False,
                 mjx_options: dict[str, Any] | None = None, devices: list | None = None):
        self.config = config
        self.dtype = jnp.dtype(dtype)
        self.trajectories = trajectories
        body, ctrl, sc = config.body, config.controller, config.scenario
        self.model = mj_model(config, mjx_options)
        mx = mjx_model(self.model, self.dtype)
        d0 = rest_data(self.model, self.dtype)
        self.sensors = sensors(self.model, d0)
        qp = build_qp(ctrl, body, sc.control_dt)
        self.qp = qp
        settings = admm_mod.settings_from_controller(ctrl)
        lm = qp.linear
        to_state = np.linalg.solve(lm.P, JOINT_TO_ABS)
        self.arrays = Arrays(
            mx=mx, d0=d0, qp=admm_mod.build_admm(qp, settings, dtype=self.dtype),
            to_state=jnp.asarray(to_state, self.dtype),
            torque_map=jnp.asarray(lm.torque_map, self.dtype),
        )
        self.static = Static(
            n_control=sc.n_control, substeps=sc.substeps, delay_steps=sc.delay_steps,
            push_at_hip=sc.push_body == "hip", settings=settings, trajectories=trajectories,
            foot_pitch_limit=sc.foot_pitch_limit, foot_lift_limit=sc.foot_lift_limit,
            bound_violation_limit=sc.bound_violation_limit,
            lower_tilt_limit=sc.lower_tilt_limit, settle_angle_tol=sc.settle_angle_tol,
            settle_rate_tol=sc.settle_rate_tol,
            state_lower=(ctrl.state1_bounds[0], ctrl.state2_bounds[0]),
            state_upper=(ctrl.state1_bounds[1], ctrl.state2_bounds[1]),
            input_lower=(ctrl.input1_bounds[0], ctrl.input2_bounds[0]),
            input_upper=(ctrl.input1_bounds[1], ctrl.input2_bounds[1]),
        )
        devices = list(jax.local_devices() if devices is None else devices)
        self.mesh = (jax.sharding.Mesh(np.array(devices), ("batch",)) if len(devices) > 1
                     else None)
        if self.mesh is not None:  # the shared arrays, replicated on every device once
            self.arrays = jax.device_put(self.arrays, self._shardings()[1])
        self._compiled_fns: dict[int, Any] = {}
        self.compile_seconds: dict[int, float] = {}
        self.last_trajectories: dict[str, np.ndarray] | None = None

    # -- compilation ----------------------------------------------------------------------

    def _batched(self):
        sn, st = self.sensors, self.static

        def run_batch(arrays: Arrays, force: jax.Array, n_push: jax.Array):
            one = functools.partial(scenario, arrays, sn, st)
            return jax.vmap(one)(force, n_push)  # the one place batching is added

        mesh = self.mesh
        if mesh is None:
            return jax.jit(run_batch)
        # Several devices: each runs ``run_batch`` on its slice of the batch (shard_map), so
        # its loops (the ADMM while_loop, the contact solver) stop for its own scenarios only
        # and no device waits on another inside the scan.
        P = jax.sharding.PartitionSpec
        sharded = jax.shard_map(run_batch, mesh=mesh, in_specs=(P(), P("batch"), P("batch")),
                                out_specs=P("batch"), check_vma=False)
        return jax.jit(sharded)

    def _shape_key(self, batch: int) -> tuple:
        """What the compiled function depends on besides the traced arrays' values: their
        tree structure, shapes and dtypes, the static addresses and settings, the batch."""
        leaves, treedef = jax.tree.flatten(self.arrays)
        sn = tuple(tuple(np.asarray(v).ravel().tolist()) + (np.shape(v),) for v in self.sensors)
        devices = None if self.mesh is None else tuple(d.id for d in self.mesh.devices.flat)
        return (treedef, tuple((np.shape(v), str(v.dtype)) for v in leaves), sn, self.static,
                batch, devices, jax.config.jax_enable_x64)

    def compiled(self, batch: int):
        """The compiled batch function for a padded batch size (compiled ahead of time).

        The model, QP and ADMM data are traced arguments, so configurations of equal shapes
        (another body, convention, weights, bounds; the same horizon, delay, t_end, ADMM
        settings and thresholds) share one compiled function (:data:`_COMPILED`)."""
        fn = self._compiled_fns.get(batch)
        if fn is None:
            t0 = _time.perf_counter()
            key = self._shape_key(batch)
            fn = _COMPILED.get(key)
            if fn is None:
                split, whole = self._shardings()
                force = jax.ShapeDtypeStruct((batch,), self.dtype, sharding=split)
                n_push = jax.ShapeDtypeStruct((batch,), jnp.int32, sharding=split)
                fn = self._batched().lower(self.arrays, force, n_push).compile()
                _COMPILED[key] = fn
            self.compile_seconds[batch] = _time.perf_counter() - t0
            self._compiled_fns[batch] = fn
        return fn

    def _shardings(self):
        """(batch axis split over the devices, replicated) NamedShardings; (None, None) on
        one device."""
        if self.mesh is None:
            return None, None
        P = jax.sharding.PartitionSpec
        return (jax.sharding.NamedSharding(self.mesh, P("batch")),
                jax.sharding.NamedSharding(self.mesh, P()))

    def padded_batch(self, n: int) -> int:
        """The compiled batch size for n scenarios: the next power of two (>= 8), rounded up
        to a multiple of the number of devices (unchanged for 1, 2, 4 or 8 devices, so a
        sweep's chunk size is the compiled size)."""
        devices = 1 if self.mesh is None else self.mesh.devices.size
        return -(-_bucket(n) // devices) * devices

    # -- running --------------------------------------------------------------------------

    def _inputs(self, forces, durations) -> tuple[np.ndarray, np.ndarray]:
        forces = np.atleast_1d(np.asarray(forces, np.float64))
        durations = np.atleast_1d(np.asarray(durations, np.float64))
        if forces.ndim != 1 or forces.shape != durations.shape:
            raise ValueError(f"forces and durations must be 1-D arrays of one length, got "
                             f"shapes {forces.shape} and {durations.shape}")
        if not (np.isfinite(forces).all() and np.isfinite(durations).all()):
            raise ValueError("forces and durations must be finite")
        if (durations < 0).any():
            raise ValueError("durations must be >= 0")
        return forces, durations

    def run_raw(self, forces, durations) -> tuple[Accumulators, dict[str, np.ndarray] | None]:
        """Device results as numpy (accumulators, series), padding removed."""
        forces, durations = self._inputs(forces, durations)
        n = forces.shape[0]
        batch = self.padded_batch(n)
        f = np.zeros(batch, np.float64)
        f[:n] = forces
        steps = np.zeros(batch, np.int32)
        steps[:n] = push_steps(durations, self.config.scenario.physics_dt)
        fn = self.compiled(batch)
        split, _ = self._shardings()
        f = np.asarray(f, self.dtype)
        if split is None:
            acc, series = fn(self.arrays, jnp.asarray(f), jnp.asarray(steps))
        else:  # the batch axis split over the devices (padding cells F = 0, T = 0)
            acc, series = fn(self.arrays, jax.device_put(f, split), jax.device_put(steps, split))
        acc = Accumulators(*(np.asarray(v)[:n] for v in acc))
        if series is not None:
            series = {k: np.asarray(v)[:n] for k, v in series.items()}
        return acc, series

    def run(self, forces, durations) -> dict[str, np.ndarray]:
        """Summary of each scenario (SUMMARY_COLUMNS except convention, plus
        ``admm_iterations``, the ADMM iterations summed over the counted control periods):
        numpy arrays, one entry per scenario, outcome as int codes (``metrics.OUTCOMES``).
        With ``trajectories=True`` the per-physics-step series of the batch are left in
        ``self.last_trajectories`` (arrays [B, n_steps, ...], plus time [n_steps])."""
        forces, durations = self._inputs(forces, durations)
        acc, series = self.run_raw(forces, durations)
        summary = {"force": forces, "duration": durations, **summarize(acc, self.config)}
        if series is not None:
            sc = self.config.scenario
            n_steps = sc.n_control * sc.substeps
            series["time"] = (np.arange(n_steps) + 1) * sc.physics_dt
        self.last_trajectories = series
        return summary

    def run_frame(self, forces, durations) -> pd.DataFrame:
        """As :meth:`run`, as a table with columns ``metrics.SUMMARY_COLUMNS``."""
        forces, durations = self._inputs(forces, durations)
        summary = self.run(forces, durations)
        return summary_frame(summary, forces, durations, self.config.controller.convention)


def summarize(acc: Accumulators, config: Config) -> dict[str, np.ndarray]:
    """Summary columns from the final accumulators [B] (host side, float64)."""
    sc = config.scenario
    dt = sc.physics_dt

    def f64(v):
        return np.asarray(v, np.float64)

    def finite_or_nan(v):
        v = f64(v)
        return np.where(np.isfinite(v), v, np.nan)

    diverged, fell = np.asarray(acc.diverged), np.asarray(acc.fell)
    recovered = np.asarray(acc.alive) & np.asarray(acc.in_band)
    outcome = np.where(diverged, metrics.DIVERGED, np.where(
        fell, metrics.FELL, np.where(recovered, metrics.RECOVERED, metrics.NOT_SETTLED)))
    outcome = outcome.astype(np.int32)
    settle = np.where(acc.last_outside >= 0, (f64(acc.last_outside) + 1) * dt, 0.0)
    settle = np.where(outcome == metrics.RECOVERED, settle, np.nan)
    fall_time = np.where(outcome == metrics.FELL, (f64(acc.fall_step) + 1) * dt, np.nan)
    periods = f64(acc.control_periods)
    with np.errstate(invalid="ignore", divide="ignore"):
        sat_ankle = np.where(periods > 0, f64(acc.saturated_ankle) / periods, np.nan)
        sat_hip = np.where(periods > 0, f64(acc.saturated_hip) / periods, np.nan)
    energy_ankle, energy_hip = f64(acc.energy_ankle), f64(acc.energy_hip)
    return {
        "outcome": outcome,
        "settle_time": settle,
        "fall_time": fall_time,
        "peak_ankle": finite_or_nan(acc.peak_ankle),
        "peak_hip": finite_or_nan(acc.peak_hip),
        "peak_foot_pitch": finite_or_nan(acc.peak_foot_pitch),
        "cop_min": finite_or_nan(acc.cop_min),
        "cop_max": finite_or_nan(acc.cop_max),
        "com_min": finite_or_nan(acc.com_min),
        "com_max": finite_or_nan(acc.com_max),
        "peak_tau_ankle": finite_or_nan(acc.peak_tau_ankle),
        "peak_tau_hip": finite_or_nan(acc.peak_tau_hip),
        "ankle_saturation_fraction": sat_ankle,
        "hip_saturation_fraction": sat_hip,
        "energy_ankle": energy_ankle,
        "energy_hip": energy_hip,
        "energy_total": energy_ankle + energy_hip,
        "work_ankle": f64(acc.work_ankle),
        "work_hip": f64(acc.work_hip),
        "energy_u1": f64(acc.energy_u1),
        "energy_u2": f64(acc.energy_u2),
        "nonconverged_solves": np.asarray(acc.nonconverged_solves, np.int64),
        "max_residual": finite_or_nan(acc.max_residual),
        "max_bound_violation": f64(acc.max_bound_violation),
        "admm_iterations": np.asarray(acc.admm_iterations, np.int64),
    }


def summary_frame(summary: dict[str, np.ndarray], forces: np.ndarray, durations: np.ndarray,
                  convention: str) -> pd.DataFrame:
    """The summary as a table: columns SUMMARY_COLUMNS, outcome as strings."""
    n = len(forces)
    columns = dict(summary)
    columns["force"] = np.asarray(forces, np.float64)
    columns["duration"] = np.asarray(durations, np.float64)
    columns["convention"] = np.full(n, convention, dtype=object)
    columns["outcome"] = np.asarray(metrics.OUTCOMES, dtype=object)[summary["outcome"]]
    return pd.DataFrame({name: columns[name] for name in metrics.SUMMARY_COLUMNS})
