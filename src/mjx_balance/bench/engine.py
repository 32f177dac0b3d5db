"""The engine's time per control period, split into its parts, on each physics path
(``mjx-balance bench engine``).

What runs. The cells of a force x duration grid (by default the default sweep's durations and
forces 0-155 N every 5 N: 256 cells of 12 s) go through the continuous-batching engine as
``sweep`` runs them: ``rollout.BatchRunner`` with the engine's defaults (slots per device, the
block of control periods, the refill buffer, certified early stop, every local device), all
cells through one queue (a sweep's chunks share one queue too: chunking only decides when a
chunk file is written). The runs are driven by :func:`drive_mjx` / :func:`drive_c`, copies of
``Engine.stream`` / ``CEngine.stream`` with clocks between the calls: the same compiled calls
on the same inputs (tests/test_bench_engine.py checks that they return ``Engine.run``'s bytes).

Three kinds of figures (``how`` in the table and the JSON):

- **in run**: clocked inside the timed runs (the mean over ``runs``): the host's work between
  the compiled calls: the queue and the results in Python, the transfers host -> device
  (``device_put``) and device -> host (``np.asarray`` / ``device_get``), and on the C path the
  MuJoCo C physics (``mujoco.rollout`` on its thread pool) and the decoding of its samples.
  The compiled calls themselves (dispatch to ready) are clocked too (``device call``, not in
  the sum: the isolated parts split them).
- **isolated**: each stage of a control period as a compiled function of its own, with the
  engine's ``vmap`` over the slots and ``shard_map`` over the devices, timed on the stage's
  inputs captured from the first timed run, over many periods in one ``scan`` (as the engine's
  block: each device loops on its own): the median of ``repeats`` calls after a compiling one,
  less the median of a no-op with the same arguments and as many outputs (a call's own
  cost). Of every
  100 control periods (an MJX block; 100 calls on the C path) the first ``sampled`` are
  replayed and stand for the 100. The MJX path replays a block from the state it started with,
  one stage call at a time, to get each stage's inputs (with ``sampled = block`` the replay
  ends in the engine's own state, bit for bit, which the bench checks); the C path replays each
  sampled call from its recorded inputs and checks its outputs against the call's, bit for bit.
  ``compiled calls' own cost``: a no-op with the engine call's arguments and donation and as
  many outputs, dispatched as the engine does, times the number of calls.
- **remainder**: the end-to-end time minus the sum of the parts, printed, never hidden: what no
  part holds (inside the calls: the block's loop, the dead-slot resets, the output packing; on
  the host: loop glue), the error of timing stages apart (a stage alone writes its outputs,
  which the engine's loop may keep in place), and on a shared machine the load's drift between
  the runs and the replay. It is split into its side inside the compiled calls (their time in
  run minus the isolated parts) and its side on the host.

The stages, per control period, over every slot (busy or vacant):

- physics steps: MJX: ``substeps`` x (``mjx.step`` + reading the sample, the fall rules and
  the accumulators) + one ``mjx.kinematics`` (``kernel.period`` after the solve); the bare
  steps (``mjx.step`` x substeps + one ``mjx.kinematics``) are timed as information. C: the
  rollout (in run); the samples' decoding on the host (in run) and their folding into the
  accumulators on the device (``cpath.fold_period``, isolated) are parts of their own.
- QP build: ``kernel.control`` without the solve: the state from the measurement buffer, the
  delay prediction or offset-free target where set, the solve's statistics, the input buffer;
  on the MJX path also the reset of a dead slot before the solve and the selection after it.
  The QP's matrices never change (condensed and factorised once, ``admm.build_admm``): per
  solve only its vectors move, inside ``admm_solve``; they are timed apart as information.
- ADMM: ``kernel.solve_batch`` over the slots: one ``while_loop`` per device (or per tile of
  ``engine.tile`` slots solved one after the other, ``--admm-tile``), which runs until its
  slowest slot stops. Iterations are counted per busy slot and per loop and period (the
  slowest slot's, what the loop costs).
- certificate: ``engine.certify`` (the check runs every ``CHECK_EVERY`` periods).
- refill, harvest, vacate: the engine's compaction (decided slots out, new cells in).

The stage functions mirror ``kernel.period`` / ``kernel.control`` / ``cpath.call`` piece by
piece; the replay's bit-for-bit checks above are what holds them to it.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from contextlib import contextmanager
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..control import admm as admm_mod
from ..control import certificate as cert_mod
from ..model.params import Config
from ..rollout import BatchRunner, cpath
from ..rollout import engine as engine_mod
from ..rollout import kernel
from ..rollout.kernel import (
    Carry,
    initial_carry,
    limits_of,
    measure_step,
    remember,
    sample_update,
    select,
    start,
    with_positions,
)
from ..rollout.physics import mjx, step
from ..rollout.runner import push_steps
from ..runs.grid import grid_cells, parse_grid
from ..runtime.compiled import MATMUL_PRECISION

# The default grid: the default sweep's durations (sweeps/default.toml), forces 0-155 N every
# 5 N (twice its force resolution): 256 cells.
DEFAULT_FORCES = "0:155:5"
DEFAULT_DURATIONS = "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5"

PARTS = {  # key: (label, how) in the table's order; "how" may differ per path (see split)
    "physics": "physics steps",
    "samples_host": "samples: decode (host)",
    "samples": "samples: fold, fall rules, accumulators",
    "qp_build": "QP build (kernel.control without the solve)",
    "admm": "ADMM iterations (admm_solve)",
    "certificate": "certificate check",
    "refill": "refill, harvest, vacate",
    "call": "compiled calls' own cost (a no-op's)",
    "transfers": "transfers host <-> device",
    "python": "Python driver (queue, results)",
}
INFO = {  # timed, not parts of the sum
    "bare_physics": "of physics: bare mjx.step x substeps + kinematics",
    "qp_vectors": "of ADMM: the per-solve QP vectors and warm start",
    "device_call": "compiled calls, dispatch to ready (in run)",
}


# --------------------------------------------------------------------------------------------
# One lane's stages (mirrors of kernel.period and kernel.control)


def physics(arrays, sensors, static, carry: Carry, k, force, n_push, torques, *, u) -> Carry:
    """``kernel.period`` after the solve, lean path: ``substeps`` physics steps, each sample
    completed with the positions the next step computes, the last with one kinematics."""
    dtype = arrays.d0.qpos.dtype
    S = static.substeps

    def fold(carry, s, i):
        acc = sample_update(carry.acc, s, i, torques, u, carry.q_prev, carry.x_prev,
                            limits_of(arrays, static))
        return carry._replace(q_prev=s.q, x_prev=s.x, acc=acc)

    def lean_step(cs, i):
        carry, pending = cs
        d = step(arrays.mx, sensors, carry.d, torques,
                 jnp.where(i < n_push, force, jnp.zeros((), dtype)), static.push_at_hip)
        folded = fold(carry, with_positions(pending, arrays, sensors, d), i - 1)
        kept = select(i > k * S, (folded.acc, folded.q_prev, folded.x_prev),
                      (carry.acc, carry.q_prev, carry.x_prev))
        carry = carry._replace(acc=kept[0], q_prev=kept[1], x_prev=kept[2])
        s = measure_step(arrays, sensors, d)
        return (carry._replace(d=d, history=remember(carry.history, s)), s), None

    steps = k * S + jnp.arange(S, dtype=jnp.int32)
    (carry, last), _ = jax.lax.scan(lean_step, (carry, measure_step(arrays, sensors, carry.d)),
                                    steps)
    positions = mjx.kinematics(arrays.mx, carry.d)
    return fold(carry, with_positions(last, arrays, sensors, positions), steps[-1])


def bare_physics(arrays, sensors, static, d, k, force, n_push, torques):
    """Only the physics of :func:`physics`: ``substeps`` steps and one kinematics."""
    dtype = arrays.d0.qpos.dtype

    def one(d, i):
        push = jnp.where(i < n_push, force, jnp.zeros((), dtype))
        return step(arrays.mx, sensors, d, torques, push, static.push_at_hip), None

    d, _ = jax.lax.scan(one, d, k * static.substeps + jnp.arange(static.substeps, dtype=jnp.int32))
    return mjx.kinematics(arrays.mx, d).xpos


def qp_vectors(data: admm_mod.ADMMData, x0, warm):
    """The per-solve work of ``admm_solve`` outside its iterations, from the public data: the
    linear term, the offset, the scaled bounds and the warm start's scaling (information:
    the QP's matrices never change, so this is all the QP building a period does)."""
    q, g, shift = x0 @ data.FT, x0 @ data.GT, x0 @ data.bT
    x = warm.z @ data.T_inv.T
    return q, g, data.l0 - shift, data.u0 - shift, x @ data.AT, warm.y * data.E / data.rho


