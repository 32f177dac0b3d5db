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
from typing import Any, Iterator, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..control import certificate as cert_mod
from ..runtime import signals
from ..runtime.xla import deterministic_flags
from ..runtime.compiled import get_or_compile
from .queue import Queue
from .kernel import (Accumulators, Arrays, Carry, initial_carry, lane_arrays, period_batch,
                     rest_of, select, start)
from .sensing import whole_body_com

# Slots per body tile of an engine with per-lane bodies (``refill_tiles``): each tile solves
# one body's QP with shared matrix products; a tile's slots switch body only when all are vacant
# (docs/engine.md, "Per-lane bodies").
LANE_TILE = 8



def default_slots(platform: str) -> int:
    """Slots per device: 32 on a CPU (the fastest per scenario measured on 2 cores, batch 16-64:
    BENCHMARKS.md), 4096 on an accelerator."""
    return 32 if platform == "cpu" else 4096


class Slots(NamedTuple):
    """The scenarios in flight, one per slot (leading axis: slots of every device)."""

    carry: Any  # a Carry; between calls packed (Packing.pack: a tuple of its leaves)
    cell: jax.Array  # int32 cell index, -1: vacant
    force: jax.Array
    n_push: jax.Array  # int32
    k: jax.Array  # int32 control periods done
    body: jax.Array  # int32 the scenario's body (lanes; 0 when the engine has one shared body)


class Finished(NamedTuple):
    """Scenarios decided during one call (leading axis: buffer entries of every device)."""

    cell: jax.Array  # int32, -1: unused entry
    acc: Accumulators
    periods: jax.Array  # int32 control periods simulated
    certified: jax.Array  # bool: stopped by the certificate


class Packing:
    """Stores a batched carry without its zero-size leaves (MJX keeps a few empty arrays, which
    JAX places replicated whatever sharding is asked for, so a sharded state would not match
    its own compiled call); :meth:`unpack` puts them back inside the call."""

    def __init__(self, template: Carry):
        leaves, self.treedef = jax.tree.flatten(template)
        self.layout = tuple((tuple(v.shape), jnp.dtype(v.dtype), v.size == 0) for v in leaves)

    def pack(self, carry: Carry) -> tuple:
        return tuple(v for v, (_, _, empty) in zip(jax.tree.leaves(carry), self.layout)
                     if not empty)

    def unpack(self, packed: tuple, batch: int) -> Carry:
        it = iter(packed)
        leaves = [jnp.zeros((batch,) + shape, dtype) if empty else next(it)
                  for shape, dtype, empty in self.layout]
        return jax.tree.unflatten(self.treedef, leaves)


def broadcast(tree, n):
    return jax.tree.map(lambda v: jnp.broadcast_to(v, (n,) + jnp.shape(v)), tree)


def refill(slots: Slots, rest: Carry, taken, vacant, refill_cell, refill_force, refill_push, *,
           starts: Carry | None = None, refill_body=None) -> tuple[Slots, jax.Array]:
    """Vacant slots take the next refill cells, in slot order (``taken`` already used).
    ``starts`` [R]: each refill cell's first carry (:func:`kernel.start`, a per-scenario
    initial state); None: upright rest (``rest``). ``refill_body`` [R]: each cell's body
    (lanes; None: 0)."""
    R = refill_cell.shape[0]
    if refill_body is None:
        refill_body = jnp.zeros(R, jnp.int32)
    rank = taken + jnp.cumsum(vacant) - 1
    source = jnp.clip(rank, 0, R - 1)
    take = vacant & (rank < R) & (refill_cell[source] >= 0)
    first = rest if starts is None else jax.tree.map(lambda v: v[source], starts)
    slots = Slots(
        carry=select(take, first, slots.carry),
        cell=jnp.where(take, refill_cell[source], slots.cell),
        force=jnp.where(take, refill_force[source], slots.force),
        n_push=jnp.where(take, refill_push[source], slots.n_push),
        k=jnp.where(take, 0, slots.k),
        body=jnp.where(take, refill_body[source], slots.body),
    )
    return slots, taken + take.sum(dtype=jnp.int32)


