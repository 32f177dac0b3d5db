"""The MuJoCo C path: the engine's slots stepped by MuJoCo C on a thread pool, the ADMM in JAX.

The same continuous batching as ``engine.py`` (fixed slots per device, each refilled with the
next cell when its scenario is decided), run one control period per call:

    loop over control periods p (host):
        call(p)   jitted, vmapped over the slots, sharded over the JAX devices:
            fold the samples of the period the slots ran since call(p - 1)  (kernel.sample_update)
            decide (fall, t_end, certificate), harvest and vacate             (slots.certify, ...)
            refill vacant slots; solve every slot's MPC       (kernel.prepare, solve, conclude)
        MuJoCo C: every busy slot advances ``substeps`` steps (``mujoco.rollout`` on a
            persistent thread pool, one MjData per thread) with the held torques and the push
        decode the samples on the host (float64), for call(p + 1)

The rules, the accumulators, the controller and the engine's bookkeeping are the MJX path's
functions (``kernel.py``, ``slots.py``); only the physics and the way a sample is read differ.

Samples. MuJoCo's physics here is the reference's (``reference/loop.py``: the same MJCF and
MuJoCo's default solver options, float64; the MJX path runs float32 with a capped contact
solver). The model carries sensors that only read the simulation (:func:`sensor_xml`): per load
cell a contact sensor (normal force and point of the cell-floor contact, ``mj_contactForce`` as
in ``metrics.load_cell_cop``) and a frame-position sensor, and the foot subtree's CoM.
``mj_step`` evaluates them at the step's start (positions) and after its constraint solve
(forces), so the sample of step i -- joints at t = (i+1) dt, the contacts that acted during step
i, positions at t = (i+1) dt, exactly the reference's -- takes its forces from step i's sensors
and its positions from step i + 1's. The period's last sample takes its positions from
``mjx.kinematics`` of its joint positions inside the next call (float32; the only float32 physics
quantity of this path).

Warm start. ``mujoco.rollout`` starts every call from a full physics state, which does not hold
the contact solver's warm start (``qacc_warmstart``, the previous step's accelerations, which
``mj_step`` carries over in the reference). It is passed back in: with the Euler integrator
qvel(t + dt) = qvel(t) + dt qacc, so the last step's accelerations are recovered from its two
velocities (to round-off; with the hip servo's implicit damping only approximately). A warm
start only changes where the solver starts; the solution is the same to its tolerance.

Divergence. MuJoCo resets a simulation that meets a NaN, Inf or huge value (and warns), and the
rollout then repeats that state. Each call starts at time :data:`TIME0`; a sample whose time is
not TIME0 + (j+1) dt marks the run diverged (the reference: a bad-value warning).

Not supported here (:func:`unsupported`): the push at the hip (its moment needs the upper
body's orientation at every step, inside the rollout) and per-step trajectories.
"""

from __future__ import annotations

import os
import time as _time
from typing import Any, Iterator, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from ..control import certificate as cert_mod
from ..measures import outcomes
from ..model.mjcf import indices
from ..model.params import Config
from .queue import Queue
from .engine import NO_PROBE, Engine, Probe, cells_of
from .slots import Finished, Slots, broadcast, checker, decide, empty_finished, retire, take
from ..runtime import compiled, signals
from ..runtime.compiled import MATMUL_PRECISION
from .kernel import (
    Carry,
    conclude_batch,
    initial_carry,
    limits_of,
    prepare_batch,
    remember,
    sample_update,
    select,
    solve_lanes,
)
from .physics import mj_model, mjx
from .sensing import (
    Sample,
    Sensors,
    cell_heights,
    com_velocity,
    pendulum_frequency,
    state,
    whole_body_com,
)

PATHS = ("auto", "mjx", "c")

# The start time of every rollout call (time has no effect on this model's physics; a reset
# simulation restarts at 0, which is how a divergence is seen).
TIME0 = 1.0