# --------------------------------------------------------------------------------------------
# Clocks


class Clock:
    """Seconds per named segment, and pauses left out of the total."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self.paused_s = 0.0
        self.t0 = time.perf_counter()

    @contextmanager
    def __call__(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0

    @contextmanager
    def paused(self):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.paused_s += time.perf_counter() - t0

    def total(self) -> float:
        return time.perf_counter() - self.t0 - self.paused_s


class Drive(NamedTuple):
    """One instrumented engine run."""

    raw: dict  # cell -> results, as Engine.run returns them
    seconds: float  # end to end (paused recording left out)
    parts: dict  # name -> seconds (in run)
    periods: int  # control periods of the engine's loop (every slot)
    calls: int  # compiled calls (host round trips)
    records: list  # what the replay needs (first run only)


def _collect(out: dict, index, raw: dict, n: int) -> None:
    for name, v in raw.items():
        if name not in out:
            out[name] = np.zeros((n,) + v.shape[1:], v.dtype)
        out[name][index] = v


# --------------------------------------------------------------------------------------------
# The instrumented runs (copies of Engine.stream and CEngine.stream, clocks between the calls)


def drive_mjx(engine, forces, n_push, *, record: bool = False, sampled: int = 0) -> Drive:
    """``Engine.stream`` over every cell with clocks; ``record``: keep each call's inputs (the
    slots' state and the refill offer, host copies, outside the clock) for the replay
    (``sampled``: not used here, the replay samples inside each recorded block)."""
    forces, n_push = np.asarray(forces, np.float64), np.asarray(n_push, np.int32)
    n = forces.shape[0]
    fn = engine.block_fn()
    r = engine.runner
    batch_sharding, _ = r._shardings()
    state = engine._state if engine._state is not None else engine._initial_state()
    engine._state = None
    clock, out, records, calls = Clock(), {}, [], 0
    queue = engine_mod.Queue(forces, n_push, engine.n_devices, engine.refill,
                             block=engine.block)
    remaining = n
    while remaining:
        with clock("python"):
            cells, f, p, init = queue.offer()
        with clock("transfers"):
            args = _offer_args(r, batch_sharding, cells, f, p, init)
        if record:
            with clock.paused():
                records.append((jax.device_get(state), jax.device_get(args)))
        with clock("device_call"):
            state, taken, done = jax.block_until_ready(fn(r.arrays, engine.cert, state, *args))
        calls += 1
        with clock("transfers"):
            taken, index, acc, periods, certified = _fetch(taken, done)
        with clock("python"):
            queue.took(taken)
            keep = index >= 0
            if keep.any():
                raw = {name: v[keep] for name, v in zip(engine_mod.Accumulators._fields, acc)}
                raw["periods"], raw["certified"] = periods[keep], certified[keep]
                queue.finished(index[keep], raw["periods"])
                remaining -= int(keep.sum())
                _collect(out, index[keep], raw, n)
    engine._state = state
    if record:  # the state the last block ended in (every slot vacant)
        records.append((jax.device_get(state), None))
    return Drive(out, clock.total(), clock.seconds, calls * engine.block, calls, records)


def warm_up(engine) -> None:
    """One call of the MJX engine's compiled block on vacant slots with nothing to refill
    (its first execution, outside the runs: vacant slots idle at rest, as after any run)."""
    r = engine.runner
    batch_sharding, _ = r._shardings()
    n = engine.refill * engine.n_devices
    args = _offer_args(r, batch_sharding, np.full(n, -1, np.int32), np.zeros(n),
                       np.zeros(n, np.int32), np.zeros((n, 4)))
    state = engine._state if engine._state is not None else engine._initial_state()
    state, taken, done = engine.block_fn()(r.arrays, engine.cert, state, *args)
    _fetch(taken, done)
    engine._state = state


def _offer_args(r, batch_sharding, cells, f, p, init) -> tuple:
    """The refill offer on the devices, as ``Engine.stream`` places it."""
    args = (jnp.asarray(cells), jnp.asarray(f.astype(r.dtype)), jnp.asarray(p),
            jnp.asarray(init.astype(r.dtype)))
    if batch_sharding is None:
        return args
    return tuple(jax.device_put(a, batch_sharding) for a in args)


def _fetch(taken, done) -> tuple:
    """A call's outputs on the host, as ``Engine.stream`` reads them."""
    return (np.asarray(taken), np.asarray(done.cell), [np.asarray(v) for v in done.acc],
            np.asarray(done.periods), np.asarray(done.certified))