def _ranks(key, mask):
    """Each masked entry's rank among the masked entries of its key, in order, and the stable
    sort by key (masked entries first, by key then position) with its sorted keys."""
    n = key.shape[0]
    keyed = jnp.where(mask, key, jnp.iinfo(jnp.int32).max)
    order = jnp.argsort(keyed, stable=True)
    sorted_key = keyed[order]
    rank = jnp.arange(n, dtype=jnp.int32) - jnp.searchsorted(sorted_key, sorted_key, side="left")
    return jnp.zeros(n, jnp.int32).at[order].set(rank.astype(jnp.int32)), order, sorted_key


def refill_tiles(slots: Slots, rests: Carry, used, vacant, refill_cell, refill_force,
                 refill_push, *, starts: Carry, refill_body, tile: int) -> tuple[Slots, jax.Array]:
    """:func:`refill` for per-lane bodies solved by body tiles: every ``tile`` consecutive
    slots hold one body's scenarios (``admm.admm_solve_tiles`` solves one QP per tile).

    First the vacant slots of tiles with a scenario take offered cells not yet ``used`` [R] of
    their tile's body: the j-th such slot of body b (in slot order) the j-th such cell of b.
    Then each tile with no scenario takes the next group of up to ``tile`` cells left of one
    body (a body's cells left, in order, cut into groups of ``tile``; the groups in the order
    of their first cells): it switches to that body, and its slots that find no cell idle at
    the body's rest (``rests`` [n_bodies]). Sorts and searches, no loop over tiles, so its
    cost grows as R log R rather than with the tiles. Returns the slots and ``used``."""
    S, R = slots.cell.shape[0], refill_cell.shape[0]
    T = S // tile
    n_bodies = jax.tree.leaves(rests)[0].shape[0]
    avail = (refill_cell >= 0) & ~used
    rank, order, sorted_body = _ranks(refill_body, avail)
    body_first = jnp.searchsorted(sorted_body, jnp.arange(n_bodies, dtype=jnp.int32),
                                  side="left").astype(jnp.int32)

    def cell_of(b, r):  # the offered cell of body b at rank r among those available, if any
        at = body_first[b] + r
        found = (r >= 0) & (at < R) & (sorted_body[jnp.clip(at, 0, R - 1)] == b)
        return found, order[jnp.clip(at, 0, R - 1)]

    empty = jnp.repeat((slots.cell < 0).reshape(T, tile).all(axis=1), tile)
    joining = vacant & ~empty  # vacant slots of tiles with a scenario
    found, source_busy = cell_of(slots.body, _ranks(slots.body, joining)[0])
    take_busy = joining & found
    # each body's first cells went to the busy tiles: the rest are ranked from there
    gone = jnp.zeros(n_bodies, jnp.int32).at[slots.body].add(take_busy.astype(jnp.int32))
    left = rank - gone[refill_body]
    leads = avail & (left >= 0) & (left % tile == 0)  # each group's first cell
    n_groups = leads.sum(dtype=jnp.int32)
    tile_free = (empty & vacant).reshape(T, tile).any(axis=1)
    nth = jnp.cumsum(tile_free.astype(jnp.int32)) - 1  # the empty tile's turn
    served = tile_free & (nth < n_groups)
    lead = jnp.clip(jnp.searchsorted(jnp.cumsum(leads.astype(jnp.int32)), nth + 1,
                                     side="left"), 0, R - 1)
    new_body = jnp.where(served, refill_body[lead], slots.body.reshape(T, tile)[:, 0])
    body = jnp.repeat(new_body.astype(slots.body.dtype), tile)
    seat = jnp.cumsum(vacant.reshape(T, tile), axis=1).reshape(S) - 1  # j-th vacant of a tile
    found, source_new = cell_of(body, jnp.repeat(rank[lead], tile) + seat)
    take_new = jnp.repeat(served, tile) & vacant & found
    take = take_busy | take_new
    source = jnp.where(take_busy, source_busy, source_new)
    idle = (slots.cell < 0) & ~take  # vacant slots, at their (maybe new) body's rest
    first = jax.tree.map(lambda v: v[source], starts)
    carry = select(idle, lane_arrays(rests, body), slots.carry)
    slots = Slots(
        carry=select(take, first, carry),
        cell=jnp.where(take, refill_cell[source], slots.cell),
        force=jnp.where(take, refill_force[source], slots.force),
        n_push=jnp.where(take, refill_push[source], slots.n_push),
        k=jnp.where(take, 0, slots.k), body=body)
    return slots, (refill_cell >= 0) & (used | jnp.zeros(R, bool).at[source].max(take))


