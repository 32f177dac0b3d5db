"""MJX physics of the balance model: the model, the rest state, the steps.

A sample is read after every physics step, at t = (i+1) dt: joints and velocities at the new
time, contacts and constraint forces those that acted during the step (as the reference leaves
them after ``mj_step`` + ``mj_kinematics``), body and geom positions at the new time. ``mjx.step``
computes positions at its start only, so those of t = (i+1) dt come either from an extra
``mjx.kinematics`` (:func:`advance`) or, for free, from the next step (:func:`step`; the
closed loop reads them there, ``kernel.period``). What a sample holds is read by
``sensing.py``.

MJX options (:data:`MJX_OPTIONS`), chosen for speed on the CPU and justified by the agreement
tests in tests/rollout/test_rollout.py:

- Newton solver (MuJoCo's default, so the reference uses it too) with ``iterations = 4`` and
  ``ls_iterations = 8``. The contact problem is four sphere-plane contacts on a five-dof chain,
  warm-started from the previous step's accelerations; with 3 or more iterations MJX matches
  ``mj_step`` as closely as with 100 (float32 rounding dominates); with 2 the rocking foot
  drifts (tests/rollout/test_rollout.py states the figures). The tolerance stays at MuJoCo's 1e-8,
  which float32 never meets, so every step runs the capped 4 iterations (under ``vmap`` the
  loop runs for the slowest element anyway).
- pyramidal friction cone (MuJoCo's default; the load-cell CoP decodes pyramidal forces).
- disabled: Euler damping, springs, dampers, friction loss, joint limits, equality constraints,
  control clamping -- the model has none of them, so these flags only skip dead code (springs,
  dampers and Euler damping stay on for a body with the hip servo, which has them).

The rest state comes from ``mj_forward`` in C (:func:`rest_data`), so building a runner
compiles nothing.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

# mujoco.mjx prints "Failed to import warp" when its GPU-only Warp backend is not installed;
# the JAX implementation used here does not need it, so keep that line off the user's screen.
# Without mujoco-mjx this module still imports (the scalar reference runs on MuJoCo C alone);
# the batched paths are refused at their first call (check_mujoco) with what to install.
if TYPE_CHECKING:  # (for the type checker: the module, never None)
    from mujoco import mjx
elif importlib.util.find_spec("mujoco.mjx") is None:
    mjx = None
else:
    with contextlib.redirect_stdout(io.StringIO()):
        from mujoco import mjx

from ..model.mjcf import mjcf
from ..model.params import Config
from ..runtime.version import check_mujoco
from .sensing import Sensors, cell_heights, load_cell_cop, whole_body_com

MJX_OPTIONS: dict[str, Any] = {
    "solver": int(mujoco.mjtSolver.mjSOL_NEWTON),
    "iterations": 4,
    "ls_iterations": 8,
    "cone": int(mujoco.mjtCone.mjCONE_PYRAMIDAL),
}

_DISABLE = (
    mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    | mujoco.mjtDisableBit.mjDSBL_SPRING
    | mujoco.mjtDisableBit.mjDSBL_DAMPER
    | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    | mujoco.mjtDisableBit.mjDSBL_LIMIT
    | mujoco.mjtDisableBit.mjDSBL_EQUALITY
    | mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL
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


def mj_model(
    config: Config, options: dict[str, Any] | None = None, *, sensors: str = ""
) -> mujoco.MjModel:
    """The free-foot MuJoCo model of ``config`` with the MJX options applied (C side too).

    sensors: MJCF sensor elements to add (the C path's measurements, ``cpath.py``); sensors
    only read the simulation, so the physics is the same with or without them."""
    check_mujoco(mjx=True)  # the batched paths (MJX and C) run mujoco-mjx: refuse a bad pair
    xml = mjcf(config.body, config.scenario.physics_dt, foot="free")
    if sensors:
        xml = xml.replace("</mujoco>", f"  <sensor>\n{sensors}  </sensor>\n</mujoco>")
    model = mujoco.MjModel.from_xml_string(xml)
    opts = dict(MJX_OPTIONS if options is None else options)
    for name, value in opts.items():
        setattr(model.opt, name, value)
    disable = _DISABLE
    if (model.jnt_stiffness != 0).any() or (model.dof_damping != 0).any():
        # a body with the hip servo (BodyParams): keep its spring and damper, and Euler's
        # implicit damping, exactly as mj_step in the reference runs them
        disable &= ~(
            mujoco.mjtDisableBit.mjDSBL_EULERDAMP
            | mujoco.mjtDisableBit.mjDSBL_SPRING
            | mujoco.mjtDisableBit.mjDSBL_DAMPER
        )
    model.opt.disableflags |= int(disable)
    return model


def mjx_model(model: mujoco.MjModel, dtype=jnp.float32) -> mjx.Model:
    """``mjx.put_model`` with every floating field cast to ``dtype``."""
    check_mujoco(mjx=True)
    return cast_floats(mjx.put_model(model, impl="jax"), dtype)


def canonical_hfield_bounds(mx: mjx.Model, model: mujoco.MjModel) -> mjx.Model:
    """``mx`` with MJX's static copy of the geoms' bounding radii (``geom_rbound_hfield``, a
    NumPy array in the model's tree structure, read only for height-field collisions) zeroed
    when the model has no height field: it is then read nowhere, and bodies of other sizes
    (subjects) keep one tree structure, so one compiled program serves them all (the traced
    ``geom_rbound`` that the collisions read is untouched)."""
    impl = getattr(mx, "_impl", None)
    if model.nhfield or impl is None or not hasattr(impl, "geom_rbound_hfield"):
        return mx
    zero = np.zeros_like(np.asarray(impl.geom_rbound_hfield))
    return mx.replace(_impl=impl.replace(geom_rbound_hfield=zero))


def rest_data(model: mujoco.MjModel, dtype=jnp.float32) -> mjx.Data:
    """Upright rest (qpos = qvel = 0) with positions computed: ``mj_forward`` in C, then
    ``mjx.put_data``.

    Computing it with a jitted ``mjx.forward`` instead would cost a compile per configuration
    for one call. The two differ only in fields that every
    ``mjx.step`` recomputes before use (the factor ``qLD`` and ``efc_D`` are laid out
    differently); one ``mjx.step`` from either gives bit-identical data (checked when this was
    changed), and the contact layout read by :func:`sensors` is the same.
    """
    check_mujoco(mjx=True)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    d = cast_floats(mjx.put_data(model, data, impl="jax"), dtype)
    # mjx.step builds some integer fields (the contacts' geom ids) in JAX's default integer width
    # (int64 under jax_enable_x64) where put_data writes int32: give every integer leaf the type
    # the step returns, so the state is a valid scan carry either way. (Floating leaves are cast
    # back to ``dtype`` after every step.)
    stepped = _stepped_dtypes(model, dtype, d)

    def match(x, s):
        if jnp.issubdtype(x.dtype, jnp.integer) and x.dtype != s:
            return x.astype(s)
        return x

    return jax.tree_util.tree_unflatten(
        jax.tree_util.tree_structure(d),
        [match(x, s) for x, s in zip(jax.tree_util.tree_leaves(d), stepped)],
    )


_STEPPED: dict[tuple, tuple] = {}


def _stepped_dtypes(model: mujoco.MjModel, dtype, d: mjx.Data) -> tuple:
    """The dtype of every leaf of ``mjx.step`` from ``d``, traced abstractly (nothing
    compiled) once per kind of model and state: the state's layout (its tree structure, with
    the contacts' static geom arrays, and the leaves' shapes and dtypes), JAX's integer width
    and what picks ``mjx.step``'s code paths (the geom and joint types, the integrator,
    friction cone, solver and flags). Tracing the step is most of a runner's set-up
    (BENCHMARKS.md, "Per-lane bodies and a cohort's one queue"), and bodies of one MJCF
    structure, a cohort's, share it."""
    leaves, treedef = jax.tree_util.tree_flatten(d)
    opt = model.opt
    key = (
        treedef,
        tuple((v.shape, str(v.dtype)) for v in leaves),  # jax arrays, all
        bool(jax.config.jax_enable_x64),  # type: ignore[attr-defined]  # flags set at run time
        np.dtype(dtype).name,
        model.geom_type.tobytes(),
        model.jnt_type.tobytes(),
        int(opt.integrator),
        int(opt.cone),
        int(opt.solver),
        int(opt.disableflags),
        int(opt.enableflags),
    )
    if key not in _STEPPED:
        _STEPPED[key] = tuple(
            s.dtype
            for s in jax.tree_util.tree_leaves(jax.eval_shape(mjx.step, mjx_model(model, dtype), d))
        )
    return _STEPPED[key]


