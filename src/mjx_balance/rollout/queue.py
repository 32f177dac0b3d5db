"""The engine's work queue: the cells not yet in a slot, longest expected first, offered to
every device as it refills (docs/engine.md, "Longest first"). Host-side NumPy; the engines
(``engine.Engine``, ``cpath.CEngine``) hold one per run.
"""

from __future__ import annotations

import numpy as np

# Finished or running cells whose longest length is a queued cell's expected length (Queue).
# 16 of them and the periods of the cells in a slot (Queue.running), against the nearest one
# and whole calls: 11 calls instead of 14 for a 153,520-cell sweep replayed on 16,384 slots,
# 14 instead of 17 for a cohort of that size (docs/scripts/queue_replay.py, BENCHMARKS.md).
NEIGHBOURS = 16


class Queue:
    """The cells not yet in a slot, longest expected first. Each call offers every device up to
    ``refill`` cells (device d gets offer[d::D]: neighbouring cells spread over the devices);
    what a device did not take stays at the head of the queue.

    Order (list scheduling's longest-first rule): a long scenario that starts late holds the
    run's end while the other slots idle, so the queue starts the cells expected to run longest
    first. Before any cell has finished, smaller |force| first: small pushes recover, and a
    recovery runs until it is certified or to t_end, a fall only until it falls (docs/engine.md,
    "Longest first"). Once cells finish (:meth:`finished`), a cell's expected length is the
    longest of its ``NEIGHBOURS`` nearest cells in (force, push steps, initial state), of any
    body, among the cells that finished or that are in a slot (as long as they have run so
    far: :meth:`running`, else the whole calls since they took a slot); while fewer than
    ``NEIGHBOURS`` squared are known, of fewer (a sixteenth of those known). Re-estimated each
    time the count of finished cells has grown by a tenth. The longest of several, not the
    nearest one: lengths peak on the thin ridge along the recovery boundary, where one
    neighbour is often a short fall across it, and a long cell started late costs the run far
    more than a short one started early. Other bodies' cells count as neighbours: a body's
    index says nothing about its cells, and a cohort's bodies run at once. Only the schedule
    depends on it: a cell's result is the same in any slot and at any time (the module
    docstring).
    """

    def __init__(
        self,
        forces: np.ndarray,
        n_push: np.ndarray,
        devices: int,
        refill: int,
        inits: np.ndarray | None = None,
        block: int = 1,
        bodies: np.ndarray | None = None,
        wave: int = 1,
    ):
        self.forces, self.n_push = forces, n_push
        self.wave = max(1, int(wave))
        n = forces.shape[0]
        self.inits = np.zeros((n, 4)) if inits is None else inits
        self.bodies = np.zeros(n, np.int32) if bodies is None else bodies
        self.D, self.R, self.block = devices, refill, block
        self.pending = self._grouped(np.argsort(np.abs(forces), kind="stable"))
        self.length = np.full(n, -1, np.int64)  # control periods of a finished cell
        self.progress = np.full(n, -1, np.int64)  # periods run so far by a cell in a slot
        self.taken_at = np.full(n, -1, np.int64)  # the call in which a cell took a slot
        self.calls = 0
        self._sorted_at = 0  # finished cells when the queue was last ordered
        self._per: list[np.ndarray] = []

    def _features(self) -> np.ndarray:
        """Each cell's (force, log push steps, initial state) scaled to [-1, 1] per column."""
        cols = np.column_stack([self.forces, np.log1p(self.n_push), self.inits])
        span = np.abs(cols).max(axis=0)
        return cols[:, span > 0] / span[span > 0]

    def _order(self) -> None:
        """Longest expected first (stable: ties keep their order)."""
        done = self.length >= 0
        count = int(done.sum())
        if not count or self.pending.size < 2 or count < 1.1 * self._sorted_at:
            return
        self._sorted_at = count
        feats = self._features()
        if not feats.shape[1]:  # every cell alike: nothing tells them apart
            return
        from scipy.spatial import cKDTree

        flight = (self.taken_at >= 0) & ~done
        known = np.flatnonzero(done | flight)
        ran = np.where(
            done,
            self.length,
            np.maximum(self.progress, (self.calls - self.taken_at - 1) * self.block),
        )
        k = min(NEIGHBOURS, max(1, known.size // NEIGHBOURS))
        # one worker, in this thread: scipy's workers are Python threads that a signal's
        # exception in this thread abandons mid-query, and they then read the arrays its
        # unwinding frees (a segfault after SIGTERM in a 1,001,000-cell sweep, 4 of 8 runs)
        _, near = cKDTree(feats[known]).query(feats[self.pending], k=k, workers=1)
        expected = ran[known][near.reshape(self.pending.size, k)].max(axis=1)
        self.pending = self._grouped(self.pending[np.argsort(-expected, kind="stable")])

    def _grouped(self, order: np.ndarray) -> np.ndarray:
        """``order`` with the cells grouped by waves of ``wave`` bodies (bodies 0..wave-1
        first, then the next ``wave``, ...), stable within a wave. An engine whose slots hold
        one body per tile (``slots.refill_tiles``) is given as many bodies at a time as it has
        tiles: each tile then finds its body's cells in the offers, and the longest cells of the
        wave's bodies start first, instead of one body's after another's."""
        return order[np.argsort(self.bodies[order] // self.wave, kind="stable")]

    def offer(self) -> tuple[np.ndarray, ...]:
        """(cells [D R], -1: none; their forces; their push steps; their initial joint states
        [D R, 4]; their bodies) for the next call."""
        D, R = self.D, self.R
        self._order()
        offer = self.pending[: D * R]
        cells = np.full(D * R, -1, np.int32)
        self._per = [offer[d::D] for d in range(D)]
        for d, part in enumerate(self._per):
            cells[d * R : d * R + part.size] = part
        used = cells >= 0
        f = np.zeros(D * R, np.float64)
        p = np.zeros(D * R, np.int32)
        f[used], p[used] = self.forces[cells[used]], self.n_push[cells[used]]
        init = np.zeros((D * R, 4), np.float64)
        init[used] = self.inits[cells[used]]
        body = np.zeros(D * R, np.int32)
        body[used] = self.bodies[cells[used]]
        return cells, f, p, init, body

    def took(self, taken: np.ndarray) -> None:
        """How many of its offered cells each device took [D] (the first ones of its offer),
        or which [D R] (bool, :meth:`offer`'s layout; body tiles take cells out of order)."""
        offer = self.pending[: self.D * self.R]  # device d's part is offer[d::D]
        left = np.ones(offer.size, bool)
        for d in range(self.D):
            part = left[d :: self.D]
            if taken.dtype == bool:
                part &= ~taken[d * self.R : d * self.R + part.size]
            else:
                part[: int(taken[d])] = False
        self.taken_at[offer[~left]] = self.calls
        self.pending = np.concatenate([offer[left], self.pending[offer.size :]])
        self.calls += 1

    def finished(self, cells: np.ndarray, periods: np.ndarray) -> None:
        """Cells decided, with the control periods each ran (orders what is still queued)."""
        self.length[cells] = periods

    def running(self, cells: np.ndarray, periods: np.ndarray) -> None:
        """The cells in a slot after a call (-1: a vacant slot) and the control periods each
        has run: their lengths' lower bounds, up to a call sharper than the calls they have
        been in."""
        busy = cells >= 0
        self.progress[cells[busy]] = periods[busy]