_CONTROL_SPEC = int(mujoco.mjtState.mjSTATE_CTRL) | int(mujoco.mjtState.mjSTATE_XFRC_APPLIED)
_FULL = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)

# Columns of a decoded sample row (float64 on the host, the runner's dtype in the call): then
# the CoM velocity, the base of support's heel and toe x, and all rates (NV: the free foot's x,
# z, pitch, the ankle and the hip; the call reads the last sample's to compute its CoM velocity)
Q, DQ, PITCH, CELLS, COP, COM, OK = slice(0, 2), slice(2, 4), 4, slice(5, 9), 9, 10, 11
VCOM, HEEL, TOE, NV = 12, 13, 14, 5
QVEL = slice(15, 15 + NV)
ROW = 15 + NV


# What ``auto`` picks on a CPU, from ``mjx-balance bench`` on this project's 2-core machine
# (BENCHMARKS.md, "Physics paths"); on an accelerator it is always the MJX path.
AUTO_ON_CPU = "mjx"


def resolve(
    physics: str, config: Config, trajectories: bool = False, platform: str | None = None
) -> str:
    """The path that runs: ``physics`` ("auto", "mjx" or "c") for this configuration on
    ``platform`` (default: JAX's). "c" where it cannot run is an error; "auto" falls back to
    MJX there."""
    if physics not in PATHS:
        raise ValueError(f"physics must be one of {', '.join(PATHS)}, got {physics!r}")
    reason = unsupported(config, trajectories)
    if physics == "c" and reason:
        raise ValueError(reason)
    if physics != "auto":
        return physics
    if reason:
        return "mjx"
    if platform is None:
        platform = jax.default_backend()
    return AUTO_ON_CPU if platform == "cpu" else "mjx"


def unsupported(config: Config, trajectories: bool = False) -> str | None:
    """Why the C path cannot run this (None: it can)."""
    if config.scenario.push_body != "upper":
        return (
            "the C path pushes at the upper body's CoM only (scenario.push_body = "
            f"{config.scenario.push_body!r} needs the MJX path)"
        )
    if config.scenario.push_ramp > 0:
        return "the C path pushes with a step only (scenario.push_ramp > 0 needs the MJX path)"
    if trajectories:
        return "the C path returns summaries only (per-step series come from the MJX path)"
    return None


def sensor_xml(model: mujoco.MjModel) -> str:
    """MJCF sensors for a sample: per load cell its contact with the floor (found, force in the
    contact frame, point) and its centre, and the whole body's CoM (the foot's subtree)."""
    ix = indices(model)
    lines = []
    for g in ix.cell_geoms:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        lines.append(
            f'    <contact geom1="{name}" geom2="floor" data="found force pos" num="1"/>\n'
        )
    for g in ix.cell_geoms:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        lines.append(f'    <framepos objtype="geom" objname="{name}"/>\n')
    lines.append('    <subtreecom body="foot"/>\n')
    lines.append('    <subtreelinvel body="foot"/>\n')
    return "".join(lines)


