"""The slots of continuous batching on the device: pure JAX, one compiled call's body.

A device runs a fixed number of *slots* side by side, each holding one scenario (a cell of the
work) or vacant (cell -1); :class:`Slots` is their state and :class:`Finished` the buffer the
decided scenarios go to. :func:`block` runs ``periods`` control periods of one device's slots
(a ``lax.scan``); each period takes four steps:

1. :func:`take`: vacant slots take the next refill cells, in slot order (:func:`refill`, or
   :func:`refill_tiles` for per-lane bodies solved by body tiles);
2. one control period of every slot (:func:`kernel.period_batch`);
3. :func:`decide`: a busy slot's scenario is decided when it fell or diverged, reached t_end,
   or, with early stopping, its recovery is certified (:func:`certify`, ``certificate.py``);
4. :func:`retire`: decided scenarios go to the buffer (:func:`harvest`) and their slots are
   vacated at rest (:func:`vacate`).

No value crosses slots (refill and harvest are gathers and scatters), so a cell's result does
not depend on its slot: the schedule independence that ``engine.py``'s docstring explains. The
host side, compiling :func:`block` and driving it, is :class:`engine.Engine`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from ..control import certificate as cert_mod
from .kernel import (
    Accumulators,
    Carry,
    initial_carry,
    lane_arrays,
    period_batch,
    rest_of,
    select,
    start,
)


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
        return tuple(
            v for v, (_, _, empty) in zip(jax.tree.leaves(carry), self.layout) if not empty
        )

    def unpack(self, packed: tuple, batch: int) -> Carry:
        it = iter(packed)
        leaves = [
            jnp.zeros((batch,) + shape, dtype) if empty else next(it)
            for shape, dtype, empty in self.layout
        ]
        return jax.tree.unflatten(self.treedef, leaves)


def broadcast(tree, n):
    return jax.tree.map(lambda v: jnp.broadcast_to(v, (n,) + jnp.shape(v)), tree)


def refill(
    slots: Slots,
    rest: Carry,
    taken,
    vacant,
    refill_cell,
    refill_force,
    refill_push,
    *,
    starts: Carry | None = None,
    refill_body=None,
) -> tuple[Slots, jax.Array]:
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


def refill_tiles(
    slots: Slots,
    rests: Carry,
    used,
    vacant,
    refill_cell,
    refill_force,
    refill_push,
    *,
    starts: Carry,
    refill_body,
    tile: int,
) -> tuple[Slots, jax.Array]:
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
    body_first = jnp.searchsorted(
        sorted_body, jnp.arange(n_bodies, dtype=jnp.int32), side="left"
    ).astype(jnp.int32)

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
    lead = jnp.clip(
        jnp.searchsorted(jnp.cumsum(leads.astype(jnp.int32)), nth + 1, side="left"), 0, R - 1
    )
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
        k=jnp.where(take, 0, slots.k),
        body=body,
    )
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
        control_periods=jnp.where(
            certified, acc.control_periods + (n_control - k), acc.control_periods
        ),
        **{
            name: jnp.where(certified, getattr(acc, name) + v.astype(dtype), getattr(acc, name))
            for name, v in tail.items()
        },
    )
    return acc, certified


def harvest(
    done: Finished, n_done, decided, cell, acc: Accumulators, k, certified
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
    return Slots(
        carry=select(decided, rest, carry),
        cell=jnp.where(decided, -1, slots.cell),
        force=jnp.where(decided, 0, slots.force),
        n_push=jnp.where(decided, 0, slots.n_push),
        k=k,
        body=slots.body,
    )


def take(
    slots: Slots,
    rest: Carry,
    taken,
    s,
    refill_cell,
    refill_force,
    refill_push,
    starts: Carry | None,
    *,
    gated: bool,
    refill_body=None,
    tile: int | None = None,
) -> tuple[Slots, jax.Array]:
    """Step 1 of a period (``s``: its index in the call): vacant slots take the next refill
    cells, in slot order. ``gated`` (with the certificate): only every ``CHECK_EVERY`` periods,
    so that every scenario's k is a multiple of it when it is checked (a check skipped for the
    whole batch, not masked per slot). ``tile``: per-lane bodies by body tiles
    (:func:`refill_tiles`; ``rest``: each body's, ``taken``: the offered cells used [R])."""
    vacant = slots.cell < 0
    if tile is not None:

        def fill(_):
            return refill_tiles(
                slots,
                rest,
                taken,
                vacant,
                refill_cell,
                refill_force,
                refill_push,
                starts=starts,
                refill_body=refill_body,
                tile=tile,
            )

        if not gated:
            return fill(None)
        # the tiles' sorts and searches run only in the periods that refill
        return jax.lax.cond(s % cert_mod.CHECK_EVERY == 0, fill, lambda _: (slots, taken), None)
    if gated:
        vacant = vacant & (s % cert_mod.CHECK_EVERY == 0)
    return refill(
        slots,
        rest,
        taken,
        vacant,
        refill_cell,
        refill_force,
        refill_push,
        starts=starts,
        refill_body=refill_body,
    )


def decide(
    check, static, n_control, carry: Carry, k, push, busy, due
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
    acc, certified = certify(
        check,
        static,
        carry.x_prev,
        carry.acc,
        k,
        n_push,
        ended,
        due,
        n_control=n_control,
        force=force,
    )
    return acc, certified, busy & (ended | certified)


def retire(
    done: Finished,
    n_done,
    decided,
    slots: Slots,
    acc: Accumulators,
    k,
    certified,
    *,
    carry: Carry,
    rest: Carry,
) -> tuple[Finished, jax.Array, Slots]:
    """Step 4 of a period: decided scenarios go to the buffer (:func:`harvest`) and their
    slots are vacated (:func:`vacate`)."""
    done, n_done = harvest(done, n_done, decided, slots.cell, acc, k, certified)
    return done, n_done, vacate(decided, rest, carry, slots, k)


def empty_finished(capacity: int, dtype) -> Finished:
    return Finished(
        cell=jnp.full(capacity, -1, jnp.int32),
        acc=broadcast(Accumulators.initial(dtype), capacity),
        periods=jnp.zeros(capacity, jnp.int32),
        certified=jnp.zeros(capacity, bool),
    )


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
    check = jax.vmap(
        lambda c, x, acc, over, left: cert_mod.check(jnp, c, x, acc, over, left),
        in_axes=(axis, 0, 0, 0, 0),
    )
    if body is not None:
        return lambda x, acc, over, left: check(lane_arrays(cert, body), x, acc, over, left)
    return lambda x, acc, over, left: check(cert, x, acc, over, left)


def opened(
    arrays, sensors, static, slots: Slots, refill_init, packing: Packing, refill_body=None
) -> tuple[Slots, Carry, Carry]:
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
        lane_arrays(arrays, refill_body), lane_arrays(rests, refill_body), refill_init
    )
    return slots, rests, starts


def _run_period(
    arrays,
    sensors,
    static,
    cert,
    slots: Slots,
    rest: Carry,
    s,
    *,
    done: Finished,
    n_done,
    periods: int,
    tile: int | None,
    lanes: bool,
) -> tuple[Finished, jax.Array, Slots]:
    """Steps 2-4 of :func:`block`'s period ``s``: run it, decide, harvest and vacate."""
    every = cert_mod.CHECK_EVERY
    axis = 0 if lanes else None
    body, body_rest = (
        (lane_arrays(arrays, slots.body), lane_arrays(rest, slots.body))
        if lanes
        else (arrays, rest)
    )
    check = checker(cert, periods, axis, slots.body if lanes else None)
    # lanes: the QPs by body tiles of ``tile`` slots (:func:`refill_tiles`)
    carry = period_batch(
        body,
        sensors,
        static,
        slots.carry,
        slots.k,
        slots.force,
        slots.n_push,
        tile=tile,
        axis=axis,
        tiles=(arrays.qp, slots.body[::tile]) if lanes else None,
    )[0]
    k = slots.k + 1
    acc, certified, decided = decide(
        check,
        static,
        body.n_control,
        carry,
        k,
        (slots.n_push, slots.force),
        slots.cell >= 0,
        s % every == every - 1,
    )
    return retire(done, n_done, decided, slots, acc, k, certified, carry=carry, rest=body_rest)


def block(
    arrays,
    sensors,
    static,
    cert,
    slots: Slots,
    *,
    refill_cell,
    refill_force,
    refill_push,
    refill_init,
    refill_body,
    periods: int,
    packing: Packing,
    tile: int | None = None,
    lanes: bool = False,
):
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
    slots, rest, starts = opened(
        arrays, sensors, static, slots, refill_init, packing, refill_body if lanes else None
    )

    def step(state, s):
        slots, taken, done, n_done = state
        # 1. refill; 2. one control period of every slot; 3. decide; 4. harvest and vacate
        slots, taken = take(
            slots,
            rest,
            taken,
            s,
            refill_cell,
            refill_force,
            refill_push,
            starts,
            gated=cert is not None,
            refill_body=refill_body,
            tile=tile if lanes else None,
        )
        done, n_done, slots = _run_period(
            arrays,
            sensors,
            static,
            cert,
            slots,
            rest,
            s,
            done=done,
            n_done=n_done,
            periods=periods,
            tile=tile,
            lanes=lanes,
        )
        return (slots, taken, done, n_done), None

    done = empty_finished(S + refill_cell.shape[0], arrays.d0.qpos.dtype)
    zero = jnp.zeros((), jnp.int32)
    taken = jnp.zeros(refill_cell.shape, bool) if lanes else zero
    (slots, taken, done, _), _ = jax.lax.scan(
        step, (slots, taken, done, zero), jnp.arange(periods, dtype=jnp.int32)
    )
    return slots._replace(carry=packing.pack(slots.carry)), taken if lanes else taken[None], done
