"""The engine's work queue (rollout/queue.py ``Queue``): every cell is offered until taken and
taken once, and the queue starts the cells expected to run longest first.

Only the schedule depends on the order (a cell's result is the same in any slot and at any
time: tests/rollout/test_engine.py checks the bytes), so these tests drive the queue with a model
of the engine (slots refilled at period boundaries, ``block`` periods per call) and known lengths.
"""

import heapq

import numpy as np

from mjx_balance.rollout.queue import Queue


def simulate(queue: Queue, length: np.ndarray, slots: int, block: int) -> tuple[int, list]:
    """Run the queue's cells through ``slots`` slots per device, as the engine does: each call
    runs ``block`` periods, a slot that frees takes its device's next offered cell; returns
    (periods until the last cell finished, the cells in the order they were taken)."""
    D = queue.D
    free = [[0] * slots for _ in range(D)]  # period at which each slot frees
    for f in free:
        heapq.heapify(f)
    running: list[tuple[int, int]] = []  # (end period, cell)
    taken_order, t, left = [], 0, length.size
    while left:
        cells, *_ = queue.offer()
        parts = [cells[d * queue.R : (d + 1) * queue.R] for d in range(D)]
        took = np.zeros(D, int)
        for d in range(D):
            part = parts[d][parts[d] >= 0]
            while took[d] < part.size and free[d][0] < t + block:
                start = max(heapq.heappop(free[d]), t)
                cell = int(part[took[d]])
                took[d] += 1
                heapq.heappush(free[d], start + int(length[cell]))
                running.append((start + int(length[cell]), cell))
                taken_order.append(cell)
        queue.took(took)
        t += block
        done = [(e, c) for e, c in running if e <= t]
        running = [(e, c) for e, c in running if e > t]
        if done:
            cells_done = np.array([c for _, c in done])
            queue.finished(cells_done, length[cells_done])
            left -= len(done)
    return max(max(f) for f in free), taken_order