def step(
    mx: mjx.Model,
    sensors: Sensors,
    d: mjx.Data,
    torques: jax.Array,
    force: jax.Array,
    push_at_hip: bool = False,
) -> mjx.Data:
    """One physics step (``mjx.step``) with motor ``torques`` [2] and the push ``force`` []
    (N, along x). Afterwards qpos and qvel are those at the new time, while body and geom
    positions, contacts and constraint forces are those the step computed at its start.

    The push acts on the upper body through ``xfrc_applied`` (a wrench at its CoM, xipos); at
    the hip it is the same force plus the moment (xpos - xipos) x F, from the positions in
    ``d`` (those of the current time only if ``d`` came from :func:`advance`).
    """
    dtype = d.qpos.dtype
    push = jnp.zeros(d.xfrc_applied.shape, dtype).at[sensors.upper_body, 0].set(force)
    if push_at_hip:
        r = d.xpos[sensors.upper_body] - d.xipos[sensors.upper_body]
        moment = jnp.cross(r, jnp.stack([force, 0 * force, 0 * force]).astype(dtype))
        push = push.at[sensors.upper_body, 3:].set(moment)
    d = d.replace(ctrl=torques.astype(dtype), xfrc_applied=push)
    return cast_floats(mjx.step(mx, d), dtype)