def drive_c(engine, forces, n_push, *, record: bool = False, sampled: int = 10) -> Drive:
    """``CEngine.stream`` over every cell with clocks; ``record``: keep the inputs and outputs
    of the calls the replay samples (the first ``sampled`` of every 100), outside the clock."""
    forces, n_push = np.asarray(forces, np.float64), np.asarray(n_push, np.int32)
    n = forces.shape[0]
    fn = engine.block_fn()
    r, c = engine.runner, engine.c
    cs = engine._state if engine._state is not None else engine._initial_state()
    engine._state = None
    template = jax.eval_shape(lambda: initial_carry(r.arrays, r.sensors, r.static).acc)
    B, S = engine.slots * engine.n_devices, c.substeps
    phys, warm = np.tile(c.rest, (B, 1)), np.tile(c.rest_warm, (B, 1))
    rows, last_qpos = np.zeros((B, S, cpath.ROW)), np.tile(c.rest[c.qpos], (B, 1))
    queue = engine_mod.Queue(forces, n_push, engine.n_devices, engine.refill)
    clock, out, records, remaining, p = Clock(), {}, [], n, 0
    while remaining:
        with clock("python"):
            cells, f, pp, _ = queue.offer()
            floats, ints = cpath.pack(rows, last_qpos, cells, f, pp, p, r.dtype)
        with clock("transfers"):
            args = (engine._put(floats), engine._put(ints))
        sample = record and p % SAMPLE_GROUP < sampled
        if sample:
            with clock.paused():
                kept = jax.device_get(cs)
        with clock("device_call"):
            cs, out_f, out_i = jax.block_until_ready(fn(engine._leaves, cs, *args))
        with clock("transfers"):
            out_f, out_i = jax.device_get((out_f, out_i))
        if sample:
            records.append((p, kept, floats, ints, out_f, out_i))
        p += 1
        with clock("python"):
            torques, push = out_f[:, :2], out_f[:, 2:2 + S]
            reset, busy, index = out_i[:, 0] > 0, out_i[:, 1] > 0, out_i[:, 2]
            queue.took(out_i[::engine.slots, 5])
            keep = index >= 0
            if keep.any():
                raw = cpath.unpack_acc(out_f[keep, 2 + S:], out_i[keep, 6:], template)
                raw["periods"], raw["certified"] = out_i[keep, 3], out_i[keep, 4] > 0
                queue.finished(index[keep], raw["periods"])
                remaining -= int(keep.sum())
                _collect(out, index[keep], raw, n)
        if not remaining:
            break
        with clock("samples_host"):
            phys[reset], warm[reset] = c.rest, c.rest_warm
            run = np.flatnonzero(busy)
        if run.size:
            with clock("physics"):
                states, sens = c.advance(phys[run], warm[run], torques[run].astype(float),
                                         push[run].astype(float))
            with clock("samples_host"):
                warm[run] = c.next_warm(phys[run], states)
                phys[run] = states[:, -1]
                phys[run, 0] = cpath.TIME0
                rows[run], last_qpos[run] = c.samples(states, sens)
    engine._state = cs
    return Drive(out, clock.total(), clock.seconds, p, p, records)


# The C path's calls are sampled in groups of this many periods (the MJX path's block)
SAMPLE_GROUP = 100


# --------------------------------------------------------------------------------------------
# Stages as compiled functions, timed over many periods per call