def workload(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Forces, push steps and lengths shaped like the bench's: tiny pushes never certify
    (t_end: 1200 periods), recoveries run longer than falls, long pushes at least their push."""
    rng = np.random.default_rng(seed)
    forces = np.round(rng.uniform(0, 150, n), 1)
    n_push = np.round(np.exp(rng.uniform(np.log(25), np.log(5000), n))).astype(np.int32)
    steps = n_push / 5  # control periods the push lasts
    recovers = forces * steps < 400
    length = np.where(
        forces < 2, 1200, np.where(recovers, np.minimum(1200, steps + 250), 40 + steps // 4)
    )
    return forces, n_push, length.astype(np.int64)


def test_every_cell_is_taken_exactly_once():
    for seed, (D, R, S, block) in enumerate([(1, 4, 2, 1), (2, 128, 32, 100), (3, 7, 5, 10)]):
        forces, n_push, length = workload(301, seed)
        queue = Queue(forces, n_push, D, R, block=block)
        _, order = simulate(queue, length, S, block)
        assert sorted(order) == list(range(forces.size))
        assert queue.pending.size == 0


def test_cells_alike_keep_their_order():
    """Cells with one force, one push and one initial state (repeats of a scenario; no push
    from rest): nothing to rank by, the given order stays."""
    for n_push, inits in ((0, None), (3, None), (0, np.ones((7, 4)))):
        queue = Queue(np.zeros(7), np.full(7, n_push, np.int32), devices=1, refill=2, inits=inits)
        _, order = simulate(queue, np.arange(7, 0, -1), slots=2, block=1)
        assert order == list(range(7))


def test_before_any_result_smaller_forces_first_ties_in_given_order():
    forces = np.array([30.0, -5.0, 10.0, 5.0, 0.0, 10.0])
    queue = Queue(forces, np.full(6, 10, np.int32), devices=1, refill=6)
    cells, f, *_ = queue.offer()
    assert cells.tolist() == [4, 1, 3, 2, 5, 0]
    assert np.array_equal(f, forces[cells])


def test_cells_near_long_finished_cells_go_first():
    forces = np.array([1.0, 2.0, 3.0, 100.0, 101.0, 102.0])
    n_push = np.full(6, 50, np.int32)
    queue = Queue(forces, n_push, devices=1, refill=6)
    queue.pending = np.array([1, 2, 4, 5])  # cells 0 and 3 took slots
    queue.finished(np.array([0, 3]), np.array([20, 900]))
    cells, *_ = queue.offer()
    assert cells[:4].tolist() == [4, 5, 1, 2]


def test_a_cell_still_running_counts_as_long_as_it_has_run():
    forces = np.array([1.0, 2.0, 3.0, 100.0, 101.0, 102.0])
    n_push = np.full(6, 50, np.int32)
    queue = Queue(forces, n_push, devices=1, refill=6, block=100)
    queue.pending = np.array([1, 2, 4, 5])
    queue.taken_at[[0, 3]] = 0
    queue.calls = 5  # cell 3 has run 4 whole calls or more (400 periods), cell 0 finished
    queue.finished(np.array([0]), np.array([20]))
    cells, *_ = queue.offer()
    assert cells[:4].tolist() == [4, 5, 1, 2]


def test_a_cell_beside_a_long_ridge_goes_before_cells_in_short_country():
    """Known cells on a line of forces, one push: short falls with a thin ridge of long
    recoveries at 40-42 N. A queued cell at 44.5 N has a short nearest neighbour (44 N) but long
    ones within the 16 nearest: it goes before the cells among short ones only (with the nearest
    neighbour alone it would rank with them)."""
    known = np.arange(0.0, 300.0, 1.0)  # 300 cells known: the longest of 16 neighbours
    length = np.where((known >= 40) & (known <= 42), 800, 30)
    queued = np.array([150.5, 44.5, 250.5])
    forces = np.concatenate([known, queued])
    queue = Queue(forces, np.full(forces.size, 50, np.int32), devices=1, refill=3)
    queue.pending = np.arange(known.size, forces.size)
    queue.finished(np.arange(known.size), length)
    cells, *_ = queue.offer()
    assert cells[0] == known.size + 1  # 44.5 N first, then the others in their given order
    assert cells.tolist() == [known.size + 1, known.size, known.size + 2]


def test_running_gives_a_cell_in_a_slot_the_periods_it_has_run():
    """A cell told to have run 700 periods in its slot (``running``) counts as at least that
    long before the calls it has been in say so (one call of 100 periods here)."""
    forces = np.array([1.0, 2.0, 3.0, 100.0, 101.0, 102.0])
    queue = Queue(forces, np.full(6, 50, np.int32), devices=1, refill=6, block=100)
    queue.pending = np.array([1, 2, 4, 5])
    queue.taken_at[[0, 3]] = 0
    queue.calls = 1  # cell 3 took a slot in the call just run: no whole call yet
    queue.running(np.array([3, -1]), np.array([700, 0]))  # vacant slots are ignored
    queue.finished(np.array([0]), np.array([20]))
    cells, *_ = queue.offer()
    assert cells[:4].tolist() == [4, 5, 1, 2]


def test_the_order_shortens_the_schedule():
    """On a bench-like workload the queue's schedule is within 10 % of the longest-first
    schedule that knows every length, and shorter than the given order's by 15 % or more. The
    simulation is integer arithmetic, the same on every machine: 1,887 periods against 1,851
    for the all-knowing order and 2,720 for the given one (whose never-certified tiny pushes
    that arrive late run on alone); with the ordering switched off the first bound fails.)"""
    forces, n_push, length = workload(1024, 7)
    D, R, S, block = 2, 128, 32, 100
    ours, _ = simulate(Queue(forces, n_push, D, R, block=block), length, S, block)

    class Given(Queue):
        def _order(self):
            return None

    given_q = Given(forces, n_push, D, R, block=block)
    given_q.pending = np.arange(forces.size)
    given, _ = simulate(given_q, length, S, block)

    oracle_q = Given(forces, n_push, D, R, block=block)
    oracle_q.pending = np.argsort(-length, kind="stable")
    oracle, _ = simulate(oracle_q, length, S, block)
    assert oracle <= ours <= 1.1 * oracle, (oracle, ours, given)
    assert ours <= 0.85 * given, (ours, given)


def test_ordering_starts_no_thread(monkeypatch):
    """The queue orders its cells in the calling thread: scipy's query workers are Python
    threads, which a signal's exception in the main thread abandoned mid-query while its
    unwinding freed their arrays (a segfault after SIGTERM in a 1,001,000-cell sweep, 4 of 8
    runs; docs/reliability.md). Fails with ``workers=-1`` on any machine of two cores or more."""
    import threading

    def refused(self):
        raise AssertionError(f"a thread was started: {self.name}")

    monkeypatch.setattr(threading.Thread, "start", refused)
    rng = np.random.default_rng(0)
    forces = rng.uniform(0, 150, 4000)
    queue = Queue(forces, np.full(forces.size, 50, np.int32), devices=1, refill=8)
    queue.pending = np.arange(200, forces.size)  # the first 200 took slots
    queue.finished(np.arange(200), rng.integers(10, 900, 200))
    cells, *_ = queue.offer()
    assert (cells >= 200).all()
