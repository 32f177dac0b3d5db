"""Per-lane bodies by body tiles (rollout/slots.py ``refill_tiles``, control/admm.py
``admm_solve_tiles``): every tile of slots holds one body at a time, so that its QPs share their
matrix products; the queue groups the cells by body and takes back the cells a tile used, in
whatever order it used them. Small pure-JAX cases: nothing here compiles MJX."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_balance.control import admm
from mjx_balance.control.qp import build_qp
from mjx_balance.model.params import BodyParams, ControllerParams
from mjx_balance.rollout.slots import Slots, refill_tiles
from mjx_balance.rollout.queue import Queue


# refill_tiles as it runs in the engine: inside jit (one program per shape, not one small
# program per operation).
jit_refill_tiles = jax.jit(refill_tiles, static_argnames=("tile",))


def slots_of(cell, body):
    """Slots whose carry is one number per slot: the body whose rest it holds (-1: a scenario's
    start, 100 + c: cell c's start)."""
    cell, body = np.asarray(cell, np.int32), np.asarray(body, np.int32)
    S = cell.size
    return Slots(
        carry={"x": jnp.asarray(np.where(cell >= 0, 100 + cell, body), jnp.float32)},
        cell=jnp.asarray(cell),
        force=jnp.zeros(S),
        n_push=jnp.zeros(S, jnp.int32),
        k=jnp.ones(S, jnp.int32),
        body=jnp.asarray(body),
    )


def refill_of(slots, offer_body, used=None, tile=2):
    R = len(offer_body)
    cells = jnp.arange(R, dtype=jnp.int32)
    starts = {"x": 100.0 + jnp.arange(R, dtype=jnp.float32)}
    rests = {"x": jnp.arange(4, dtype=jnp.float32)}  # body b's rest: b
    used = jnp.zeros(R, bool) if used is None else jnp.asarray(used)
    return jit_refill_tiles(
        slots,
        rests,
        used,
        slots.cell < 0,
        cells,
        jnp.ones(R),
        jnp.ones(R, jnp.int32),
        starts=starts,
        refill_body=jnp.asarray(offer_body, jnp.int32),
        tile=tile,
    )


def test_a_tile_takes_only_cells_of_its_body_and_an_empty_tile_takes_the_next_body():
    # tiles of 2: [busy body 1, vacant], [vacant, vacant] (an empty tile, body 0 so far),
    # [busy body 0, busy body 0]
    slots = slots_of([7, -1, -1, -1, 8, 9], [1, 1, 0, 0, 0, 0])
    new, used = refill_of(slots, [0, 0, 1, 2, 2])
    # the first tile's vacant slot takes the first body-1 cell (offer 2), not the body-0 ones;
    # the empty tile takes the first cell left's body (0) and its two cells
    assert np.asarray(new.cell).tolist() == [7, 2, 0, 1, 8, 9]
    assert np.asarray(new.body).tolist() == [1, 1, 0, 0, 0, 0]
    assert np.asarray(used).tolist() == [True, True, True, False, False]
    assert np.asarray(new.carry["x"]).tolist() == [107, 102, 100, 101, 108, 109]
    assert np.asarray(new.k).tolist() == [1, 0, 0, 0, 1, 1]


def test_an_empty_tile_switches_body_with_its_idle_slots_at_the_new_rest():
    # one cell of body 2 left for an empty tile of 2: one slot takes it, the other idles at
    # body 2's rest, so that the whole tile is body 2
    slots = slots_of([-1, -1, 5, -1], [0, 0, 1, 1])
    new, used = refill_of(slots, [1, 2, 2], used=[True, False, True])
    assert np.asarray(new.cell).tolist() == [1, -1, 5, -1]
    assert np.asarray(new.body).tolist() == [2, 2, 1, 1]
    assert np.asarray(new.carry["x"]).tolist() == [101, 2, 105, 1]
    assert np.asarray(used).tolist() == [True, True, True]


def test_no_cell_is_taken_twice_and_unused_offers_stay_for_later():
    rng = np.random.default_rng(3)
    for _ in range(20):
        cell = np.where(rng.random(8) < 0.5, rng.integers(50, 60, 8), -1)
        body = np.repeat(rng.integers(0, 3, 4), 2)
        slots = slots_of(cell, body)
        offer = np.sort(rng.integers(0, 3, 10))
        new, used = refill_of(slots, offer)
        new_cell, new_body = np.asarray(new.cell), np.asarray(new.body)
        taken = new_cell[(cell < 0) & (new_cell >= 0)]
        assert sorted(taken.tolist()) == np.flatnonzero(np.asarray(used)).tolist()
        for t in range(4):  # one body per tile, and the offers it took are that body's
            assert len(set(new_body[2 * t : 2 * t + 2])) == 1
            took = new_cell[2 * t : 2 * t + 2][cell[2 * t : 2 * t + 2] < 0]
            assert all(offer[c] == new_body[2 * t] for c in took if c >= 0)
            if (cell[2 * t : 2 * t + 2] >= 0).any():  # a busy tile keeps its body
                assert new_body[2 * t] == body[2 * t]


def rule(cell, body, vacant, offer_body, used, tile):
    """refill_tiles's documented rule, one slot and one tile at a time: busy tiles' vacant
    slots first, each taking its body's first cell left; then each empty tile (in order) the
    next group of up to ``tile`` cells of one body (groups in the order of their first cells)."""
    cell, body, avail = list(cell), list(body), [not u for u in used]
    T = len(cell) // tile
    empty = [all(c < 0 for c in cell[t * tile : (t + 1) * tile]) for t in range(T)]
    for s in range(len(cell)):
        if vacant[s] and not empty[s // tile]:
            mine = [c for c in range(len(avail)) if avail[c] and offer_body[c] == body[s]]
            if mine:
                cell[s], avail[mine[0]] = mine[0], False
    groups = []
    for b in sorted(set(offer_body)):
        mine = [c for c in range(len(avail)) if avail[c] and offer_body[c] == b]
        groups += [mine[i : i + tile] for i in range(0, len(mine), tile)]
    groups.sort(key=lambda g: g[0])
    for t in range(T):
        seats = [s for s in range(t * tile, (t + 1) * tile) if vacant[s]]
        if empty[t] and seats and groups:
            group = groups.pop(0)
            for s in range(t * tile, (t + 1) * tile):
                body[s] = offer_body[group[0]]
            for s, c in zip(seats, group):
                cell[s], avail[c] = c, False
    return cell, body, [not a for a in avail]


@pytest.mark.parametrize("tile", [2, 4])
def test_the_refill_follows_its_rule_on_random_slots(tile):
    """Random slots, bodies, gating and offers with cells already used: refill_tiles (sorts and
    searches) takes exactly the cells the rule above takes, and puts the idle slots of a tile
    that changed body at that body's rest."""
    rng = np.random.default_rng(7)
    S = 4 * tile
    for _ in range(40):
        cell = np.where(rng.random(S) < 0.4, rng.integers(50, 60, S), -1)
        body = np.repeat(rng.integers(0, 4, S // tile), tile)
        offer = rng.integers(0, 4, 12)  # any order: waves interleave bodies
        used = rng.random(12) < 0.3
        gated = rng.random() < 0.2  # a period between refills: no slot takes a cell
        slots = slots_of(cell, body)
        R = offer.size
        new, took = jit_refill_tiles(
            slots,
            {"x": jnp.arange(4, dtype=jnp.float32)},
            jnp.asarray(used),
            (slots.cell < 0) & (not gated),
            jnp.arange(R, dtype=jnp.int32),
            jnp.ones(R),
            jnp.ones(R, jnp.int32),
            starts={"x": 100.0 + jnp.arange(R, dtype=jnp.float32)},
            refill_body=jnp.asarray(offer, jnp.int32),
            tile=tile,
        )
        want_cell, want_body, want_used = rule(
            cell, body, (cell < 0) & (not gated), offer.tolist(), used, tile
        )
        assert np.asarray(new.cell).tolist() == want_cell
        assert np.asarray(new.body).tolist() == want_body
        assert np.asarray(took).tolist() == want_used
        want_x = np.where(
            np.asarray(want_cell) >= 0,
            100 + np.asarray(want_cell),
            np.where(cell >= 0, 100 + cell, want_body),
        )
        assert np.asarray(new.carry["x"]).tolist() == want_x.tolist()


def test_the_queue_groups_by_body_and_takes_back_a_mask():
    forces = np.array([30.0, 10.0, 20.0, 0.0, 5.0])
    q = Queue(forces, np.ones(5, np.int32), devices=2, refill=2, bodies=np.array([1, 0, 1, 0, 2]))
    assert q.pending.tolist() == [3, 1, 2, 0, 4]  # body by body, smaller |force| first
    cells, *_ = q.offer()
    assert cells.tolist() == [3, 2, 1, 0]  # device 0 gets offer[0::2], device 1 offer[1::2]
    q.took(np.array([False, True, True, False]))  # device 0 took cell 2, device 1 cell 1
    assert q.pending.tolist() == [3, 0, 4]
    q.took(np.array([1, 0]))  # counts: the first offered of device 0
    assert q.pending.tolist() == [0, 4]


@pytest.mark.parametrize("tile", [2, 4])
def test_a_body_tile_solves_each_lane_as_its_own_body_would(tile):
    """Each lane of admm_solve_tiles equals the same lane solved with its body's QP shared by
    the batch (float64: the products' rows are the lane's own sums). Measured: the same bits.
    The bound allows another summation order of each product on another CPU: float64's 2.2e-16
    x 120 terms x 100 iterations is about 3e-12 relative, well inside 1e-9; an iteration count
    could then change only for a residual within that of its tolerance."""
    controller = ControllerParams()
    settings = admm.settings_from_controller(controller)
    bodies = [BodyParams(), BodyParams(lower_mass=40.0, upper_mass=45.0, upper_length=0.7)]
    datas = [admm.build_admm(build_qp(controller, b, 0.01), settings, jnp.float64) for b in bodies]
    stacked = jax.tree.map(lambda *v: jnp.stack(v), *datas)
    rng = np.random.default_rng(1)
    B = 8
    x0 = jnp.asarray(rng.normal(0, 0.02, (B, 4)))
    warm = jax.vmap(lambda _: admm.initial_warm(datas[0]))(jnp.arange(B))
    tile_body = jnp.asarray(np.arange(B // tile) % 2, jnp.int32)
    got = jax.jit(admm.admm_solve_tiles, static_argnums=(4, 5))(
        stacked, tile_body, x0, warm, settings, tile
    )
    lane_body = np.repeat(np.asarray(tile_body), tile)
    for b, data in enumerate(datas):
        alone = admm.admm_solve_batch(data, x0, warm, settings)
        mine = lane_body == b
        np.testing.assert_allclose(
            np.asarray(got.z)[mine], np.asarray(alone.z)[mine], rtol=1e-9, atol=1e-12
        )
        assert np.asarray(got.iters)[mine].tolist() == np.asarray(alone.iters)[mine].tolist()
    assert not np.allclose(
        np.asarray(got.z)[lane_body == 0][0],  # two bodies, not one twice
        np.asarray(admm.admm_solve_batch(datas[1], x0, warm, settings).z)[lane_body == 0][0],
    )