class Stages:
    """The stage functions of a control period, compiled over the runner's devices (``vmap``
    inside a body, ``shard_map`` over the devices as the engine's calls).

    A body is ``body(arrays, cert, *args)`` on one device's share; every ``arg`` is split over
    the devices along its leading axis (per-device numbers as arrays [devices]); the shared
    arrays are passed replicated, flat, once placed (as ``CEngine`` does).

    :meth:`scan` times a stage over many periods in one compiled ``scan`` (as the engine's
    block runs its periods: each device loops on its own, the devices meet at the end of the
    call): the median of ``repeats`` calls after a first (compiling) one, less the median of a
    no-op of the same arguments and as many outputs (:func:`noop_outputs`: the call's own
    cost), times ``weight`` (the periods each replayed period stands for); it returns the
    stage's outputs of every period. Where a period's inputs need the period before (the MJX path), the replay
    calls each stage once per period instead (:meth:`__call__`, not timed), which keeps the
    inputs for :meth:`flush` to time with :meth:`scan`."""

    def __init__(self, engine, repeats: int):
        r = engine.runner
        self.mesh, self.repeats = r.mesh, max(1, int(repeats))
        self.split, whole = r._shardings()
        self.stacked = (None if self.mesh is None else jax.sharding.NamedSharding(
            self.mesh, jax.sharding.PartitionSpec(None, "batch")))
        leaves, self.treedef = jax.tree.flatten((r.arrays, engine.cert))
        self.leaves = tuple(leaves if whole is None else jax.device_put(leaves, whole))
        self.fns: dict[Any, Any] = {}
        self.overhead: dict[str, float] = {}
        self.seconds: dict[str, float] = {}
        self.kept: dict[str, list] = {}
        self.bodies: dict[str, Any] = {}
        self._stack = jax.jit(lambda *trees: jax.tree.map(lambda *v: jnp.stack(v), *trees),
                              out_shardings=self.stacked)

    def put(self, tree, stacked: bool = False):
        sharding = self.stacked if stacked else self.split
        return jax.tree.map(jnp.asarray if sharding is None
                            else (lambda a: jax.device_put(a, sharding)), tree)

    def _fn(self, name: str, body, n_args: int, scan: bool = False):
        """The compiled stage: one period, or (``scan``) every period of stacked inputs."""
        if (name, scan) not in self.fns:
            treedef = self.treedef

            def call(leaves, *args):
                arrays, cert = jax.tree.unflatten(treedef, leaves)
                if not scan:
                    return body(arrays, cert, *args)
                return jax.lax.scan(lambda c, x: (c, body(arrays, cert, *x)), 0, args)[1]

            self.fns[name, scan] = self.sharded(call, n_args, scan)
        return self.fns[name, scan]

    def sharded(self, call, n_args: int, scan: bool = False, donate: tuple = ()):
        """``jit`` of ``call(leaves, *args)``, under ``shard_map`` over the devices."""
        if self.mesh is None:
            return jax.jit(call, keep_unused=True, donate_argnums=donate)
        P = jax.sharding.PartitionSpec
        spec = P(None, "batch") if scan else P("batch")
        return jax.jit(jax.shard_map(call, mesh=self.mesh, in_specs=(P(),) + (spec,) * n_args,
                                     out_specs=spec, check_vma=False),
                       keep_unused=True, donate_argnums=donate)

    def __call__(self, name: str, body, *args, keep: bool = True, run: bool = True):
        """``body`` on ``args`` (one period); with ``keep``, the inputs kept for :meth:`flush`
        (with ``run`` False only kept: a stage whose outputs the next stages do not need)."""
        if keep:
            self.bodies[name] = body
            self.kept.setdefault(name, []).append(args)
        if run:
            with jax.default_matmul_precision(MATMUL_PRECISION):
                return jax.block_until_ready(self._fn(name, body, len(args))(self.leaves, *args))
        return None

    def scan(self, name: str, body, *args, weight: float = 1.0, timed: bool = True):
        """``body`` over periods: every ``arg`` stacked [periods, ...] (:meth:`put` with
        ``stacked``); returns the outputs stacked; with ``timed``, the seconds (see the class)
        added to ``name``."""
        with jax.default_matmul_precision(MATMUL_PRECISION):
            fn = self._fn(name, body, len(args), scan=True)
            if not timed:
                return jax.block_until_ready(fn(self.leaves, *args))
            if name not in self.overhead:
                jax.block_until_ready(fn(self.leaves, *args))  # compiles
                shapes = jax.eval_shape(fn, self.leaves, *args)  # (jit's own trace)
                noop = self.sharded(lambda leaves, *a: noop_outputs(shapes, stacked=True),
                                    len(args), scan=True)
                jax.block_until_ready(noop(self.leaves, *args))
                self.overhead[name] = _median_call(noop, self.leaves, args, 5)[0]
            seconds, out = _median_call(fn, self.leaves, args, self.repeats)
        self.seconds[name] = (self.seconds.get(name, 0.0)
                              + (seconds - self.overhead[name]) * weight)
        return out

    def flush(self, weight: float) -> None:
        """Time every stage over the periods kept since the last flush (:meth:`scan`)."""
        for name, kept in self.kept.items():
            self.scan(name, self.bodies[name], *self._stack(*kept), weight=weight)
        self.kept = {}


def noop_outputs(shapes, stacked: bool = False):
    """Outputs of the tree structure and types of ``shapes``, one element per device each: a
    no-op's outputs (as many arrays as the real function returns, next to no data)."""
    return jax.tree.map(lambda v: jnp.zeros((1, 1) if stacked else (1,), v.dtype), shapes)


def _median_call(fn, leaves, args, repeats: int) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn(leaves, *args))
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), out


class Iterations:
    """ADMM iterations of the replayed solves: per busy slot, and per loop and call (the
    slowest slot of a device's slots or of a tile of them, which its ``while_loop`` waits
    for; ``loops``: loops per period over all devices, in slot order, default one per
    device); how often each ran to the cap ``cap``."""

    def __init__(self, devices: int, cap: int, loops: int | None = None):
        self.devices, self.cap = devices, cap
        self.loops = devices if loops is None else loops
        self.lane_sum = self.lanes = self.block_sum = self.blocks = 0
        self.lanes_capped = self.blocks_capped = 0

    def add(self, iters, busy) -> None:
        iters, busy = np.asarray(iters), np.asarray(busy)
        self.lane_sum += int(iters[busy].sum())
        self.lanes += int(busy.sum())
        self.lanes_capped += int((iters[busy] >= self.cap).sum())
        slowest = iters.reshape(self.loops, -1).max(axis=1)
        self.block_sum += int(slowest.sum())
        self.blocks += self.loops
        self.blocks_capped += int((slowest >= self.cap).sum())

    def figures(self) -> dict[str, float]:
        per_lane = self.lane_sum / max(1, self.lanes)
        per_block = self.block_sum / max(1, self.blocks)
        return {"per_busy_slot": round(per_lane, 2), "per_block": round(per_block, 2),
                "block_over_slot": round(per_block / per_lane, 2) if per_lane else math.nan,
                "cap": self.cap,
                "busy_slots_at_cap": round(self.lanes_capped / max(1, self.lanes), 4),
                "blocks_at_cap": round(self.blocks_capped / max(1, self.blocks), 4)}


