"""The replay of ``mjx-balance bench engine``: each stage of a control period as a compiled
function of its own, timed on the inputs the engine's own run recorded (bench/engine.py says
what the figures mean).

The stage bodies call the engines' own parts (``rollout.slots``: ``opened``, ``take``,
``decide``, ``retire``; ``rollout.kernel``: ``prepare_batch``, ``solve_batch`` /
``solve_lanes``, ``conclude_batch``, ``physics_batch``; ``rollout.cpath``: ``folded``,
``judged``, ``turnover``, ``outputs``), the functions ``slots.block`` and ``cpath.call`` are
made of, so a stage timed here is the engine's code. The replay checks that it ends where the
engine's call ended, bit for bit (:class:`Agreement`).
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..control import admm as admm_mod
from ..control import certificate as cert_mod
from ..rollout import cpath, kernel
from ..rollout import slots as slots_mod
from ..rollout.kernel import initial_carry
from ..rollout.physics import mjx, step
from ..runtime.compiled import MATMUL_PRECISION

# The C path's calls are sampled in groups of this many periods (the MJX path's block)
SAMPLE_GROUP = 100


# --------------------------------------------------------------------------------------------
# Information: parts of a stage, timed apart


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
    stage's outputs of every period. Where a period's inputs need the period before (the MJX
    path), the replay calls each stage once per period instead (:meth:`__call__`, not timed),
    which keeps the inputs for :meth:`flush` to time with :meth:`scan`."""

    def __init__(self, engine, repeats: int):
        r = engine.runner
        self.mesh, self.repeats = r.mesh, max(1, int(repeats))
        self.split, whole = r._shardings()
        self.stacked = (
            None
            if self.mesh is None
            else jax.sharding.NamedSharding(self.mesh, jax.sharding.PartitionSpec(None, "batch"))
        )
        leaves, self.treedef = jax.tree.flatten((engine.arrays, engine.cert))
        self.leaves = tuple(leaves if whole is None else jax.device_put(leaves, whole))
        self.fns: dict[Any, Any] = {}
        self.overhead: dict[str, float] = {}
        self.seconds: dict[str, float] = {}
        self.kept: dict[str, list] = {}
        self.bodies: dict[str, Any] = {}
        self._stack = jax.jit(
            lambda *trees: jax.tree.map(lambda *v: jnp.stack(v), *trees), out_shardings=self.stacked
        )

    def put(self, tree, stacked: bool = False):
        sharding = self.stacked if stacked else self.split
        return jax.tree.map(
            jnp.asarray if sharding is None else (lambda a: jax.device_put(a, sharding)), tree
        )

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
        return jax.jit(
            jax.shard_map(
                call,
                mesh=self.mesh,
                in_specs=(P(),) + (spec,) * n_args,
                out_specs=spec,
                check_vma=False,
            ),
            keep_unused=True,
            donate_argnums=donate,
        )

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
                noop = self.sharded(
                    lambda leaves, *a: noop_outputs(shapes, stacked=True), len(args), scan=True
                )
                jax.block_until_ready(noop(self.leaves, *args))
                self.overhead[name] = _median_call(noop, self.leaves, args, 5)[0]
            seconds, out = _median_call(fn, self.leaves, args, self.repeats)
        self.seconds[name] = self.seconds.get(name, 0.0) + (seconds - self.overhead[name]) * weight
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
        return {
            "per_busy_slot": round(per_lane, 2),
            "per_block": round(per_block, 2),
            "block_over_slot": round(per_block / per_lane, 2) if per_lane else math.nan,
            "cap": self.cap,
            "busy_slots_at_cap": round(self.lanes_capped / max(1, self.lanes), 4),
            "blocks_at_cap": round(self.blocks_capped / max(1, self.blocks), 4),
        }


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
        return {
            "checked": checked,
            "values": self.values,
            "differ": self.differ,
            "max_rel_diff": self.max_rel,
            "identical": self.differ == 0 if checked else None,
        }


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
    head = (engine._leaves,) if c_path else (engine.arrays, engine.cert)
    shapes = (
        jax.eval_shape(fn, *head, *stages.put(tail))
        if c_path  # (jit's own trace)
        else fn.out_info
    )

    def run(*args):
        return noop_outputs(shapes)

    if r.mesh is not None:
        P = jax.sharding.PartitionSpec
        run = jax.shard_map(
            run,
            mesh=r.mesh,
            out_specs=P("batch"),
            check_vma=False,
            in_specs=(P(),) * len(head) + (P("batch"),) * len(tail),
        )
    noop: jax.stages.Wrapped | jax.stages.Compiled  # (compiled ahead of time on the MJX path)
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
    return {
        "seconds": float(np.median(times[1:])),
        "arrays_in": len(jax.tree.leaves((head, tail))),
        "arrays_out": len(jax.tree.leaves(shapes)),
    }


