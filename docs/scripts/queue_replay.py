"""The engine's schedule replayed on many slots from recorded cell lengths: the real queue
(``queue.Queue``: its order, its offers, its estimates from finished cells) and the real refill
(``slots.refill`` or, for per-lane bodies, ``slots.refill_tiles``), with each slot's scenario
lasting its recorded control periods instead of being simulated. It predicts an accelerator's
calls and slot occupancy from a CPU's recordings.

    python docs/scripts/queue_replay.py [--record FILE.npz] [--subjects 3] \
        [--forces 0:150:4] [--durations 0.05:2.0:0.05] [--population 100] [--slots 16384] \
        [--oracle]

``--oracle``: a queue that knows every cell's length, longest first from the start (the best
this rule can do). With ``PYTHONPATH=CHECKOUT/src`` it replays another commit's queue and
refill (one without ``Queue.running`` is not told the periods of the cells in a slot, as its
engine did not tell it).

Records (or reads from ``--record``, written the first time) the control periods of every cell
of the study's body and ``--subjects`` subjects of ``cohort_members.population(100, 1)`` over the grid,
MJX path, one queue. Replays (1) a cohort of ``--population`` subjects and the base body in one
queue with body tiles, body b having the recorded lengths of recorded body b mod the count (a
model of a population, stated as such), and (2) a plain sweep of as many cells of the study's
body (forces spread over the range; each cell the length of the nearest recorded force).
Prints each one's calls, periods and occupancy (the cells' periods over the slot-periods).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import mjx_balance as mb
from mjx_balance.control.certificate import CHECK_EVERY
from mjx_balance.rollout.engine import LANE_TILE
from mjx_balance.rollout.slots import Slots, refill, refill_tiles
from mjx_balance.rollout.queue import Queue
from mjx_balance.rollout.runner import push_steps
from mjx_balance.runs.grid import parse_grid
from mjx_balance.runs.population import Population
from mjx_balance.studies import members as cohort_members


def record(path: Path, forces, durations, subjects: int) -> dict[str, np.ndarray]:
    if path.exists():
        return dict(np.load(path))
    configs = [mb.Config()] + [m.subject.config() for m in cohort_members.population(100, 1)[:subjects]]
    columns = Population(configs, forces, durations).run(range(len(configs)))
    lengths = np.stack([np.asarray(columns[i]["periods"], np.int64) for i in range(len(configs))])
    np.savez(path, lengths=lengths, forces=forces, durations=durations)
    return dict(lengths=lengths, forces=forces, durations=durations)


class Known(Queue):
    """A queue given the cells longest first, which it keeps."""

    def _order(self) -> None:
        return None


def replay(forces, n_push, lengths, bodies, slots: int, block: int, tile: int | None,
           n_bodies: int = 1, oracle: bool = False) -> dict:
    """Calls, periods and occupancy of the engine's loop over these cells (one device)."""
    n = forces.size
    R = 4 * slots
    queue = (Known if oracle else Queue)(forces, n_push, 1, R, None, block, bodies,
                                         wave=slots // tile if tile else 1)
    if oracle:
        queue.pending = queue._grouped(np.argsort(-lengths, kind="stable"))
    cell = np.full(slots, -1, np.int64)
    body = np.zeros(slots, np.int32)
    k = np.zeros(slots, np.int64)
    rests = {"x": jnp.zeros((n_bodies, 1))}

    @jax.jit
    def fill(cell, body, taken, vacant, offer, offer_body):  # the engine's own refill
        state = Slots(carry={"x": jnp.zeros((slots, 1))}, cell=cell, force=jnp.zeros(slots),
                      n_push=jnp.zeros(slots, jnp.int32), k=jnp.zeros(slots, jnp.int32),
                      body=body)
        args = (taken, vacant, offer, jnp.ones(R), jnp.ones(R, jnp.int32))
        starts = {"x": jnp.zeros((R, 1))}
        if tile:
            new, taken = refill_tiles(state, rests, *args, starts=starts,
                                      refill_body=offer_body, tile=tile)
        else:
            new, taken = refill(state, rests, *args, starts=starts, refill_body=offer_body)
        return new.cell, new.body, taken

    left, calls = n, 0
    while left:
        offer, _, _, _, offer_body = queue.offer()
        taken = np.zeros(R, bool) if tile else np.int32(0)
        finished, periods = [], []
        for s in range(block):
            if s % CHECK_EVERY == 0:
                vacant = cell < 0
                new_cell, body, taken = jax.device_get(fill(
                    jnp.asarray(cell, jnp.int32), jnp.asarray(body), jnp.asarray(taken),
                    jnp.asarray(vacant), jnp.asarray(offer, jnp.int32),
                    jnp.asarray(offer_body, jnp.int32)))
                fresh = vacant & (new_cell >= 0)
                cell = new_cell.astype(np.int64)
                k[fresh] = 0
            busy = cell >= 0
            k[busy] += 1
            done = busy & (k >= lengths[np.maximum(cell, 0)])
            finished.append(cell[done].copy())
            periods.append(k[done].copy())
            cell[done] = -1
        queue.took(taken if tile else np.array([taken]))
        if hasattr(queue, "running"):  # as the engine tells it after each call
            queue.running(cell, k)
        ended = np.concatenate(finished)
        queue.finished(ended, np.concatenate(periods))
        left -= ended.size
        calls += 1
    work = int(lengths.sum())
    return dict(calls=calls, periods=calls * block, occupancy=work / (calls * block * slots),
                mean=float(lengths.mean()), max=int(lengths.max()))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--record", default="lengths.npz")
    p.add_argument("--subjects", type=int, default=3)
    p.add_argument("--forces", default="0:150:4")
    p.add_argument("--durations", default="0.05:2.0:0.05")
    p.add_argument("--population", type=int, default=100)
    p.add_argument("--slots", type=int, default=16384)
    p.add_argument("--block", type=int, default=100)
    p.add_argument("--plain", action=argparse.BooleanOptionalAction, default=True)
    p.add_argument("--oracle", action="store_true")
    args = p.parse_args()
    forces = parse_grid(args.forces, "forces")
    durations = parse_grid(args.durations, "durations")
    rec = record(Path(args.record), forces, durations, args.subjects)
    lengths = rec["lengths"]
    F, D = np.meshgrid(forces, durations, indexing="ij")
    steps = push_steps(D.ravel(), mb.Config().scenario.physics_dt)
    cells = forces.size * durations.size
    n_maps = args.population + 1
    print(f"recorded {len(lengths)} bodies x {cells} cells; periods a cell: mean "
          f"{lengths.mean():.0f}, max {lengths.max()}")
    cohort_lengths = np.concatenate([lengths[b % len(lengths)] for b in range(n_maps)])
    got = replay(np.tile(F.ravel(), n_maps), np.tile(steps, n_maps), cohort_lengths,
                 np.repeat(np.arange(n_maps, dtype=np.int32), cells), args.slots, args.block,
                 LANE_TILE, n_maps, args.oracle)
    print(f"cohort, one queue, body tiles of {LANE_TILE}: {n_maps * cells:,} cells on "
          f"{args.slots:,} slots: {got['calls']} calls, occupancy "
          f"{100 * got['occupancy']:.1f} %")
    if args.plain:
        plain = np.linspace(forces[0], forces[-1], n_maps * cells // durations.size)
        nearest = np.abs(plain[:, None] - forces[None, :]).argmin(axis=1)
        plain_lengths = lengths[0].reshape(forces.size, durations.size)[nearest].ravel()
        PF, PD = np.meshgrid(plain, durations, indexing="ij")
        got = replay(PF.ravel(), push_steps(PD.ravel(), mb.Config().scenario.physics_dt),
                     plain_lengths,
                     np.zeros(PF.size, np.int32), args.slots, args.block, None,
                     oracle=args.oracle)
        print(f"plain sweep: {PF.size:,} cells: {got['calls']} calls, occupancy "
              f"{100 * got['occupancy']:.1f} %")


if __name__ == "__main__":
    main()
