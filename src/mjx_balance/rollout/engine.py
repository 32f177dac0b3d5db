"""Continuous batching: a fixed set of slots, each refilled with the next cell when its scenario
is decided.

Every device runs ``slots`` scenarios side by side (:func:`kernel.period_batch`). After each
control period a slot's scenario is *decided* when it fell or diverged (the fall sample), when it
reached t_end, or, with early stopping, when its recovery is certified (``certificate.py``).
A decided slot hands its accumulators to an output buffer, is reset to upright rest with a cold
controller and takes the next cell of a refill buffer: the auto-reset pattern of batched RL
simulators with a work queue behind it. All of that happens on the device inside one compiled
call (:meth:`Engine.block_fn`) that runs ``block`` control periods; between calls the slots stay
on the device and the host only tops up the refill buffers and collects finished cells, so a
sweep's slots are never idle until its queue runs dry.

The device side, the slots and the steps of a period (pure JAX), is ``rollout/slots.py``; this
module is the host side: :class:`Engine` compiles :func:`slots.block` and drives it, with the
bodies and certificates it runs on and the probe a benchmark hooks into its loop.

Schedule independence. A cell's result must not depend on its slot, its neighbours, the number
of cells, the device count or the order of a resumed sweep. Each slot's computation is its own
lane of a vmap (no value crosses lanes: refill and harvest are gathers and scatters), and the
compiled program always has ``slots`` lanes per device whatever the work, so only XLA's code for
one lane position could differ. On the CPU it does unless XLA is told to use the same
instructions everywhere (:data:`DETERMINISTIC_XLA_FLAGS`, set by :func:`deterministic_flags`
before JAX starts; tests/rollout/test_engine.py checks the result bytes). Results do depend on
the slot count, which a sweep therefore records.
"""

from __future__ import annotations

import contextlib
import math
import time as _time
import warnings
from collections.abc import Callable, Sequence
from typing import Any, Iterator

import jax
import jax.numpy as jnp
import numpy as np

from ..control import certificate as cert_mod
from ..runtime import signals
from ..runtime.xla import deterministic_flags
from ..runtime.compiled import get_or_compile
from .queue import Queue
from .kernel import Accumulators, Arrays, initial_carry
from .sensing import whole_body_com
from .slots import Packing, Slots, block, broadcast

# Slots per body tile of an engine with per-lane bodies (``slots.refill_tiles``): each tile
# solves one body's QP with shared matrix products; a tile's slots switch body only when all
# are vacant (docs/engine.md, "Per-lane bodies").
LANE_TILE = 8


def default_slots(platform: str) -> int:
    """Slots per device: 32 on a CPU (the fastest per scenario measured on 2 cores, batch 16-64:
    BENCHMARKS.md), 4096 on an accelerator."""
    return 32 if platform == "cpu" else 4096


def slot_layout(runner, slots: int | None) -> tuple[str, int, int]:
    """The platform, the device count and the slots per device an engine of ``runner`` with
    ``slots`` (None: :func:`default_slots`) runs."""
    devices: list[Any] = [None] if runner.mesh is None else list(runner.mesh.devices.flat)
    platform = (jax.local_devices()[0] if runner.mesh is None else devices[0]).platform
    return platform, len(devices), int(slots or default_slots(platform))


def certificate(runner, early_stop: bool):
    """The certificate of ``runner``'s configuration (``certificate.py``) in its dtype, or None
    (no certificate applies: then its scenarios run to t_end). Without ``early_stop``
    (``--full-length``) it is the same certificate with ``stops`` 0, whose check never stops a
    scenario: both modes run one compiled program (the mode is data, not a compile key). Built
    once per runner (kept on it): a population asks for each body's twice."""
    config = runner.config
    if not cert_mod.applies(config):
        return None
    built = runner.__dict__.setdefault("_certificate", [])
    if not built:
        arrays, sensors = runner.arrays, runner.sensors
        com = float(whole_body_com(arrays.mx, arrays.d0, sensors))
        rest = (com, com)  # static equilibrium: the CoP lies under the CoM
        try:
            cert = cert_mod.build(runner.qp, config.controller, config.scenario, rest=rest)
        except ValueError as exc:  # e.g. a bound through rest: run to t_end instead
            if early_stop:
                warnings.warn(
                    f"no certified early stop for this configuration: {exc}", stacklevel=4
                )
            cert = None
        built.append(
            None if cert is None else jax.tree.map(lambda v: jnp.asarray(v, runner.dtype), cert)
        )
    if built[0] is None or early_stop:
        return built[0]
    return built[0]._replace(stops=jnp.zeros((), runner.dtype))