def certify(check, static, x, acc: Accumulators, k, n_push, ended, due, *, n_control, force):
    """The certificate's verdict on every slot after its period ``k`` (1-based count; ``due``:
    whether this period is a check, the same for every slot) and the accumulators with a
    certified scenario's predicted rest of the window added. x: [S, 4] latest states;
    ``n_control``: the window's control periods (``Arrays.n_control``); n_push, force: [S]
    each slot's push."""
    S = k.shape[0]
    dtype = acc.max_residual.dtype
    certified = jnp.zeros_like(ended)
    if check is None:
        return acc, certified
    over = cert_mod.push_over(k * static.substeps, n_push, force)

    def checked(_):
        ok, tail = check(x, acc, over, (n_control - k) * static.substeps)
        return ~ended & ok, tail

    def skipped(_):
        return certified, {name: jnp.zeros(S, dtype) for name in cert_mod.TAIL_FIELDS}

    certified, tail = jax.lax.cond(due, checked, skipped, None)
    # a certified scenario's remaining periods are solved and unsaturated, and its energies go
    # on as the linear model predicts (certificate.py)
    acc = acc._replace(
        control_periods=jnp.where(certified, acc.control_periods + (n_control - k),
                                  acc.control_periods),
        **{name: jnp.where(certified, getattr(acc, name) + v.astype(dtype), getattr(acc, name))
           for name, v in tail.items()})
    return acc, certified


def harvest(done: Finished, n_done, decided, cell, acc: Accumulators, k, certified
            ) -> tuple[Finished, jax.Array]:
    """Decided scenarios go to the buffer ``done`` (after its ``n_done`` entries)."""
    capacity = done.cell.shape[0]
    where = jnp.where(decided, n_done + jnp.cumsum(decided) - 1, capacity)
    done = Finished(
        cell=done.cell.at[where].set(cell, mode="drop"),
        acc=jax.tree.map(lambda b, v: b.at[where].set(v, mode="drop"), done.acc, acc),
        periods=done.periods.at[where].set(k, mode="drop"),
        certified=done.certified.at[where].set(certified, mode="drop"),
    )
    return done, n_done + decided.sum(dtype=jnp.int32)


def vacate(decided, rest: Carry, carry: Carry, slots: Slots, k) -> Slots:
    """Slots with ``carry`` after a period; decided ones vacated, reset to rest (a vacated slot
    idles at rest, unpushed, until it is refilled)."""
    return Slots(carry=select(decided, rest, carry), cell=jnp.where(decided, -1, slots.cell),
                 force=jnp.where(decided, 0, slots.force),
                 n_push=jnp.where(decided, 0, slots.n_push), k=k, body=slots.body)


def take(slots: Slots, rest: Carry, taken, s, refill_cell, refill_force, refill_push,
         starts: Carry | None, *, gated: bool, refill_body=None,
         tile: int | None = None) -> tuple[Slots, jax.Array]:
    """Step 1 of a period (``s``: its index in the call): vacant slots take the next refill
    cells, in slot order. ``gated`` (with the certificate): only every ``CHECK_EVERY`` periods,
    so that every scenario's k is a multiple of it when it is checked (a check skipped for the
    whole batch, not masked per slot). ``tile``: per-lane bodies by body tiles
    (:func:`refill_tiles`; ``rest``: each body's, ``taken``: the offered cells used [R])."""
    vacant = slots.cell < 0
    if tile is not None:
        def fill(_):
            return refill_tiles(slots, rest, taken, vacant, refill_cell, refill_force,
                                refill_push, starts=starts, refill_body=refill_body, tile=tile)
        if not gated:
            return fill(None)
        # the tiles' sorts and searches run only in the periods that refill
        return jax.lax.cond(s % cert_mod.CHECK_EVERY == 0, fill, lambda _: (slots, taken), None)
    if gated:
        vacant = vacant & (s % cert_mod.CHECK_EVERY == 0)
    return refill(slots, rest, taken, vacant, refill_cell, refill_force, refill_push,
                  starts=starts, refill_body=refill_body)