class Agreement:
    """How the replay's values compare with the engine's, bit for bit: values compared, values
    that differ, and the largest relative difference among those."""

    def __init__(self):
        self.values = self.differ = 0
        self.max_rel = 0.0

    def add(self, a, b) -> None:
        la, lb = jax.tree.leaves(a), jax.tree.leaves(b)
        if len(la) != len(lb):
            raise ValueError("the replay's outputs do not have the engine's structure")
        for x, y in zip(la, lb):
            x, y = np.asarray(x), np.asarray(y)
            if x.shape != y.shape or x.dtype != y.dtype:
                raise ValueError(f"replay output {x.shape} {x.dtype}, engine {y.shape} {y.dtype}")
            raw_x = x.reshape(-1).view(np.uint8).reshape(x.size, -1) if x.size else x
            raw_y = y.reshape(-1).view(np.uint8).reshape(y.size, -1) if y.size else y
            diff = (raw_x != raw_y).any(axis=-1) if x.size else np.zeros(0, bool)
            self.values += x.size
            self.differ += int(diff.sum())
            if diff.any() and np.issubdtype(x.dtype, np.floating):
                u, v = x.reshape(-1)[diff].astype(float), y.reshape(-1)[diff].astype(float)
                with np.errstate(invalid="ignore", divide="ignore"):
                    rel = np.abs(u - v) / np.maximum(np.abs(v), np.finfo(x.dtype).tiny)
                self.max_rel = max(self.max_rel, float(np.nanmax(rel, initial=0.0)))
            elif diff.any():
                self.max_rel = math.inf

    def figures(self, checked: int) -> dict:
        return {"checked": checked, "values": self.values, "differ": self.differ,
                "max_rel_diff": self.max_rel, "identical": self.differ == 0 if checked else None}


def call_cost(engine, stages: Stages, tail: tuple, repeats: int = 9) -> dict[str, Any]:
    """Seconds of one of the engine's compiled calls that do nothing: a no-op with the call's
    arguments, shardings and donation and as many outputs (:func:`noop_outputs`), dispatched as the
    engine dispatches its call (the MJX block ahead of time, the C path's period call through
    jit); the median of ``repeats``. ``tail``: the host inputs of one recorded call after the
    shared arrays (MJX: the slots and the refill offer; C: the slots, floats and ints).
    Returns seconds (per call) and the arrays the call takes and returns."""
    r = engine.runner
    fn = engine.block_fn()
    c_path = isinstance(engine, cpath.CEngine)
    head = (engine._leaves,) if c_path else (r.arrays, engine.cert)
    shapes = (jax.eval_shape(fn, *head, *stages.put(tail)) if c_path  # (jit's own trace)
              else fn.out_info)
    def run(*args):
        return noop_outputs(shapes)

    if r.mesh is not None:
        P = jax.sharding.PartitionSpec
        run = jax.shard_map(run, mesh=r.mesh, out_specs=P("batch"), check_vma=False,
                            in_specs=(P(),) * len(head) + (P("batch"),) * len(tail))
    noop = jax.jit(run, donate_argnums=(len(head),), keep_unused=True)
    if not c_path:
        noop = noop.lower(*head, *stages.put(tail)).compile()
    times = []
    with warnings.catch_warnings():  # (the no-op uses none of the buffers it is donated)
        warnings.filterwarnings("ignore", message=".*donated buffers were not usable")
        for _ in range(repeats + 1):
            args = stages.put(tail)
            t0 = time.perf_counter()
            jax.block_until_ready(noop(*head, *args))
            times.append(time.perf_counter() - t0)
    return {"seconds": float(np.median(times[1:])),
            "arrays_in": len(jax.tree.leaves((head, tail))),
            "arrays_out": len(jax.tree.leaves(shapes))}


# --------------------------------------------------------------------------------------------
# The MJX path: each block replayed stage by stage from the state it started with


def mjx_bodies(engine) -> dict[str, Any]:
    """The stage bodies of one MJX control period (``engine.block``'s step, in its order)."""
    r = engine.runner
    sensors, static, packing, S = r.sensors, r.static, engine.packing, engine.slots
    every = cert_mod.CHECK_EVERY
    early = engine.cert is not None

    def rest(arrays):
        return engine_mod.broadcast(initial_carry(arrays, sensors, static), S)

    def unpack(arrays, cert, slots, inits):
        single = initial_carry(arrays, sensors, static)
        starts = jax.vmap(lambda init: start(arrays, sensors, single, init))(inits)
        return slots._replace(carry=packing.unpack(slots.carry, S)), starts

    def refill(arrays, cert, slots, taken, s, offer):
        cells, force, push, starts = offer
        vacant = slots.cell < 0
        if early:
            vacant = vacant & (s[0] % every == 0)
        slots, taken = engine_mod.refill(slots, rest(arrays), taken[0], vacant, cells, force, push,
                                         starts)
        return slots, taken[None]

    def certify(arrays, cert, carry, due):
        k = due.k + 1
        ended = ~carry.acc.alive | (k >= arrays.n_control)
        acc, certified = engine_mod.certify(engine_mod.checker(cert if early else None), static,
                                            carry.x_prev, carry.acc, k, due.n_push, ended,
                                            due.due[0], n_control=arrays.n_control,
                                            force=due.force)
        return acc, certified, (due.cell >= 0) & (ended | certified)

    def harvest(arrays, cert, buffer, decided, slots, acc, certified, carry):
        done, n_done = buffer
        k = slots.k + 1
        done, n_done = engine_mod.harvest(done, n_done[0], decided, slots.cell, acc, k, certified)
        return done, n_done[None], engine_mod.vacate(decided, rest(arrays), carry, slots, k)

    return dict(
        unpack=unpack, refill=refill, certify=certify, harvest=harvest,
        pack=lambda arrays, cert, slots: slots._replace(carry=packing.pack(slots.carry)),
        prepare=lambda arrays, cert, carry, k: jax.vmap(
            lambda c: kernel.prepare(arrays, static, c,
                                     initial_carry(arrays, sensors, static)))(carry),
        solve=lambda arrays, cert, pre: kernel.solve_batch(arrays, static, pre, engine.tile),
        conclude=lambda arrays, cert, pre, res, k: jax.vmap(
            lambda p, q, k: kernel.conclude(arrays, static, p, q, k,
                                            initial_carry(arrays, sensors, static)))(
                pre, res, k),
        physics=lambda arrays, cert, carry, slots, torques, u: jax.vmap(
            lambda c, k, f, n, t, u: physics(arrays, sensors, static, c, k, f, n, t, u=u))(
            carry, slots.k, slots.force, slots.n_push, torques, u),
        bare_physics=lambda arrays, cert, d, slots, torques: jax.vmap(
            lambda d, k, f, n, t: bare_physics(arrays, sensors, static, d, k, f, n, t))(
            d, slots.k, slots.force, slots.n_push, torques),
        qp_vectors=lambda arrays, cert, pre: jax.vmap(
            lambda p: qp_vectors(arrays.qp, p.x0, p.carry.warm))(pre),
    )