# --------------------------------------------------------------------------------------------
# The MJX path: each block replayed stage by stage from the state it started with


def mjx_bodies(engine) -> dict[str, Any]:
    """The stage bodies of one MJX control period (``slots.block``'s step, in its order)."""
    r = engine.runner
    sensors, static, packing, S = r.sensors, engine.static, engine.packing, engine.slots
    early = engine.cert is not None

    def rest(arrays):
        return initial_carry(arrays, sensors, static)

    def unpack(arrays, cert, slots, inits):
        slots, _, starts = slots_mod.opened(arrays, sensors, static, slots, inits, packing)
        return slots, starts

    def refill(arrays, cert, slots, taken, s, offer):
        slots, taken = slots_mod.take(
            slots, slots_mod.broadcast(rest(arrays), S), taken[0], s[0], *offer, gated=early
        )
        return slots, taken[None]

    def certify(arrays, cert, carry, due):
        return slots_mod.decide(
            slots_mod.checker(cert if early else None),
            static,
            arrays.n_control,
            carry,
            due.k + 1,
            (due.n_push, due.force),
            due.cell >= 0,
            due.due[0],
        )

    def harvest(arrays, cert, buffer, decided, slots, acc, certified, carry):
        done, n_done, slots = slots_mod.retire(
            buffer[0],
            buffer[1][0],
            decided,
            slots,
            acc,
            slots.k + 1,
            certified,
            carry=carry,
            rest=slots_mod.broadcast(rest(arrays), S),
        )
        return done, n_done[None], slots

    return {
        "unpack": unpack,
        "refill": refill,
        "certify": certify,
        "harvest": harvest,
        "pack": lambda arrays, cert, slots: slots._replace(carry=packing.pack(slots.carry)),
        "prepare": lambda arrays, cert, carry: kernel.prepare_batch(
            arrays, static, carry, rest(arrays)
        ),
        "solve": lambda arrays, cert, pre: kernel.solve_batch(arrays, static, pre, engine.tile),
        "conclude": lambda arrays, cert, pre, res, k: kernel.conclude_batch(
            arrays, static, pre, res, k, rest(arrays)
        ),
        "physics": lambda arrays, cert, carry, slots, torques, u: kernel.physics_batch(
            arrays, sensors, static, carry, slots.k, slots.force, slots.n_push, torques=torques, u=u
        )[0],
        "bare_physics": lambda arrays, cert, d, slots, torques: jax.vmap(
            lambda d, k, f, n, t: bare_physics(arrays, sensors, static, d, k, f, n, t)
        )(d, slots.k, slots.force, slots.n_push, torques),
        "qp_vectors": lambda arrays, cert, pre: jax.vmap(
            lambda p: qp_vectors(arrays.qp, p.x0, p.carry.warm)
        )(pre),
    }


class CertifyInputs(NamedTuple):
    """The per-period numbers a certify body needs besides the slots."""

    k: jax.Array
    n_push: jax.Array
    force: jax.Array
    cell: jax.Array
    due: jax.Array  # [devices] bool: this period checks the certificate


def mjx_period(stages: Stages, bodies: dict, held: dict, s: int, iters: Iterations) -> dict:
    """One control period of the replay (``slots.block``'s step): ``held`` is what one period
    hands the next (slots, taken, done, n_done and the block's refill arrays); returns it
    updated."""
    D = iters.devices
    every = cert_mod.CHECK_EVERY
    s_arr = stages.put(np.full(D, s, np.int32))
    slots, taken = stages(
        "refill",
        bodies["refill"],
        held["slots"],
        held["taken"],
        s_arr,
        (*held["offer"], held["starts"]),
    )
    pre = stages("prepare", bodies["prepare"], slots.carry)
    stages("qp_vectors", bodies["qp_vectors"], pre, run=False)
    res = stages("solve", bodies["solve"], pre)
    iters.add(res.iters, np.asarray(slots.cell) >= 0)
    carry, u, torques = stages("conclude", bodies["conclude"], pre, res, slots.k)
    stages("bare_physics", bodies["bare_physics"], carry.d, slots, torques, run=False)
    carry = stages("physics", bodies["physics"], carry, slots, torques, u)
    due = CertifyInputs(
        slots.k,
        slots.n_push,
        slots.force,
        slots.cell,
        stages.put(np.full(D, s % every == every - 1)),
    )
    acc, certified, decided = stages("certify", bodies["certify"], carry, due)
    done, n_done, slots = stages(
        "harvest",
        bodies["harvest"],
        (held["done"], held["n_done"]),
        decided,
        slots,
        acc,
        certified,
        carry,
    )
    return dict(held, slots=slots, taken=taken, done=done, n_done=n_done)