def lane_bodies(
    runner, bodies: Sequence[Any], early_stop: bool, size: int | None = None
) -> tuple[Arrays, Any]:
    """The arrays and certificates of ``bodies`` (runners whose compiled programs agree with
    ``runner``'s: the same shapes and static settings) stacked along a first axis, padded with
    copies of the last (padding is never a cell's body) to ``size`` bodies, by default the
    next power of two (at least 2): the stacked length is a compile key, so queues padded to
    one size share one program. Raises ValueError for bodies of another shape, or some with a
    certificate and some without, or more bodies than ``size``."""
    if not bodies:
        raise ValueError("bodies: at least one")
    key = runner._shape_key(1, runner.static._replace(n_control=None))
    for other in bodies:
        if other._shape_key(1, other.static._replace(n_control=None)) != key:
            raise ValueError(
                "bodies must share the shapes and static settings of one compiled "
                "program (horizon, delay, t_end, ADMM settings, thresholds)"
            )
    certs = [certificate(b, early_stop) for b in bodies]
    if len({c is None for c in certs}) > 1:
        raise ValueError("bodies: some have a certificate and some not; run them apart")
    # at least two: with one, XLA would see that every lane gathers the same body and could
    # compute it as a shared body, whose rounding differs
    size = padded_size(len(bodies)) if size is None else int(size)
    if not max(2, len(bodies)) <= size:
        raise ValueError(f"bodies: {len(bodies)} do not fit a stack of {size} (at least 2)")

    def stack(trees):  # on the host: jnp.stack or jnp.asarray would compile a program per leaf
        def leaf(*values):
            rows = np.stack([np.asarray(v) for v in values])
            pad = np.broadcast_to(rows[-1:], (size - len(values), *rows.shape[1:]))
            return jax.device_put(np.concatenate([rows, pad]))

        return jax.tree.map(leaf, *trees)

    arrays = stack([b.arrays for b in bodies])
    _, whole = runner._shardings()
    if whole is not None:
        arrays = jax.device_put(arrays, whole)
    return arrays, None if certs[0] is None else stack(certs)


def padded_size(count: int) -> int:
    """The stacked length of ``count`` bodies: the next power of two, at least 2."""
    return max(2, 1 << (max(1, count) - 1).bit_length())


def cells_of(forces, n_push) -> tuple[np.ndarray, np.ndarray, int]:
    """A run's cells as the engines take them: forces float64 [n], push steps int32 [n]."""
    forces = np.asarray(forces, np.float64)
    return forces, np.asarray(n_push, np.int32), forces.shape[0]


class Probe:
    """What a benchmark hooks into an engine's loop (``stream(..., probe=)``); this one does
    nothing, so a run without a probe is the plain loop.

    ``probe(name)`` is a context around each part of the host's loop: ``python`` (the queue
    and the results), ``transfers`` (host <-> device), ``device_call`` (one compiled call), and
    on the C path ``physics`` (MuJoCo's rollout) and ``samples_host`` (decoding its samples).
    :meth:`before` sees each call's inputs (call ``p``, the slots' state, the arguments) before
    the call takes them (the state is donated), :meth:`after` its outputs (C path), and
    :meth:`call` runs it.
    """

    def __call__(self, name: str):
        return contextlib.nullcontext()

    def before(self, p: int, state, args) -> None:
        pass

    def after(self, p: int, outputs) -> None:
        pass

    def call(self, fn, *args):
        return fn(*args)


NO_PROBE = Probe()