def advance(
    mx: mjx.Model,
    sensors: Sensors,
    d: mjx.Data,
    torques: jax.Array,
    force: jax.Array,
    push_at_hip: bool = False,
) -> mjx.Data:
    """:func:`step`, then the positions refreshed (``mjx.kinematics``): body and geom
    positions are those at the new time while the contacts and constraint forces stay those
    that acted during the step (as the reference leaves them after ``mj_step`` +
    ``mj_kinematics``)."""
    d = step(mx, sensors, d, torques, force, push_at_hip)
    return cast_floats(mjx.kinematics(mx, d), d.qpos.dtype)


def open_loop(
    mx: mjx.Model,
    sensors: Sensors,
    d0: mjx.Data,
    torques: jax.Array,
    force: jax.Array,
    n_push: jax.Array,
    push_at_hip: bool = False,
) -> dict[str, jax.Array]:
    """Physics only: motor ``torques`` [n, 2] applied at steps i = 0..n-1, the push on for
    i < n_push. Returns per-step samples at t = (i+1) dt: qpos [n, nq], qvel [n, nv], cop [n],
    com [n], cell_low [n, 4]. Jit with ``sensors`` and ``push_at_hip`` static."""
    dtype = d0.qpos.dtype
    force = jnp.asarray(force, dtype)

    def body(d, inputs):
        i, tau = inputs
        d = advance(mx, sensors, d, tau, jnp.where(i < n_push, force, 0 * force), push_at_hip)
        cop, _ = load_cell_cop(d, sensors)
        return d, dict(
            qpos=d.qpos,
            qvel=d.qvel,
            cop=cop,
            com=whole_body_com(mx, d, sensors),
            cell_low=cell_heights(mx, d, sensors),
        )

    steps = jnp.arange(torques.shape[0], dtype=jnp.int32)
    return jax.lax.scan(body, d0, (steps, jnp.asarray(torques, dtype)))[1]