def decide(check, static, n_control, carry: Carry, k, push, busy, due
           ) -> tuple[Accumulators, jax.Array, jax.Array]:
    """Step 3 of a period, after the period ran (``carry``; ``k``: periods done; ``push``:
    each slot's (push steps, force)): whether each busy slot's scenario ended (fell, diverged
    or reached t_end) or is certified (``due``: the certificate checks this period). Returns
    the accumulators (a certified scenario's with its predicted rest of the window), the
    certified flags and the decided ones."""
    ended = ~carry.acc.alive | (k >= n_control)
    if not isinstance(push, tuple):  # (an array of two slots would unpack silently)
        raise TypeError(f"push: (push steps, force), got {type(push).__name__}")
    n_push, force = push
    acc, certified = certify(check, static, carry.x_prev, carry.acc, k, n_push, ended, due,
                             n_control=n_control, force=force)
    return acc, certified, busy & (ended | certified)


def retire(done: Finished, n_done, decided, slots: Slots, acc: Accumulators, k, certified, *,
           carry: Carry, rest: Carry) -> tuple[Finished, jax.Array, Slots]:
    """Step 4 of a period: decided scenarios go to the buffer (:func:`harvest`) and their
    slots are vacated (:func:`vacate`)."""
    done, n_done = harvest(done, n_done, decided, slots.cell, acc, k, certified)
    return done, n_done, vacate(decided, rest, carry, slots, k)


def empty_finished(capacity: int, dtype) -> Finished:
    return Finished(
        cell=jnp.full(capacity, -1, jnp.int32),
        acc=broadcast(Accumulators.initial(dtype), capacity),
        periods=jnp.zeros(capacity, jnp.int32), certified=jnp.zeros(capacity, bool))


def checker(cert, periods: int | None = None, axis: int | None = None, body=None):
    """The vmapped certificate test, or None without a certificate (``axis`` 0: ``cert`` has
    one certificate per lane, every leaf [B, ...]; or, with ``body`` [B], one per body
    [n_bodies, ...], gathered at each lane's body when the test runs: it runs every
    ``CHECK_EVERY`` periods only, inside ``certify``'s conditional, and a certificate is large
    (about 190,000 numbers for the study's configuration), so its gather is left to then)."""
    if cert is None:
        return None
    if periods is not None and periods % cert_mod.CHECK_EVERY:
        raise ValueError(f"block of {periods} periods: not a multiple of {cert_mod.CHECK_EVERY}")
    check = jax.vmap(lambda c, x, acc, over, left: cert_mod.check(jnp, c, x, acc, over, left),
                     in_axes=(axis, 0, 0, 0, 0))
    if body is not None:
        return lambda x, acc, over, left: check(lane_arrays(cert, body), x, acc, over, left)
    return lambda x, acc, over, left: check(cert, x, acc, over, left)


def opened(arrays, sensors, static, slots: Slots, refill_init, packing: Packing,
           refill_body=None) -> tuple[Slots, Carry, Carry]:
    """A call's start: the slots with their carry unpacked (:class:`Packing`), upright rest
    (shared arrays: every slot's [S]; lanes, ``refill_body`` given: each body's
    [n_bodies]), and each refill cell's first carry (from its initial joint state)."""
    n = slots.cell.shape[0]
    slots = slots._replace(carry=packing.unpack(slots.carry, n))
    if refill_body is None:
        single = initial_carry(arrays, sensors, static)
        starts = jax.vmap(lambda init: start(arrays, sensors, single, init))(refill_init)
        return slots, broadcast(single, n), starts
    rests = rest_of(arrays, sensors, static, 0)
    starts = jax.vmap(lambda a, r, init: start(a, sensors, r, init))(
        lane_arrays(arrays, refill_body), lane_arrays(rests, refill_body), refill_init)
    return slots, rests, starts