def replay_mjx(engine, records: list, stages: Stages, sampled: int) -> dict[str, Any]:
    """Every recorded block's first ``sampled`` periods, stage by stage. Returns the stage
    seconds scaled to whole blocks, the ADMM iterations and, where whole blocks were replayed,
    whether the replay ended in the engine's own state (bit for bit)."""
    if engine.lanes:
        raise ValueError(
            "the replay times an engine with one shared body (BatchRunner's); "
            "an engine with per-lane bodies is timed end to end"
        )
    bodies = mjx_bodies(engine)
    r = engine.runner
    D = engine.n_devices
    periods = min(int(sampled), engine.block)
    iters = Iterations(
        D, r.static.settings.iteration_cap, loops=D * engine.slots // (engine.tile or engine.slots)
    )
    checked, agreement = 0, Agreement()
    for b, (packed, offer) in enumerate(records[:-1]):
        packed, offer = stages.put(packed), stages.put(offer)
        slots, starts = stages("unpack", bodies["unpack"], packed, offer[3], keep=False)
        empty = slots_mod.empty_finished(engine.slots + engine.refill, r.dtype)
        held = dict(
            slots=slots,
            taken=stages.put(np.zeros(D, np.int32)),
            offer=offer[:3],
            starts=starts,
            n_done=stages.put(np.zeros(D, np.int32)),
            done=stages.put(jax.tree.map(lambda v: np.concatenate([v] * D), jax.device_get(empty))),
        )
        for s in range(periods):
            held = mjx_period(stages, bodies, held, s, iters)
        stages.flush(engine.block / periods)
        if periods == engine.block:
            packed = stages("pack", bodies["pack"], held["slots"], keep=False)
            agreement.add(jax.device_get(packed), records[b + 1][0])
            checked += 1
    cost = call_cost(engine, stages, (records[0][0], *records[0][1]))
    seconds = dict(stages.seconds, call=cost["seconds"] * (len(records) - 1))
    return dict(
        seconds=seconds,
        call=cost,
        iterations=iters.figures(),
        agreement=agreement.figures(checked),
        sampled_periods=periods * (len(records) - 1),
    )


# --------------------------------------------------------------------------------------------
# The C path: each sampled call replayed stage by stage from its recorded inputs


def c_bodies(engine) -> dict[str, Any]:
    """The stage bodies of one call of the C path (``cpath.call``, in its order)."""
    r = engine.runner
    sensors, static, S = r.sensors, engine.static, r.static.substeps
    early = engine.cert is not None

    def fold(arrays, cert, cs, floats, ints):
        rows, last_qpos, cell, force, push, p = cpath.unpack(floats, ints, S)
        carry, k = cpath.folded(arrays, sensors, static, cs, rows, last_qpos)
        return carry, k, (cell, force, push), p[None]

    def certify(arrays, cert, cs, carry, k, p):
        return cpath.judged(
            arrays, static, slots_mod.checker(cert if early else None), cs, carry, k, p[0]
        )

    def refill(arrays, cert, cs, carry, k, verdict, offer, p):
        slots, fresh, taken, done = cpath.turnover(
            arrays, sensors, static, early, cs, carry, k, p[0], verdict=verdict, offer=offer
        )
        return slots, fresh, taken[None], done

    def finish(arrays, cert, slots, u, torques, fresh, taken, done):
        return cpath.outputs(static, slots, u, torques, fresh, taken, done)[1:]

    return {
        "fold": fold,
        "certify": certify,
        "refill": refill,
        "finish": finish,
        "prepare": lambda arrays, cert, carry: kernel.prepare_batch(arrays, static, carry),
        "solve": lambda arrays, cert, pre: kernel.solve_lanes(arrays, static, pre),
        "conclude": lambda arrays, cert, pre, res, k: kernel.conclude_batch(
            arrays, static, pre, res, k
        ),
        "qp_vectors": lambda arrays, cert, pre: jax.vmap(
            lambda p: qp_vectors(arrays.qp, p.x0, p.carry.warm)
        )(pre),
    }


def c_group(
    stages: Stages,
    bodies: dict,
    records: list,
    weight: float,
    iters: Iterations,
    agreement: Agreement,
) -> None:
    """The recorded calls of one group, stage after stage, each stage over all of them in one
    scan (every call starts from its own recorded inputs); the outputs compared with the
    calls' own (``agreement``)."""
    cs, floats, ints, out_f, out_i = _stack([r[1:] for r in records])
    cs, floats, ints = stages.put((cs, floats, ints), stacked=True)

    def scan(name, *args, timed=True):
        return stages.scan(name, bodies[name], *args, weight=weight, timed=timed)

    carry, k, offer, p = scan("fold", cs, floats, ints)
    verdict = scan("certify", cs, carry, k, p)
    slots, fresh, taken, done = scan("refill", cs, carry, k, verdict, offer, p)
    pre = scan("prepare", slots.carry)
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
    return dict(
        seconds=seconds,
        call=cost,
        iterations=iters.figures(),
        agreement=agreement.figures(len(records)),
        sampled_periods=len(records),
    )