class CertifyInputs(NamedTuple):
    """The per-period numbers a certify body needs besides the slots."""

    k: jax.Array
    n_push: jax.Array
    force: jax.Array
    cell: jax.Array
    due: jax.Array  # [devices] bool: this period checks the certificate


def mjx_period(stages: Stages, bodies: dict, held: dict, s: int, iters: Iterations) -> dict:
    """One control period of the replay (``engine.block``'s step): ``held`` is what one period
    hands the next (slots, taken, done, n_done and the block's refill arrays); returns it
    updated."""
    D = iters.devices
    every = cert_mod.CHECK_EVERY
    s_arr = stages.put(np.full(D, s, np.int32))
    slots, taken = stages("refill", bodies["refill"], held["slots"], held["taken"], s_arr,
                          (*held["offer"], held["starts"]))
    pre = stages("prepare", bodies["prepare"], slots.carry, slots.k)
    stages("qp_vectors", bodies["qp_vectors"], pre, run=False)
    res = stages("solve", bodies["solve"], pre)
    iters.add(res.iters, np.asarray(slots.cell) >= 0)
    carry, u, torques = stages("conclude", bodies["conclude"], pre, res, slots.k)
    stages("bare_physics", bodies["bare_physics"], carry.d, slots, torques, run=False)
    carry = stages("physics", bodies["physics"], carry, slots, torques, u)
    due = CertifyInputs(slots.k, slots.n_push, slots.force, slots.cell,
              stages.put(np.full(D, s % every == every - 1)))
    acc, certified, decided = stages("certify", bodies["certify"], carry, due)
    done, n_done, slots = stages("harvest", bodies["harvest"], (held["done"], held["n_done"]),
                                 decided, slots, acc, certified, carry)
    return dict(held, slots=slots, taken=taken, done=done, n_done=n_done)