def default_threads() -> int:
    """MuJoCo threads: the CPU cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


class CPhysics:
    """Many scenarios of one configuration stepped by MuJoCo C (``mujoco.rollout``)."""

    def __init__(self, config: Config, threads: int | None = None):
        sc = config.scenario
        plain = mj_model(config, options={})
        self.model = mj_model(config, options={}, sensors=sensor_xml(plain))
        # the reference's physics: MuJoCo's default solver options, nothing disabled
        self.model.opt.disableflags = 0
        m = self.model
        ix = indices(m)
        self.dt = sc.physics_dt
        self.substeps = sc.substeps
        self.threads = int(threads or default_threads())
        if self.threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self._pool = mj_rollout.Rollout(nthread=self.threads if self.threads > 1 else 0)
        self._data = [mujoco.MjData(m) for _ in range(self.threads)]
        self.nq, self.nv = m.nq, m.nv
        self.nstate = mujoco.mj_stateSize(m, _FULL)
        self.ncontrol = mujoco.mj_stateSize(m, _CONTROL_SPEC)
        # addresses: state = [time, qpos, qvel, ...]; control = [ctrl, xfrc_applied]
        self.qpos = slice(1, 1 + m.nq)
        self.qvel = slice(1 + m.nq, 1 + m.nq + m.nv)
        self.joints_q = np.array([ix.ankle_qpos, ix.hip_qpos])
        self.joints_v = np.array([ix.ankle_dof, ix.hip_dof])
        self.foot_pitch = ix.foot_pitch
        self.push_col = m.nu + 6 * ix.upper_body  # x force on the upper body's CoM
        adr = m.sensor_adr
        n = len(ix.cell_geoms)
        self.contact = np.array([adr[c] for c in range(n)])  # found, force (3), pos (3)
        self.framepos = np.array([adr[n + c] for c in range(n)])
        self.subtreecom = int(adr[2 * n])
        self.subtreelinvel = int(adr[2 * n + 1])
        if m.nv != NV:
            raise ValueError(f"the C path's sample rows hold {NV} rates, the model has {m.nv}")
        self.radius = np.asarray(m.geom_size[list(ix.cell_geoms), 0])
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        self.rest = np.empty(self.nstate)
        mujoco.mj_getState(m, d, self.rest, _FULL)
        self.rest[0] = TIME0
        self.rest_warm = d.qacc_warmstart.copy()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def advance(
        self, state0: np.ndarray, warm0: np.ndarray, torques: np.ndarray, push: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``substeps`` steps of n scenarios from full states [n, nstate] with warm starts
        [n, nv], motor torques [n, 2] held and the push [n, substeps] (N). Returns the states
        [n, S, nstate] and sensor values [n, S, nsensordata] after each step."""
        n, S = state0.shape[0], self.substeps
        m = self.model
        control = np.zeros((n, S, self.ncontrol))
        control[:, :, : m.nu] = torques[:, None, :]
        control[:, :, self.push_col] = push
        states = np.empty((n, S, self.nstate))
        sens = np.empty((n, S, m.nsensordata))
        chunk = max(1, n // (10 * self.threads))
        self._pool.rollout(
            [m] * n,
            self._data,
            np.ascontiguousarray(state0),
            control,
            control_spec=_CONTROL_SPEC,
            skip_checks=True,
            nstep=S,
            initial_warmstart=np.ascontiguousarray(warm0),
            state=states,
            sensordata=sens,
            chunk_size=chunk,
        )
        return states, sens

    def next_warm(self, state0: np.ndarray, states: np.ndarray) -> np.ndarray:
        """The contact solver's warm start after the last step (its accelerations)."""
        before = states[:, -2, self.qvel] if states.shape[1] > 1 else state0[:, self.qvel]
        return (states[:, -1, self.qvel] - before) / self.dt

    def samples(self, states: np.ndarray, sens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Decoded sample rows [n, S, ROW] (the last sample's cell heights and CoM NaN: they
        come from the next step) and the last sample's qpos [n, nq]."""
        n, S = states.shape[:2]
        rows = np.full((n, S, ROW), np.nan)
        qpos, qvel = states[..., self.qpos], states[..., self.qvel]
        rows[..., Q] = qpos[..., self.joints_q]
        rows[..., DQ] = qvel[..., self.joints_v]
        rows[..., PITCH] = qpos[..., self.foot_pitch]
        contact = sens[..., self.contact[:, None] + np.arange(7)]  # [n, S, cells, 7]
        normal = np.where(contact[..., 0] > 0, contact[..., 1], 0.0)
        total = normal.sum(-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            rows[..., COP] = np.where(total > 0, (normal * contact[..., 4]).sum(-1) / total, np.nan)
        # positions at the start of step j + 1 belong to sample j
        z = sens[:, 1:, self.framepos + 2]
        rows[:, :-1, CELLS] = z - self.radius
        rows[:, :-1, COM] = sens[:, 1:, self.subtreecom]
        rows[:, :-1, VCOM] = sens[:, 1:, self.subtreelinvel]
        rows[:, :-1, HEEL], rows[:, :-1, TOE] = outcomes.support_edges(
            np, sens[:, 1:, self.framepos]
        )
        rows[..., QVEL] = qvel
        expected = TIME0 + (np.arange(S) + 1) * self.dt
        rows[..., OK] = np.abs(states[..., 0] - expected) < 0.5 * self.dt
        return rows, qpos[:, -1]


class CState(NamedTuple):
    """The slots of the C path on the device: the engine's slots (their carry without physics
    state, which lives on the host) and what the physics of the last call ran with."""

    slots: Slots
    ran: jax.Array  # bool: the slot ran a period since the previous call
    torques: jax.Array  # [2] held during that period
    u: jax.Array  # [2]


def fold_period(
    arrays,
    sensors: Sensors,
    static,
    carry: Carry,
    rows: jax.Array,
    last_qpos: jax.Array,
    k: jax.Array,
    *,
    torques: jax.Array,
    u: jax.Array,
    push: tuple[jax.Array, jax.Array] | None = None,
) -> Carry:
    """The S samples of period k (decoded ``rows`` [S, ROW]; ``last_qpos`` [nq] the last
    sample's) folded into one slot's carry; torques [2] and u [2] held during the period;
    ``push``: the slot's (force, push steps), for the decision instant (kernel.sample_update)."""
    dtype = arrays.d0.qpos.dtype
    S = static.substeps
    d = mjx.kinematics(arrays.mx, arrays.d0.replace(qpos=last_qpos.astype(dtype)))
    rows = rows.astype(dtype)
    rows = rows.at[S - 1, CELLS].set(cell_heights(arrays.mx, d, sensors))
    rows = rows.at[S - 1, COM].set(whole_body_com(arrays.mx, d, sensors))
    rows = rows.at[S - 1, VCOM].set(com_velocity(arrays.mx, d, sensors, rows[S - 1, QVEL]))
    heel, toe = outcomes.support_edges(jnp, d.geom_xpos[sensors.cells, 0])
    rows = rows.at[S - 1, HEEL].set(heel).at[S - 1, TOE].set(toe)
    omega0 = pendulum_frequency(arrays, sensors).astype(dtype)

    def one(carry: Carry, inputs):
        j, r = inputs
        q, dq = r[Q], r[DQ]
        xcom, mos_toe, mos_heel = outcomes.stability_margins(
            jnp, r[COM], r[VCOM], r[HEEL], r[TOE], omega0
        )
        s = Sample(
            q=q,
            dq=dq,
            x=state(arrays, q, dq),
            pitch=r[PITCH],
            cell_low=r[CELLS],
            cop=r[COP],
            com=r[COM],
            magnitude=jnp.where(r[OK] > 0, jnp.zeros((), dtype), jnp.inf),
            qvel=r[QVEL],
            com_vel=r[VCOM],
            mos_toe=mos_toe,
            mos_heel=mos_heel,
            xcom=xcom,
        )
        acc = sample_update(
            carry.acc,
            s,
            k * S + j,
            torques,
            u,
            carry.q_prev,
            carry.x_prev,
            limits_of(arrays, static),
            push=None if push is None else (*push, arrays.capture),
        )
        return carry._replace(
            acc=acc, q_prev=s.q, x_prev=s.x, history=remember(carry.history, s)
        ), None

    return jax.lax.scan(one, carry, (jnp.arange(S, dtype=jnp.int32), rows))[0]


def unpack(floats: jax.Array, ints: jax.Array, S: int):
    """The two arrays a call receives (one transfer each) -> sample rows [B, S, ROW], the last
    sample's qpos [B, nq], refill cells, forces and push steps [B], the period counter []."""
    B = floats.shape[0]
    rows = floats[:, : S * ROW].reshape(B, S, ROW)
    return (rows, floats[:, S * ROW : -1], ints[:, 0], floats[:, -1], ints[:, 1], ints[0, 2])


def pack(
    rows: np.ndarray,
    last_qpos: np.ndarray,
    cell: np.ndarray,
    force: np.ndarray,
    push: np.ndarray,
    p: int,
    dtype,
) -> tuple[np.ndarray, np.ndarray]:
    """The host side of :func:`unpack`."""
    B = rows.shape[0]
    floats = np.concatenate([rows.reshape(B, -1), last_qpos, force[:, None]], axis=1)
    ints = np.stack([cell, push, np.full(B, p)], axis=1).astype(np.int32)
    return floats.astype(dtype), ints


def call(arrays, sensors, static, cert, cs: CState, floats, ints):
    """One control period of one device's slots (pure JAX): fold the physics run since the
    previous call, decide and harvest, refill, solve. Inputs packed (:func:`unpack`). Returns
    the state and two arrays [slots, ...] (one transfer each, :func:`outputs`)."""
    S = static.substeps
    rows, last_qpos, refill_cell, refill_force, refill_push, p = unpack(floats, ints, S)
    check = checker(cert)
    # 1. the period each busy slot ran since the previous call
    carry, k = folded(arrays, sensors, static, cs, rows, last_qpos)
    # 2. decided scenarios harvested and their slots vacated; vacant slots take new cells
    verdict = judged(arrays, static, check, cs, carry, k, p)
    slots, fresh, taken, done = turnover(
        arrays,
        sensors,
        static,
        check is not None,
        cs,
        carry,
        k,
        p,
        verdict=verdict,
        offer=(refill_cell, refill_force, refill_push),
    )
    # 3. every slot's MPC (a vacant one solves x = 0 at rest; its result is not used)
    pre = prepare_batch(arrays, static, slots.carry)
    carry, u, torques = conclude_batch(
        arrays, static, pre, solve_lanes(arrays, static, pre), slots.k
    )
    return outputs(static, slots._replace(carry=carry), u, torques, fresh, taken, done)


def folded(
    arrays, sensors: Sensors, static, cs: CState, rows, last_qpos
) -> tuple[Carry, jax.Array]:
    """Step 1 of a call: the samples of the period each slot ran (``cs.ran``) folded into its
    carry (:func:`fold_period`); the carry and the periods done."""

    def fold(c, r, q, k, t, u, f, n):
        return fold_period(arrays, sensors, static, c, r, q, k, torques=t, u=u, push=(f, n))

    slots = cs.slots
    carry = jax.vmap(fold)(
        slots.carry, rows, last_qpos, slots.k, cs.torques, cs.u, slots.force, slots.n_push
    )
    return select(cs.ran, carry, slots.carry), jnp.where(cs.ran, slots.k + 1, slots.k)


def judged(arrays, static, check, cs: CState, carry: Carry, k, p):
    """The engine's :func:`slots.decide` over the slots that ran a period before call ``p``
    (the certificate checks after every ``CHECK_EVERY``-th period, as on the MJX path)."""
    every = cert_mod.CHECK_EVERY
    return decide(
        check,
        static,
        arrays.n_control,
        carry,
        k,
        (cs.slots.n_push, cs.slots.force),
        cs.ran,
        (p - 1) % every == every - 1,
    )


def turnover(
    arrays,
    sensors: Sensors,
    static,
    gated: bool,
    cs: CState,
    carry: Carry,
    k,
    p,
    *,
    verdict,
    offer: tuple[jax.Array, jax.Array, jax.Array],
) -> tuple[Slots, jax.Array, jax.Array, Finished]:
    """Step 2 of call ``p``: the decided scenarios (``verdict``: :func:`judged`) harvested and
    their slots vacated, then the refill (``gated``: with the certificate, only every
    ``CHECK_EVERY`` periods, as on the MJX path). Returns the slots, which were refilled (their
    physics restarts from rest), the refill cells taken and the finished buffer."""
    B = cs.slots.cell.shape[0]
    acc, certified, decided = verdict
    rest = broadcast(initial_carry(arrays, sensors, static)._replace(d=None), B)
    zero = jnp.zeros((), jnp.int32)
    done, _, slots = retire(
        empty_finished(B, arrays.d0.qpos.dtype),
        zero,
        decided,
        cs.slots,
        acc,
        k,
        certified,
        carry=carry,
        rest=rest,
    )
    vacant = slots.cell < 0
    slots, taken = take(slots, rest, zero, p, *offer, None, gated=gated)
    return slots, vacant & (slots.cell >= 0), taken, done


def outputs(
    static, slots: Slots, u, torques, fresh, taken, done: Finished
) -> tuple[CState, jax.Array, jax.Array]:
    """Step 3's end: the state and the call's two output arrays. floats = the torques [2] and
    push [S] to run, then the finished buffer's float accumulators; ints = whether the slot was
    refilled, whether it is busy, the finished buffer's cell, periods and certified, the
    refill cells taken, then its integer accumulators (:func:`pack_acc`)."""
    S = static.substeps
    B = slots.cell.shape[0]
    busy = slots.cell >= 0
    steps = slots.k[:, None] * S + jnp.arange(S, dtype=jnp.int32)[None]
    push = jnp.where(
        steps < slots.n_push[:, None], slots.force[:, None], jnp.zeros((), slots.force.dtype)
    )
    cs = CState(slots=slots, ran=busy, torques=torques, u=u)
    acc_f, acc_i = pack_acc(done.acc)
    out_f = jnp.concatenate([torques, push, acc_f], axis=1)
    flags = jnp.stack(
        [fresh, busy, done.cell, done.periods, done.certified, jnp.broadcast_to(taken, (B,))],
        axis=1,
    ).astype(jnp.int32)
    return cs, out_f, jnp.concatenate([flags, acc_i], axis=1)


def pack_acc(acc) -> tuple[jax.Array, jax.Array]:
    """Accumulators [B] as one float and one int32 array [B, fields] (one transfer each)."""
    floats = [v for v in acc if jnp.issubdtype(v.dtype, jnp.floating)]
    ints = [v.astype(jnp.int32) for v in acc if not jnp.issubdtype(v.dtype, jnp.floating)]
    return jnp.stack(floats, axis=1), jnp.stack(ints, axis=1)


def unpack_acc(floats: np.ndarray, ints: np.ndarray, template) -> dict[str, np.ndarray]:
    """The host side of :func:`pack_acc` (``template``: accumulators of the right dtypes)."""
    out, nf, ni = {}, 0, 0
    for name, v in zip(template._fields, template):
        dtype = np.dtype(v.dtype)
        if np.issubdtype(dtype, np.floating):
            out[name], nf = floats[:, nf].astype(dtype), nf + 1
        else:
            out[name], ni = ints[:, ni].astype(dtype), ni + 1
    return out


class CEngine(Engine):
    """Continuous batching with MuJoCo C physics (see the module docstring); the interface of
    :class:`engine.Engine`. threads: MuJoCo's thread pool (default: the usable cores)."""

    physics = "c"

    def __init__(
        self,
        runner,
        *,
        slots: int | None = None,
        early_stop: bool = True,
        threads: int | None = None,
        **options: Any,
    ):
        # Engine's other options have no meaning here: one control period a call (block), no
        # ADMM tiles of a slot group (tile), one body per engine (bodies). Refused, not dropped.
        if options:
            raise TypeError(
                f"the C path's engine takes slots, early_stop and threads; not "
                f"{', '.join(sorted(options))}"
            )
        reason = unsupported(runner.config, runner.trajectories)
        if reason:
            raise ValueError(reason)
        super().__init__(runner, slots=slots or default_slots(), early_stop=early_stop)
        self.block = 1
        self.refill = self.slots
        self.c = CPhysics(runner.config, threads)
        # the shared arrays as a flat tuple, on every device once: a call per control period
        # would otherwise flatten MJX's model and re-place the certificate every time
        leaves, self._treedef = jax.tree.flatten((runner.arrays, self.cert))
        _, whole = runner._shardings()
        self._leaves = tuple(leaves if whole is None else jax.device_put(leaves, whole))

    def _key(self) -> tuple:
        return (
            "cpath",
            self.runner._shape_key(self.slots, self.static),
            self.cert is not None,
            None if self.cert is None else tuple(np.shape(v) for v in self.cert),
        )

    def _template(self, arrays) -> CState:
        r = self.runner
        n = self.slots * self.n_devices
        carry = broadcast(initial_carry(arrays, r.sensors, r.static)._replace(d=None), n)
        slots = Slots(
            carry=carry,
            cell=jnp.full(n, -1, jnp.int32),
            force=jnp.zeros(n, r.dtype),
            n_push=jnp.zeros(n, jnp.int32),
            k=jnp.zeros(n, jnp.int32),
            body=jnp.zeros(n, jnp.int32),
        )
        return CState(
            slots=slots,
            ran=jnp.zeros(n, bool),
            torques=jnp.zeros((n, 2), r.dtype),
            u=jnp.zeros((n, 2), r.dtype),
        )

    def _initial_state(self) -> CState:
        batch_sharding, _ = self.runner._shardings()
        return jax.jit(self._template, out_shardings=batch_sharding)(self.runner.arrays)

    def block_fn(self):
        """The jitted period call (see :func:`call`), sharded over the runner's devices, and
        compiled by a first call on vacant slots. (Called with jit's own fast dispatch, not
        an ahead-of-time executable: a call per control period makes the Python-side
        argument handling of the latter a large part of the time.)"""
        if self._fn is not None:
            return self._fn
        t0 = _time.perf_counter()
        r = self.runner
        sensors, static = r.sensors, self.static
        treedef = self._treedef

        def one(leaves, cs, floats, ints):
            arrays, cert = jax.tree.unflatten(treedef, leaves)
            with jax.default_matmul_precision(MATMUL_PRECISION):
                return call(arrays, sensors, static, cert, cs, floats, ints)

        def build():
            run = one
            if r.mesh is not None:
                P = jax.sharding.PartitionSpec
                run = jax.shard_map(
                    one,
                    mesh=r.mesh,
                    in_specs=(P(), P("batch"), P("batch"), P("batch")),
                    out_specs=P("batch"),
                    check_vma=False,
                )
            return jax.jit(run, donate_argnums=(1,))

        key = self._key()
        new = not compiled.is_compiled(key)
        fn = compiled.get_or_compile(key, build)
        state = self._state if self._state is not None else self._initial_state()
        n = self.slots * self.n_devices
        floats, ints = pack(
            np.zeros((n, r.static.substeps, ROW)),
            np.zeros((n, self.c.nq)),
            np.full(n, -1),
            np.zeros(n),
            np.zeros(n),
            0,
            r.dtype,
        )
        t1 = _time.perf_counter()
        state, *_ = fn(self._leaves, state, self._put(floats), self._put(ints))
        self._state = jax.block_until_ready(state)  # all vacant: nothing was run
        if new:  # the first call compiled it
            compiled.charge(key, _time.perf_counter() - t1)
        self.compile_seconds = _time.perf_counter() - t0
        self._fn = fn
        return fn

    def _put(self, a: np.ndarray) -> jax.Array:
        batch_sharding, _ = self.runner._shardings()
        return jnp.asarray(a) if batch_sharding is None else jax.device_put(a, batch_sharding)

    def stream(
        self,
        forces: np.ndarray,
        n_push: np.ndarray,
        inits: np.ndarray | None = None,
        probe: Probe | None = None,
        bodies: np.ndarray | None = None,
    ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray]]]:
        """As :meth:`engine.Engine.stream`, one control period per call (from upright rest
        only: ``inits`` must be None or zero; one body: ``bodies`` None or zero)."""
        _refuse_cells(inits, bodies)
        probe = probe or NO_PROBE
        forces, n_push, n = cells_of(forces, n_push)
        if n == 0:
            return
        fn = self.block_fn()
        r, c = self.runner, self.c
        cs = self._take_state()
        template = jax.eval_shape(lambda: initial_carry(r.arrays, r.sensors, r.static).acc)
        B = self.slots * self.n_devices
        S = c.substeps
        phys = np.tile(c.rest, (B, 1))
        warm = np.tile(c.rest_warm, (B, 1))
        rows = np.zeros((B, S, ROW))
        last_qpos = np.tile(c.rest[c.qpos], (B, 1))
        queue = Queue(forces, n_push, self.n_devices, self.refill)
        remaining, finished, p = n, False, 0
        try:
            while remaining:
                signals.check()  # a checkpoint: a signal dropped where it landed ends the run
                with probe("python"):
                    cells, f, pp, *_ = queue.offer()
                    floats, ints = pack(rows, last_qpos, cells, f, pp, p, r.dtype)
                with probe("transfers"):
                    args = (self._put(floats), self._put(ints))
                probe.before(p, cs, (floats, ints))
                with probe("device_call"):
                    cs, out_f, out_i = probe.call(fn, self._leaves, cs, *args)
                with probe("transfers"):
                    out_f, out_i = jax.device_get((out_f, out_i))
                probe.after(p, (out_f, out_i))
                p += 1
                with probe("python"):
                    torques, push = out_f[:, :2], out_f[:, 2 : 2 + S]
                    reset, busy = out_i[:, 0] > 0, out_i[:, 1] > 0
                    index = out_i[:, 2]
                    queue.took(out_i[:: self.slots, 5])  # one per device
                    keep = index >= 0
                    if keep.any():
                        raw = unpack_acc(out_f[keep, 2 + S :], out_i[keep, 6:], template)
                        raw["periods"], raw["certified"] = out_i[keep, 3], out_i[keep, 4] > 0
                        queue.finished(index[keep], raw["periods"])
                        remaining -= int(keep.sum())
                if keep.any():
                    yield index[keep].astype(np.int64), raw
                if not remaining:
                    break
                # the physics of the period just solved, on the slots that hold a scenario
                with probe("samples_host"):
                    phys[reset], warm[reset] = c.rest, c.rest_warm
                    run = np.flatnonzero(busy)
                if run.size:
                    with probe("physics"):
                        states, sens = c.advance(
                            phys[run],
                            warm[run],
                            torques[run].astype(float),
                            push[run].astype(float),
                        )
                    with probe("samples_host"):
                        warm[run] = c.next_warm(phys[run], states)
                        phys[run] = states[:, -1]
                        phys[run, 0] = TIME0
                        rows[run], last_qpos[run] = c.samples(states, sens)
            finished = True
        finally:
            if finished:
                self._state = cs  # every slot vacant: reusable by the next run


def _refuse_cells(inits: np.ndarray | None, bodies: np.ndarray | None) -> None:
    """Raise ValueError for cells the C path cannot run: off upright rest or of other bodies."""
    if inits is not None and np.any(inits):
        raise ValueError(
            "the MuJoCo C path starts every scenario at upright rest; "
            "initial states need --physics mjx"
        )
    if bodies is not None and np.any(bodies):
        raise ValueError(
            "the MuJoCo C path steps one body's model; several bodies in "
            "one queue need --physics mjx"
        )


def default_slots() -> int:
    """Slots per JAX device on the C path (measured: BENCHMARKS.md)."""
    return 64


# (re-exported for the tests)
__all__ = [
    "CEngine",
    "CPhysics",
    "CState",
    "PATHS",
    "TIME0",
    "call",
    "default_threads",
    "fold_period",
    "sensor_xml",
    "unsupported",
]