def block(arrays, sensors, static, cert, slots: Slots, *, refill_cell, refill_force, refill_push,
          refill_init, refill_body, periods: int, early_stop: bool, packing: Packing,
          tile: int | None = None, lanes: bool = False):
    """``periods`` control periods of one device's slots with refill and harvest (pure JAX).

    refill_*: [R] the next cells for this device (cell -1: none), refill_init [R, 4] their
    initial joint states (0: upright rest), refill_body [R] their bodies. Returns the slots,
    the number of refill cells taken [1] and the finished buffer [slots + R]. ``slots.carry``
    is packed (:class:`Packing`). ``lanes``: ``arrays`` and ``cert`` hold one body each
    [n_bodies, ...] and every slot runs its scenario's body (``kernel.lane_arrays``), each
    ``tile`` slots one body whose QP they solve together (:func:`refill_tiles`; then the refill
    cells taken are returned as a mask [R]); otherwise they are shared by every slot (``tile``:
    sequential ADMM tiles).
    """
    S = slots.cell.shape[0]
    slots, rest, starts = opened(arrays, sensors, static, slots, refill_init, packing,
                                 refill_body if lanes else None)
    every = cert_mod.CHECK_EVERY
    axis = 0 if lanes else None
    # lanes: the QPs by body tiles of ``tile`` slots (:func:`refill_tiles`)
    qp_tiles = (lambda body: (arrays.qp, body[::tile])) if lanes else (lambda body: None)

    def step(state, s):
        slots, taken, done, n_done = state
        # 1. refill; 2. one control period of every slot; 3. decide; 4. harvest and vacate
        slots, taken = take(slots, rest, taken, s, refill_cell, refill_force, refill_push,
                            starts, gated=early_stop and cert is not None, refill_body=refill_body,
                            tile=tile if lanes else None)
        body, body_rest = ((lane_arrays(arrays, slots.body), lane_arrays(rest, slots.body))
                           if lanes else (arrays, rest))
        check = checker(cert if early_stop else None, periods, axis,
                        slots.body if lanes else None)
        carry = period_batch(body, sensors, static, slots.carry, slots.k, slots.force,
                             slots.n_push, tile=tile, axis=axis, tiles=qp_tiles(slots.body))[0]
        k = slots.k + 1
        acc, certified, decided = decide(check, static, body.n_control, carry, k,
                                         (slots.n_push, slots.force), slots.cell >= 0,
                                         s % every == every - 1)
        done, n_done, slots = retire(done, n_done, decided, slots, acc, k, certified,
                                     carry=carry, rest=body_rest)
        return (slots, taken, done, n_done), None

    done = empty_finished(S + refill_cell.shape[0], arrays.d0.qpos.dtype)
    zero = jnp.zeros((), jnp.int32)
    taken = jnp.zeros(refill_cell.shape, bool) if lanes else zero
    (slots, taken, done, _), _ = jax.lax.scan(step, (slots, taken, done, zero),
                                              jnp.arange(periods, dtype=jnp.int32))
    return slots._replace(carry=packing.pack(slots.carry)), taken if lanes else taken[None], done


def certificate(runner, early_stop: bool):
    """The certificate of ``runner``'s configuration (``certificate.py``) in its dtype, or None
    (``early_stop`` off, or no certificate applies: then its scenarios run to t_end). Built once
    per runner (kept on it): a population asks for each body's twice."""
    config = runner.config
    if not (early_stop and cert_mod.applies(config)):
        return None
    built = runner.__dict__.setdefault("_certificate", [])
    if built:
        return built[0]
    arrays, sensors = runner.arrays, runner.sensors
    com = float(whole_body_com(arrays.mx, arrays.d0, sensors))
    rest = (com, com)  # static equilibrium: the CoP lies under the CoM
    try:
        cert = cert_mod.build(runner.qp, config.controller, config.scenario, rest=rest)
    except ValueError as exc:  # e.g. a bound through rest: run to t_end instead
        warnings.warn(f"no certified early stop for this configuration: {exc}", stacklevel=4)
        cert = None
    built.append(None if cert is None else
                 jax.tree.map(lambda v: jnp.asarray(v, runner.dtype), cert))
    return built[0]