def replay_mjx(engine, records: list, stages: Stages, sampled: int) -> dict[str, Any]:
    """Every recorded block's first ``sampled`` periods, stage by stage. Returns the stage
    seconds scaled to whole blocks, the ADMM iterations and, where whole blocks were replayed,
    whether the replay ended in the engine's own state (bit for bit)."""
    bodies = mjx_bodies(engine)
    r = engine.runner
    D = engine.n_devices
    periods = min(int(sampled), engine.block)
    iters = Iterations(D, r.static.settings.iteration_cap,
                       loops=D * engine.slots // (engine.tile or engine.slots))
    checked, agreement = 0, Agreement()
    for b, (packed, offer) in enumerate(records[:-1]):
        packed, offer = stages.put(packed), stages.put(offer)
        slots, starts = stages("unpack", bodies["unpack"], packed, offer[3], keep=False)
        empty = engine_mod.empty_finished(engine.slots + engine.refill, r.dtype)
        held = dict(slots=slots, taken=stages.put(np.zeros(D, np.int32)), offer=offer[:3],
                    starts=starts, n_done=stages.put(np.zeros(D, np.int32)),
                    done=stages.put(jax.tree.map(lambda v: np.concatenate([v] * D),
                                                 jax.device_get(empty))))
        for s in range(periods):
            held = mjx_period(stages, bodies, held, s, iters)
        stages.flush(engine.block / periods)
        if periods == engine.block:
            packed = stages("pack", bodies["pack"], held["slots"], keep=False)
            agreement.add(jax.device_get(packed), records[b + 1][0])
            checked += 1
    cost = call_cost(engine, stages, (records[0][0], *records[0][1]))
    seconds = dict(stages.seconds, call=cost["seconds"] * (len(records) - 1))
    return dict(seconds=seconds, call=cost,
                iterations=iters.figures(), agreement=agreement.figures(checked),
                sampled_periods=periods * (len(records) - 1))


# --------------------------------------------------------------------------------------------
# The C path: each sampled call replayed stage by stage from its recorded inputs


def c_bodies(engine) -> dict[str, Any]:
    """The stage bodies of one call of the C path (``cpath.call``, in its order)."""
    r = engine.runner
    sensors, static, B, S = r.sensors, r.static, engine.slots, r.static.substeps
    every = cert_mod.CHECK_EVERY
    early = engine.cert is not None

    def rest(arrays):
        return engine_mod.broadcast(initial_carry(arrays, sensors, static)._replace(d=None), B)

    def fold(arrays, cert, cs, floats, ints):
        rows, last_qpos, cell, force, push, p = cpath.unpack(floats, ints, S)
        slots = cs.slots
        folded = jax.vmap(lambda c, w, q, k, t, u: cpath.fold_period(
            arrays, sensors, static, c, w, q, k, torques=t, u=u))(slots.carry, rows, last_qpos,
                                                                 slots.k, cs.torques, cs.u)
        carry = select(cs.ran, folded, slots.carry)
        k = jnp.where(cs.ran, slots.k + 1, slots.k)
        return carry, k, ~carry.acc.alive | (k >= arrays.n_control), (cell, force, push), p[None]

    def certify(arrays, cert, carry, k, n_push, force, ended, p):
        return engine_mod.certify(engine_mod.checker(cert if early else None), static,
                                  carry.x_prev, carry.acc, k, n_push, ended,
                                  (p[0] - 1) % every == every - 1, n_control=arrays.n_control,
                                  force=force)

    def refill(arrays, cert, cs, carry, verdict, offer, p):
        acc, k, certified, ended = verdict
        decided = cs.ran & (ended | certified)
        zero = jnp.zeros((), jnp.int32)
        done, _ = engine_mod.harvest(engine_mod.empty_finished(B, r.dtype), zero, decided,
                                     cs.slots.cell, acc, k, certified)
        slots = engine_mod.vacate(decided, rest(arrays), carry, cs.slots, k)
        vacant = slots.cell < 0
        if early:
            vacant = vacant & (p[0] % every == 0)
        slots, taken = engine_mod.refill(slots, rest(arrays), zero, vacant, *offer)
        return slots, vacant & (slots.cell >= 0), taken[None], done

    def finish(arrays, cert, slots, u, torques, fresh, taken, done):
        busy = slots.cell >= 0
        steps = slots.k[:, None] * S + jnp.arange(S, dtype=jnp.int32)[None]
        push = jnp.where(steps < slots.n_push[:, None], slots.force[:, None],
                         jnp.zeros((), r.dtype))
        acc_f, acc_i = cpath.pack_acc(done.acc)
        flags = jnp.stack([fresh, busy, done.cell, done.periods, done.certified,
                           jnp.broadcast_to(taken[0], (B,))], axis=1).astype(jnp.int32)
        return (jnp.concatenate([torques, push, acc_f], axis=1),
                jnp.concatenate([flags, acc_i], axis=1))

    return dict(
        fold=fold, certify=certify, refill=refill, finish=finish,
        prepare=lambda arrays, cert, carry, k: jax.vmap(
            lambda c: kernel.prepare(arrays, static, c))(carry),
        solve=lambda arrays, cert, pre: jax.vmap(lambda p: kernel.solve(arrays, static, p))(pre),
        conclude=lambda arrays, cert, pre, res, k: jax.vmap(
            lambda p, q, k: kernel.conclude(arrays, static, p, q, k))(pre, res, k),
        qp_vectors=lambda arrays, cert, pre: jax.vmap(
            lambda p: qp_vectors(arrays.qp, p.x0, p.carry.warm))(pre),
    )


def c_group(stages: Stages, bodies: dict, records: list, weight: float,
            iters: Iterations, agreement: Agreement) -> None:
    """The recorded calls of one group, stage after stage, each stage over all of them in one
    scan (every call starts from its own recorded inputs); the outputs compared with the
    calls' own (``agreement``)."""
    cs, floats, ints, out_f, out_i = _stack([r[1:] for r in records])
    cs, floats, ints = stages.put((cs, floats, ints), stacked=True)

    def scan(name, *args, timed=True):
        return stages.scan(name, bodies[name], *args, weight=weight, timed=timed)

    carry, k, ended, offer, p = scan("fold", cs, floats, ints)
    acc, certified = scan("certify", carry, k, cs.slots.n_push, cs.slots.force, ended, p)
    slots, fresh, taken, done = scan("refill", cs, carry, (acc, k, certified, ended), offer, p)
    pre = scan("prepare", slots.carry, slots.k)
    scan("qp_vectors", pre)
    res = scan("solve", pre)
    for it, cell in zip(np.asarray(res.iters), np.asarray(slots.cell)):
        iters.add(it, cell >= 0)
    carry, u, torques = scan("conclude", pre, res, slots.k)
    out = scan("finish", slots, u, torques, fresh, taken, done, timed=False)
    agreement.add(jax.device_get(out), (out_f, out_i))


def _stack(rows: list) -> tuple:
    """Per-call records [(cs, floats, ints, out_f, out_i), ...] stacked along a first axis."""
    return tuple(jax.tree.map(lambda *v: np.stack(v), *column) for column in zip(*rows))


def replay_c(engine, records: list, stages: Stages, sampled: int, periods: int) -> dict:
    """The recorded calls (the first ``sampled`` of every ``SAMPLE_GROUP``), stage by stage;
    each stands for its group's periods. Each is checked against the call's outputs."""
    bodies = c_bodies(engine)
    iters = Iterations(engine.n_devices, engine.runner.static.settings.iteration_cap)
    agreement = Agreement()
    groups: dict[int, list] = {}
    for record in records:
        groups.setdefault(record[0] // SAMPLE_GROUP, []).append(record)
    for group, kept in groups.items():
        in_group = min(SAMPLE_GROUP, periods - group * SAMPLE_GROUP)
        c_group(stages, bodies, kept, in_group / len(kept), iters, agreement)
    cost = call_cost(engine, stages, records[0][1:4])
    seconds = dict(stages.seconds, call=cost["seconds"] * periods)
    return dict(seconds=seconds, call=cost, iterations=iters.figures(),
                agreement=agreement.figures(len(records)),
                sampled_periods=len(records))


# --------------------------------------------------------------------------------------------
# The split


# The isolated stages in each part (seconds of the replay), per path
ISOLATED = {
    "mjx": {"physics": ("physics",), "qp_build": ("prepare", "conclude"), "admm": ("solve",),
            "certificate": ("certify",), "refill": ("refill", "harvest"), "call": ("call",)},
    "c": {"samples": ("fold",), "qp_build": ("prepare", "conclude"), "admm": ("solve",),
          "certificate": ("certify",), "refill": ("refill",), "call": ("call",)},
}
IN_RUN = {"mjx": ("transfers", "python"),
          "c": ("physics", "samples_host", "transfers", "python")}


def _row(seconds: float, how: str, label: str, unit: tuple[float, int], total: float) -> dict:
    periods, lanes = unit
    return {"label": label, "how": how, "seconds": round(seconds, 4),
            "ms_per_period": round(1e3 * seconds / periods, 4),
            "us_per_slot_period": round(1e6 * seconds / (periods * lanes), 4),
            "share": round(seconds / total, 4)}


def split(path: str, drives: list[Drive], replay: dict, lanes: int) -> dict[str, Any]:
    """The parts (in run: the mean over ``drives``; isolated: the replay), the remainder (end to
    end minus their sum; also split into its device and host sides) and the information rows."""
    total = float(np.mean([d.seconds for d in drives]))
    in_run = {k: float(np.mean([d.parts.get(k, 0.0) for d in drives]))
              for k in set().union(*(d.parts for d in drives))}
    unit = (drives[0].periods, lanes)
    # an isolated part below the resolution of its no-op correction counts as 0 (listed)
    iso = {key: max(0.0, sum(replay["seconds"].get(n, 0.0) for n in names))
           for key, names in ISOLATED[path].items()}
    below = [key for key, names in ISOLATED[path].items()
             if sum(replay["seconds"].get(n, 0.0) for n in names) < 0]
    parts = {}
    for key, label in PARTS.items():
        if key in ISOLATED[path]:
            parts[key] = _row(iso[key], "isolated", label, unit, total)
        elif key in IN_RUN[path]:
            parts[key] = _row(in_run.get(key, 0.0), "in run", label, unit, total)
    # the sum and the remainder from the unrounded seconds
    isolated = sum(iso.values())
    summed = isolated + sum(in_run.get(k, 0.0) for k in IN_RUN[path])
    device = in_run.get("device_call", 0.0)
    remainder = _row(total - summed, "remainder", "remainder: end to end minus the parts",
                     unit, total)
    remainder.update(device_s=round(device - isolated, 4),
                     host_s=round(total - device - sum(in_run.get(k, 0.0)
                                                       for k in IN_RUN[path]), 4))
    info = {"device_call": _row(device, "in run", INFO["device_call"], unit, total)}
    for key in ("bare_physics", "qp_vectors"):
        if key in replay["seconds"]:
            info[key] = _row(max(0.0, replay["seconds"][key]), "isolated", INFO[key], unit,
                             total)
    return {"seconds": round(total, 4), "parts": parts, "remainder": remainder, "info": info,
            "total": _row(total, "measured", "end to end", unit, total),
            "below_resolution": below}


def measure_path(config: Config, forces: np.ndarray, durations: np.ndarray, *, physics: str,
                 slots: int | None = None, runs: int = 2, repeats: int = 3,
                 sampled: int = 10, admm_tile: int | None = None,
                 log=print) -> dict[str, Any]:
    """The split of one physics path: build and compile the engine, ``runs`` instrumented runs
    of every cell (the first records the replay's inputs), the replay."""
    t0 = time.perf_counter()
    runner = BatchRunner(config, slots=slots, early_stop=True, physics=physics,
                         admm_tile=admm_tile if physics == "mjx" else None)
    compile_s = runner.prepare()
    engine = runner.engine
    if physics == "mjx":  # the block's first execution, outside the runs
        warm_up(engine)
    build_s = time.perf_counter() - t0
    lanes = engine.slots * engine.n_devices
    log(f"  {physics}: engine ready in {build_s:.1f} s ({engine.slots} slots on each of "
        f"{engine.n_devices} device(s), block {engine.block}, refill {engine.refill}, "
        f"ADMM tile {engine.tile or engine.slots})")
    n_push = push_steps(durations, config.scenario.physics_dt)
    drive = drive_mjx if physics == "mjx" else drive_c
    drives = []
    for i in range(max(1, runs)):
        drives.append(drive(engine, forces, n_push, record=i == 0, sampled=sampled))
        log(f"  {physics}: run {i + 1}: {len(forces)} scenarios in {drives[-1].seconds:.2f} s "
            f"({drives[-1].periods} control periods, {drives[-1].calls} calls)")
    t1 = time.perf_counter()
    stages = Stages(engine, repeats)
    if physics == "mjx":
        replay = replay_mjx(engine, drives[0].records, stages, sampled)
    else:
        replay = replay_c(engine, drives[0].records, stages, sampled, drives[0].periods)
    log(f"  {physics}: replayed {replay['sampled_periods']} control periods stage by stage in "
        f"{time.perf_counter() - t1:.1f} s")
    figures = split(physics, drives, replay, lanes)
    raw = drives[0].raw
    figures.update(
        physics=physics, slots=engine.slots, devices=engine.n_devices, lanes=lanes,
        block=engine.block, refill=engine.refill, admm_tile=engine.tile or engine.slots,
        compile_s=round(compile_s, 3),
        runs=[round(d.seconds, 4) for d in drives], scenarios=len(forces),
        scen_per_s=round(len(forces) / figures["seconds"], 3), periods=drives[0].periods,
        calls=drives[0].calls, certified=int(raw["certified"].sum()),
        occupancy=round(float(raw["periods"].sum()) / (drives[0].periods * lanes), 4),
        admm_iterations=replay["iterations"], repeats=stages.repeats,
        call={k: round(v, 6) if isinstance(v, float) else v for k, v in replay["call"].items()},
        replay=dict(sampled_periods=replay["sampled_periods"],
                    **replay["agreement"]))
    if physics == "c":
        figures["threads"] = engine.c.threads
    return figures


def measure(config: Config, *, forces: str = DEFAULT_FORCES,
            durations: str = DEFAULT_DURATIONS, paths: tuple[str, ...] = ("mjx", "c"),
            slots: int | None = None, runs: int = 2, repeats: int = 3, sampled: int = 10,
            admm_tile: int | None = None, log=print) -> dict[str, Any]:
    """:func:`measure_path` of every path on the cells of ``forces`` x ``durations`` (grid
    specifications as ``sweep`` takes them)."""
    f, d = grid_cells(parse_grid(forces, "forces"), parse_grid(durations, "durations"))
    d = np.minimum(d, config.scenario.t_end)
    load = os.getloadavg()
    out = {"scenarios": int(f.size), "forces": forces, "durations": durations,
           "t_end": config.scenario.t_end, "cpus": os.cpu_count(),
           "load_average_start": [round(v, 2) for v in load], "paths": {}}
    for path in paths:
        if path == "c" and cpath.unsupported(config):
            log(f"  c: skipped ({cpath.unsupported(config)})")
            continue
        out["paths"][path] = measure_path(config, f, d, physics=path, slots=slots, runs=runs,
                                          repeats=repeats, sampled=sampled,
                                          admm_tile=admm_tile, log=log)
    out["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    return out