class Engine:
    """Continuous batching for one :class:`runner.BatchRunner` (its model, QP and devices).

    slots: per device (default :func:`default_slots`); block: control periods per call;
    early_stop: stop certified recoveries (``--full-length`` turns it off). Falls and t_end
    stop a scenario either way. tile: slots per ADMM loop, solved one tile after the other (default:
    one loop over the device's slots; docs/engine.md, "ADMM tiles").

    bodies: runners of one shape (:func:`lane_bodies`; the first is ``runner``) whose
    scenarios share the queue, each slot running its scenario's body, QP and certificate
    (:meth:`stream`'s ``bodies``); their arrays are stacked, padded to a power of two so that
    populations of similar size share one compiled program. Each ``tile`` slots (default
    :data:`LANE_TILE`) then hold one body at a time and solve its QP together
    (:func:`slots.refill_tiles`). None: one body, shared by every slot. stack: the bodies'
    stacked length (:func:`lane_bodies`' ``size``; default the next power of two).
    """

    def __init__(
        self,
        runner,
        *,
        slots: int | None = None,
        block: int = 100,
        early_stop: bool = True,
        refill: int | None = None,
        tile: int | None = None,
        bodies: Sequence[Any] | None = None,
        stack: int | None = None,
    ):
        self.runner = runner
        platform, self.n_devices, self.slots = slot_layout(runner, slots)
        if platform == "cpu" and not deterministic_flags():
            warnings.warn(
                "JAX started before mjx_balance could set its XLA options "
                "(mjx_balance.runtime.xla): results may depend on the slot a "
                "scenario ran in; import mjx_balance before running anything with "
                "JAX",
                stacklevel=3,
            )
        if self.slots < 1:
            raise ValueError(f"slots must be >= 1, got {slots}")
        # a call runs at most a scenario's length (short scenarios refill sooner), in whole
        # certificate intervals
        every = cert_mod.CHECK_EVERY
        self.block = int(min(block, -(-runner.config.scenario.n_control // every) * every))
        self.refill = int(refill or 4 * self.slots)
        if tile is not None and (tile < 1 or self.slots % tile):
            raise ValueError(f"ADMM tile {tile} must divide the slots per device, {self.slots}")
        self.lanes = bodies is not None
        if self.lanes:  # body tiles (default: LANE_TILE slots, or fewer dividing the slots)
            self.tile: int | None = (
                int(tile) if tile is not None else math.gcd(self.slots, LANE_TILE)
            )
        else:
            self.tile = int(tile) if tile is not None and tile < self.slots else None
        self.early_stop = bool(early_stop)
        if self.lanes:
            assert bodies is not None  # (self.lanes says so)
            self.n_bodies = len(bodies)
            self.arrays, self.cert = lane_bodies(runner, bodies, self.early_stop, stack)
        else:
            self.n_bodies = 1
            self.arrays, self.cert = runner.arrays, certificate(runner, self.early_stop)
        # what the compiled call bakes in: the runner's static settings without the window's
        # length, which the call reads from the traced Arrays.n_control
        self.static = runner.static._replace(n_control=None)
        self.packing = Packing(initial_carry(runner.arrays, runner.sensors, runner.static))
        self.compile_seconds: float | None = None
        self._fn = None
        self._state: Slots | None = None

    # -- compilation ----------------------------------------------------------------------

    def _key(self) -> tuple:
        return (
            "engine",
            self.runner._shape_key(self.slots, self.static),
            self.refill,
            self.block,
            self.tile,
            self.cert is not None,
            None if self.cert is None else tuple(np.shape(v) for v in self.cert),
            self.lanes and jax.tree.leaves(self.arrays)[0].shape[0],
        )

    def block_fn(self):
        """The compiled call: (arrays, cert, slots, refill cell/force/push) -> (slots, taken,
        finished), sharded over the runner's devices."""
        if self._fn is not None:
            return self._fn
        t0 = _time.perf_counter()
        r = self.runner
        sensors, static, periods = r.sensors, self.static, self.block
        packing, tile, lanes = self.packing, self.tile, self.lanes

        def call(arrays, cert, slots, cell, force, push, init, body):
            return block(
                arrays,
                sensors,
                static,
                cert,
                slots,
                refill_cell=cell,
                refill_force=force,
                refill_push=push,
                refill_init=init,
                refill_body=body,
                periods=periods,
                packing=packing,
                tile=tile,
                lanes=lanes,
            )

        def build():
            run = call
            if r.mesh is not None:
                P = jax.sharding.PartitionSpec
                run = jax.shard_map(
                    call,
                    mesh=r.mesh,
                    in_specs=(
                        P(),
                        P(),
                        P("batch"),
                        P("batch"),
                        P("batch"),
                        P("batch"),
                        P("batch"),
                        P("batch"),
                    ),
                    out_specs=P("batch"),
                    check_vma=False,
                )
            slots = jax.eval_shape(self._vacant, self.arrays)
            batch_sharding, _ = r._shardings()

            def spec(a):
                return jax.ShapeDtypeStruct(a.shape, a.dtype, sharding=batch_sharding)

            n = self.refill * self.n_devices
            return (
                jax.jit(run, donate_argnums=(2,))
                .lower(
                    self.arrays,
                    self.cert,
                    jax.tree.map(spec, slots),
                    jax.ShapeDtypeStruct((n,), jnp.int32, sharding=batch_sharding),
                    jax.ShapeDtypeStruct((n,), r.dtype, sharding=batch_sharding),
                    jax.ShapeDtypeStruct((n,), jnp.int32, sharding=batch_sharding),
                    jax.ShapeDtypeStruct((n, 4), r.dtype, sharding=batch_sharding),
                    jax.ShapeDtypeStruct((n,), jnp.int32, sharding=batch_sharding),
                )
                .compile()
            )

        fn = get_or_compile(self._key(), build)
        self.compile_seconds = _time.perf_counter() - t0
        self._fn = fn
        return fn

    def _vacant(self, arrays: Arrays) -> Slots:
        """Every slot vacant at upright rest (``arrays`` traced: configurations of equal
        shapes share the compiled function, in the process and in the persistent cache)."""
        r = self.runner
        n = self.slots * self.n_devices
        if self.lanes:  # vacant slots idle at the first body's rest
            arrays = jax.tree.map(lambda v: v[0], arrays)
        carry = broadcast(initial_carry(arrays, r.sensors, r.static), n)
        return Slots(
            carry=self.packing.pack(carry),
            cell=jnp.full(n, -1, jnp.int32),
            force=jnp.zeros(n, r.dtype),
            n_push=jnp.zeros(n, jnp.int32),
            k=jnp.zeros(n, jnp.int32),
            body=jnp.zeros(n, jnp.int32),
        )

    def _initial_state(self) -> tuple:  # Slots (cpath.CEngine: its CState)
        batch_sharding, _ = self.runner._shardings()
        return jax.jit(self._vacant, out_shardings=batch_sharding)(self.arrays)

    # -- running --------------------------------------------------------------------------

    def stream(
        self,
        forces: np.ndarray,
        n_push: np.ndarray,
        inits: np.ndarray | None = None,
        probe: Probe | None = None,
        bodies: np.ndarray | None = None,
    ) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray]]]:
        """Run every cell (forces [n], push steps [n], initial joint states [n, 4] or None:
        upright rest); yield (cell indices, finished raw results) after each call, as cells
        complete. Raw results: the accumulators' fields, ``periods`` and ``certified``, numpy,
        one entry per index. ``probe``: what a benchmark hooks into the loop (:class:`Probe`).
        ``bodies`` [n]: each cell's body, an index into the engine's ``bodies`` (None: 0)."""
        probe = probe or NO_PROBE
        forces, n_push, n = cells_of(forces, n_push)
        if n == 0:
            return
        bodies = self._bodies_of(bodies, n)
        fn = self.block_fn()
        state = self._take_state()
        wave = 1
        if self.lanes:
            assert self.tile is not None  # (set with self.lanes: __init__)
            wave = self.slots * self.n_devices // self.tile
        queue = Queue(
            forces, n_push, self.n_devices, self.refill, inits, self.block, bodies, wave=wave
        )
        remaining, finished, p = n, False, 0
        try:
            while remaining:
                signals.check()  # a checkpoint: a signal dropped where it landed ends the run
                with probe("python"):
                    offer = queue.offer()
                with probe("transfers"):
                    args = self.offer_args(*offer)
                probe.before(p, state, args)
                with probe("device_call"):
                    state, taken, done = probe.call(fn, self.arrays, self.cert, state, *args)
                with probe("transfers"):
                    taken, index, acc, periods, certified, in_slot, ran = jax.device_get(
                        (
                            taken,
                            done.cell,
                            tuple(done.acc),
                            done.periods,
                            done.certified,
                            state.cell,
                            state.k,
                        )
                    )
                p += 1
                with probe("python"):
                    queue.took(taken)
                    queue.running(in_slot, ran)
                    keep = index >= 0
                    if keep.any():
                        raw = {name: v[keep] for name, v in zip(Accumulators._fields, acc)}
                        raw["periods"], raw["certified"] = periods[keep], certified[keep]
                        queue.finished(index[keep], raw["periods"])
                        remaining -= int(keep.sum())
                if keep.any():
                    yield index[keep].astype(np.int64), raw
            finished = True
        finally:
            if finished:
                self._state = state  # every slot vacant: reusable by the next run

    def _take_state(self):
        """The slots' state to run from: the last run's (every slot vacant) or a new one; the
        engine holds none while a run has it (the call donates it)."""
        state = self._state if self._state is not None else self._initial_state()
        self._state = None
        return state

    def _bodies_of(self, bodies, n: int) -> np.ndarray | None:
        if bodies is None:
            return None
        bodies = np.asarray(bodies)
        if bodies.shape != (n,) or not np.issubdtype(bodies.dtype, np.integer):
            raise ValueError(
                f"bodies: one integer per cell ({n}), got {bodies.dtype} {bodies.shape}"
            )
        if n and (bodies.min() < 0 or bodies.max() >= self.n_bodies):
            raise ValueError(
                f"bodies: indices must lie in [0, {self.n_bodies}), got "
                f"{bodies.min()}..{bodies.max()}"
            )
        return bodies.astype(np.int32)

    def offer_args(self, cells, f, p, init, body) -> tuple:
        """A refill offer (:meth:`Queue.offer`) as the compiled call's arguments, placed on the
        devices."""
        r = self.runner
        batch_sharding, _ = r._shardings()
        args = (
            jnp.asarray(cells),
            jnp.asarray(f.astype(r.dtype)),
            jnp.asarray(p),
            jnp.asarray(init.astype(r.dtype)),
            jnp.asarray(body),
        )
        if batch_sharding is None:
            return args
        return tuple(jax.device_put(a, batch_sharding) for a in args)

    def run(
        self,
        forces: np.ndarray,
        n_push: np.ndarray,
        inits: np.ndarray | None = None,
        bodies: np.ndarray | None = None,
        *,
        probe: Probe | None = None,
        update: Callable[[int], None] | None = None,
    ) -> dict[str, np.ndarray]:
        """Every cell's raw results (see :meth:`stream`; ``probe`` clocks their collection as
        ``python`` too), in the order of the cells. ``update(n)``: n more cells decided."""
        probe = probe or NO_PROBE
        n = np.asarray(forces).shape[0]
        out: dict[str, Any] = {}
        seen = np.zeros(n, bool)
        for index, raw in self.stream(forces, n_push, inits, probe=probe, bodies=bodies):
            with probe("python"):
                for name, v in raw.items():
                    if name not in out:
                        out[name] = np.zeros((n,) + v.shape[1:], v.dtype)
                    out[name][index] = v
                seen[index] = True
            if update is not None:
                update(len(index))
        if not seen.all():
            raise RuntimeError(f"the engine returned {int(seen.sum())} of {n} scenarios")
        if not out:  # no cells: empty columns of the accumulators' types
            initial = Accumulators.initial(self.runner.dtype)
            out = {
                name: np.zeros(0, np.asarray(v).dtype)
                for name, v in zip(Accumulators._fields, initial)
            }
            out.update(periods=np.zeros(0, np.int32), certified=np.zeros(0, bool))
        return out