def lane_bodies(runner, bodies: Sequence[Any], early_stop: bool) -> tuple[Arrays, Any]:
    """The arrays and certificates of ``bodies`` (runners whose compiled programs agree with
    ``runner``'s: the same shapes and static settings) stacked along a first axis, padded to a
    power of two (at least 2) with copies of the last (padding is never a cell's body).
    Raises ValueError for bodies of another shape, or some with a certificate and some
    without."""
    if not bodies:
        raise ValueError("bodies: at least one")
    key = runner._shape_key(1, runner.static._replace(n_control=None))
    for other in bodies:
        if other._shape_key(1, other.static._replace(n_control=None)) != key:
            raise ValueError("bodies must share the shapes and static settings of one compiled "
                             "program (horizon, delay, t_end, ADMM settings, thresholds)")
    certs = [certificate(b, early_stop) for b in bodies]
    if len({c is None for c in certs}) > 1:
        raise ValueError("bodies: some have a certificate and some not; run them apart")
    # at least two: with one, XLA would see that every lane gathers the same body and could
    # compute it as a shared body, whose rounding differs
    size = max(2, 1 << (len(bodies) - 1).bit_length())
    padded = list(bodies) + [bodies[-1]] * (size - len(bodies))
    certs += [certs[-1]] * (len(padded) - len(certs))

    def stack(trees):  # on the host: jnp.stack or jnp.asarray would compile a program per leaf
        return jax.tree.map(lambda *v: jax.device_put(np.stack([np.asarray(x) for x in v])),
                            *trees)

    arrays = stack([b.arrays for b in padded])
    _, whole = runner._shardings()
    if whole is not None:
        arrays = jax.device_put(arrays, whole)
    return arrays, None if certs[0] is None else stack(certs)


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
    (:func:`refill_tiles`). None: one body, shared by every slot.
    """

    def __init__(self, runner, *, slots: int | None = None, block: int = 100,
                 early_stop: bool = True, refill: int | None = None, tile: int | None = None,
                 bodies: Sequence[Any] | None = None):
        self.runner = runner
        devices: list[Any] = [None] if runner.mesh is None else list(runner.mesh.devices.flat)
        self.n_devices = len(devices)
        platform = (jax.local_devices()[0] if runner.mesh is None else devices[0]).platform
        if platform == "cpu" and not deterministic_flags():
            warnings.warn("JAX started before mjx_balance could set its XLA options "
                          "(mjx_balance.runtime.xla): results may depend on the slot a "
                          "scenario ran in; import mjx_balance before running anything with "
                          "JAX",
                          stacklevel=3)
        self.slots = int(slots or default_slots(platform))
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
            self.tile: int | None = (int(tile) if tile is not None
                                     else math.gcd(self.slots, LANE_TILE))
        else:
            self.tile = int(tile) if tile is not None and tile < self.slots else None
        self.early_stop = bool(early_stop)
        if self.lanes:
            assert bodies is not None  # (self.lanes says so)
            self.n_bodies = len(bodies)
            self.arrays, self.cert = lane_bodies(runner, bodies, self.early_stop)
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
        return ("engine", self.runner._shape_key(self.slots, self.static), self.refill,
                self.block,
                self.tile, self.cert is not None, None if self.cert is None else
                tuple(np.shape(v) for v in self.cert),
                self.lanes and jax.tree.leaves(self.arrays)[0].shape[0])

    def block_fn(self):
        """The compiled call: (arrays, cert, slots, refill cell/force/push) -> (slots, taken,
        finished), sharded over the runner's devices."""
        if self._fn is not None:
            return self._fn
        t0 = _time.perf_counter()
        r = self.runner
        sensors, static, periods = r.sensors, self.static, self.block
        early_stop = self.cert is not None
        packing, tile, lanes = self.packing, self.tile, self.lanes

        def call(arrays, cert, slots, cell, force, push, init, body):
            return block(arrays, sensors, static, cert, slots, refill_cell=cell,
                         refill_force=force, refill_push=push, refill_init=init,
                         refill_body=body, periods=periods, early_stop=early_stop, packing=packing,
                         tile=tile, lanes=lanes)

        def build():
            run = call
            if r.mesh is not None:
                P = jax.sharding.PartitionSpec
                run = jax.shard_map(call, mesh=r.mesh,
                                    in_specs=(P(), P(), P("batch"), P("batch"), P("batch"),
                                              P("batch"), P("batch"), P("batch")),
                                    out_specs=P("batch"), check_vma=False)
            slots = jax.eval_shape(self._vacant, self.arrays)
            batch_sharding, _ = r._shardings()
            def spec(a):
                return jax.ShapeDtypeStruct(a.shape, a.dtype, sharding=batch_sharding)
            n = self.refill * self.n_devices
            return jax.jit(run, donate_argnums=(2,)).lower(
                self.arrays, self.cert, jax.tree.map(spec, slots),
                jax.ShapeDtypeStruct((n,), jnp.int32, sharding=batch_sharding),
                jax.ShapeDtypeStruct((n,), r.dtype, sharding=batch_sharding),
                jax.ShapeDtypeStruct((n,), jnp.int32, sharding=batch_sharding),
                jax.ShapeDtypeStruct((n, 4), r.dtype, sharding=batch_sharding),
                jax.ShapeDtypeStruct((n,), jnp.int32, sharding=batch_sharding)).compile()

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
        return Slots(carry=self.packing.pack(carry), cell=jnp.full(n, -1, jnp.int32),
                     force=jnp.zeros(n, r.dtype), n_push=jnp.zeros(n, jnp.int32),
                     k=jnp.zeros(n, jnp.int32), body=jnp.zeros(n, jnp.int32))

    def _initial_state(self) -> tuple:  # Slots (cpath.CEngine: its CState)
        batch_sharding, _ = self.runner._shardings()
        return jax.jit(self._vacant, out_shardings=batch_sharding)(self.arrays)

    # -- running --------------------------------------------------------------------------

    def stream(self, forces: np.ndarray, n_push: np.ndarray, inits: np.ndarray | None = None,
               probe: Probe | None = None, bodies: np.ndarray | None = None
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
        queue = Queue(forces, n_push, self.n_devices, self.refill, inits, self.block, bodies,
                      wave=wave)
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
                        (taken, done.cell, tuple(done.acc), done.periods, done.certified,
                         state.cell, state.k))
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
            raise ValueError(f"bodies: one integer per cell ({n}), got {bodies.dtype} "
                             f"{bodies.shape}")
        if n and (bodies.min() < 0 or bodies.max() >= self.n_bodies):
            raise ValueError(f"bodies: indices must lie in [0, {self.n_bodies}), got "
                             f"{bodies.min()}..{bodies.max()}")
        return bodies.astype(np.int32)

    def offer_args(self, cells, f, p, init, body) -> tuple:
        """A refill offer (:meth:`Queue.offer`) as the compiled call's arguments, placed on the
        devices."""
        r = self.runner
        batch_sharding, _ = r._shardings()
        args = (jnp.asarray(cells), jnp.asarray(f.astype(r.dtype)), jnp.asarray(p),
                jnp.asarray(init.astype(r.dtype)), jnp.asarray(body))
        if batch_sharding is None:
            return args
        return tuple(jax.device_put(a, batch_sharding) for a in args)

    def run(self, forces: np.ndarray, n_push: np.ndarray, inits: np.ndarray | None = None,
            bodies: np.ndarray | None = None, *, probe: Probe | None = None,
            update: Callable[[int], None] | None = None) -> dict[str, np.ndarray]:
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
            out = {name: np.zeros(0, np.asarray(v).dtype)
                   for name, v in zip(Accumulators._fields, initial)}
            out.update(periods=np.zeros(0, np.int32), certified=np.zeros(0, bool))
        return out
