"""The slot occupancy a population's one queue would give on an accelerator's slots, replayed
from cell lengths recorded on this machine.

    python docs/scripts/occupancy_replay.py [--subjects 4] [--forces 0:155:10] \
        [--durations 0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5] [--slots 16384] [--population 1200]

Runs ``--subjects`` subjects (heights 1.55-1.90 m, masses 50-100 kg) over the grid through one
engine queue on the MJX path (``runs.population``) and records each cell's control periods
(its length: to its fall, its certificate or t_end). Then replays the engine's schedule on
``--slots`` slots for a population of ``--population`` subjects whose cells have the recorded
subjects' lengths (subject k of the population has subject k mod ``--subjects``'s lengths:
a model of a population, stated as such): every slot takes the next queued cell when its cell
is decided (in whole blocks of ``--block`` periods, as the engine refills after each call),
the cells longest first (the engine's queue orders by expected length; here the lengths are
known, the best case), one subject's map queued after another's as a sweep per subject would
(``each``) or all in one queue (``one``), and all in one queue with the slots in body tiles
of ``--tile`` (the engine's per-lane bodies, ``rollout.slots.refill_tiles``: a tile's free
slots take only cells of the tile's body; a tile whose slots are all free takes the body whose
next cell is the longest left; the offer is not limited). Prints the occupancy (busy
slot-periods / slots x periods) and the periods to finish, for each.
"""

from __future__ import annotations

import argparse
import heapq
from collections import deque

import numpy as np

import mjx_balance as mb
from mjx_balance.runs.grid import parse_grid
from mjx_balance.runs.population import Population


def replay(lengths: list[np.ndarray], slots: int, block: int, one_queue: bool
           ) -> tuple[float, int]:
    """(occupancy, periods) of list scheduling on ``slots`` slots: ``lengths`` per subject;
    ``one_queue``: every subject's cells in one queue, longest first; else each subject's map
    its own run (all slots start it; the next starts when its last cell is decided)."""
    queues = [np.concatenate(lengths)] if one_queue else lengths
    clock, busy = 0, 0
    for cells in queues:
        order = np.sort(cells)[::-1]
        free = [clock] * slots  # the period at which each slot is free
        heapq.heapify(free)
        end = clock
        for length in order:
            start = heapq.heappop(free)
            start = -(-start // block) * block  # a slot is refilled at a call's boundary
            finish = start + int(length)
            end = max(end, finish)
            busy += int(length)
            heapq.heappush(free, finish)
        clock = end
    return busy / (slots * clock), clock


def replay_tiles(lengths: list[np.ndarray], slots: int, block: int, tile: int
                 ) -> tuple[float, int]:
    """(occupancy, periods) of one queue on ``slots`` slots in tiles of ``tile``, each tile
    one body at a time, refilled at a call's boundary (every ``block`` periods)."""
    cells = [deque(np.sort(c)[::-1].tolist()) for c in lengths]
    heads = [(-c[0], k) for k, c in enumerate(cells) if c]  # bodies by their longest cell left
    heapq.heapify(heads)
    finish = np.zeros(slots, np.int64)
    body = np.full(slots // tile, -1)
    left, clock, busy = sum(len(c) for c in cells), 0, 0
    while left:
        free = finish <= clock
        for t in range(slots // tile):
            mine = np.flatnonzero(free[t * tile:(t + 1) * tile]) + t * tile
            if not mine.size:
                continue
            if mine.size == tile:  # every slot free: the body whose next cell is the longest
                body[t] = -1
                while heads:
                    head, k = heapq.heappop(heads)
                    if cells[k] and -head == cells[k][0]:
                        body[t] = k
                        break
                    if cells[k]:  # a stale entry: the body's head moved on
                        heapq.heappush(heads, (-cells[k][0], k))
            k = body[t]
            if k < 0:
                continue
            for slot in mine[:len(cells[k])]:
                length = cells[k].popleft()
                finish[slot] = clock + length
                busy += length
                left -= 1
            if cells[k]:
                heapq.heappush(heads, (-cells[k][0], k))
        clock += block
    end = int(finish.max())
    return busy / (slots * end), end


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--subjects", type=int, default=4)
    p.add_argument("--forces", default="0:155:10")
    p.add_argument("--durations", default="0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5")
    p.add_argument("--slots", type=int, default=16384)
    p.add_argument("--block", type=int, default=100)
    p.add_argument("--population", type=int, default=1200)
    p.add_argument("--tile", type=int, default=8)
    args = p.parse_args()
    heights = np.linspace(1.55, 1.90, args.subjects)
    masses = np.linspace(50, 100, args.subjects)
    configs = [mb.Subject(float(h), float(m)).config() for h, m in zip(heights, masses)]
    forces = parse_grid(args.forces, "forces")
    durations = parse_grid(args.durations, "durations")
    people = Population(configs, forces, durations)
    columns = people.run(range(len(configs)))
    recorded = [np.asarray(columns[i]["periods"], np.int64) for i in range(len(configs))]
    cells = forces.size * durations.size
    print(f"recorded: {len(configs)} subjects x {cells} cells (MJX, one queue, "
          f"{people.slots} slots); periods per cell: mean "
          f"{np.mean(np.concatenate(recorded)):.0f}, max {max(r.max() for r in recorded)}")
    lengths = [recorded[k % len(recorded)] for k in range(args.population)]
    print(f"replayed: {args.population} subjects x {cells} cells = "
          f"{args.population * cells:,} cells on {args.slots:,} slots, refilled every "
          f"{args.block} periods")
    for one in (False, True):
        occupancy, periods = replay(lengths, args.slots, args.block, one)
        print(f"  {'one queue' if one else 'each subject its own run'}: occupancy "
              f"{100 * occupancy:.1f} %, {periods:,} periods")
    occupancy, periods = replay_tiles(lengths, args.slots, args.block, args.tile)
    print(f"  one queue, body tiles of {args.tile}: occupancy {100 * occupancy:.1f} %, "
          f"{periods:,} periods")


if __name__ == "__main__":
    main()
