"""Many bodies' region maps through one engine queue (a cohort's subjects, on the MJX path).

:class:`Population` builds one runner per body and one continuous-batching engine whose slots
each run their scenario's body (``rollout.engine.Engine``'s ``bodies``: the body, its QP and
its certificate are per-lane data, not compile keys). :meth:`Population.run` puts every grid
cell of the bodies asked for into that one queue, so the slots stay busy until the last body's
last cell instead of waiting at the end of each body's map, and returns each body's summary
columns. :class:`ServedBatch` then hands one body's columns to ``runs.folders.run_region`` as
its batch function, so each body's folder is written, resumed and recorded exactly as a
``sweep`` of that body writes it.

A body's bytes do not depend on the other bodies in its queue, their number or order: a lane's
computation does not depend on the other lanes or on its slot (``rollout/engine.py``,
"Schedule independence"), and the bodies are padded to at least two, so a body alone in a
queue runs the same per-lane program. A ``sweep`` of the body alone runs it as a shared body,
whose float rounding differs (docs/engine.md, "Per-lane bodies").
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..measures.outcomes import summary_frame
from ..model.params import Config, ParameterError
from ..rollout import BatchRunner
from ..rollout.engine import Engine, certificate, padded_size, slot_layout
from ..rollout.kernel import Accumulators
from ..rollout.runner import push_steps, summarize
from ..store.files import REGION
from .batch import LazyBatch
from .folders import checked_runner, run_region
from .grid import Grid, grid_cells

# Cells in one queue at most (its bodies' grids together): an interrupted population loses at
# most one queue's work, and the host keeps one queue's summaries. At least QUEUE_CELLS, and
# QUEUE_REFILLS times the engine's slots (every device's), so that an accelerator's thousands
# of slots get a queue long enough to keep them busy (docs/cohorts.md, "Cohorts").
QUEUE_CELLS = 20_000
QUEUE_REFILLS = 40
# Bodies in the first queue: each body's closed loop is built and checked when its queue
# starts (0.04-0.05 s a body on the 2-core CPU: BENCHMARKS.md, "A cohort's set-up"), so the
# first scenario waits for this many; each next queue holds twice the one before, up to the
# cell limit.
FIRST_QUEUE = 16
# Bodies in one queue at most: a queue's runners are built together (about 1.2 MB each) and
# its engine holds their arrays and certificates stacked (0.29 MB a body: 0.10 MB of model,
# QP and observer, 0.19 MB of certificate), every queue stacked to one length (one compiled
# program), so a cohort's memory stays flat in its subjects (BENCHMARKS.md, "A cohort's
# set-up and memory").
QUEUE_BODIES = 1024


class Population:
    """The runners and the shared engine of ``configs`` (bodies of one compiled program's
    shapes; the first one's engine settings), for the cells of ``forces`` x ``durations``.
    ``slots``, ``early_stop``: as a sweep's; ``runners``: the configurations' runners, when
    already built; ``stack``: the bodies' stacked length (``Engine``'s)."""

    def __init__(
        self,
        configs: Sequence[Config],
        forces: np.ndarray,
        durations: np.ndarray,
        *,
        slots: int | None = None,
        early_stop: bool = True,
        runners: Sequence[Any] | None = None,
        stack: int | None = None,
    ):
        self.configs = list(configs)
        built = (
            list(runners)
            if runners is not None
            else [
                BatchRunner(c, slots=slots, early_stop=early_stop, physics="mjx")
                for c in self.configs
            ]
        )
        # the engine keeps the bodies' stacked arrays and the first runner, not every runner
        # (about 1.2 MB a body: MuJoCo's and MJX's models, the QP's factors)
        self.engine = Engine(
            built[0], slots=slots, early_stop=early_stop, bodies=built, stack=stack
        )
        self.slots, self.early_stop = self.engine.slots, early_stop
        self.cell_f, self.cell_d = grid_cells(forces, durations)

    def run(
        self, which: Sequence[int], update: Callable[[int], None] | None = None
    ) -> dict[int, dict[str, np.ndarray]]:
        """Every grid cell of the bodies ``which`` (indices into ``configs``) through the one
        queue; each body's summary columns (``BatchRunner.stream``'s), in grid order.
        ``update(n)``: n more cells decided."""
        which = list(which)
        n = self.cell_f.size
        forces = np.tile(self.cell_f, len(which))
        steps = np.tile(push_steps(self.cell_d, self.configs[0].scenario.physics_dt), len(which))
        bodies = np.repeat(np.asarray(which, np.int32), n)
        raw = self.engine.run(forces, steps, bodies=bodies, update=update)
        out = {}
        for j, body in enumerate(which):
            part = {name: v[j * n : (j + 1) * n] for name, v in raw.items()}
            acc = Accumulators(*(part[name] for name in Accumulators._fields))  # type: ignore[arg-type]  # the record's host (numpy) copy
            out[body] = {
                "force": self.cell_f,
                "duration": self.cell_d,
                **summarize(acc, self.configs[body], self.cell_f, self.cell_d),
                "periods": part["periods"],
                "certified": part["certified"],
            }
        return out

    def batch(self, body: int, columns: dict[str, np.ndarray]) -> ServedBatch:
        """Body ``body``'s batch function, serving ``columns`` (:meth:`run`'s)."""
        return ServedBatch(
            self.configs[body], columns, slots=self.slots, early_stop=self.early_stop
        )


QUEUES = ("each", "one")


def check_queue(queue: Any, physics: Any = "auto", cluster: Any = None) -> str:
    """``queue`` checked: "each" (every map its own engine run) or "one" (the maps through one
    engine queue, :func:`run_maps`: the MJX path in this process, so not with physics "c" or a
    cluster). ParameterError (a ValueError) naming what it accepts."""
    if not isinstance(queue, str) or queue not in QUEUES:
        raise ParameterError(
            f"queue = {queue!r}: must be one of {', '.join(repr(q) for q in QUEUES)}"
        )
    if queue == "one" and (physics == "c" or cluster is not None):
        raise ParameterError(
            "queue = 'one' runs every map on the MJX path in this process: "
            "not with physics 'c' or a cluster"
        )
    return queue


def run_maps(
    maps: Sequence[tuple[Path, Config | Callable[[], Config]]],
    forces: np.ndarray,
    durations: np.ndarray,
    *,
    slots: int | None = None,
    full_length: bool = False,
    say: Callable[[str], None] | None = None,
    update: Callable[[int], None] | None = None,
    label: Callable[[Path], str] = str,
) -> None:
    """The region maps of ``maps`` ((folder, configuration) pairs, the configuration or a
    function giving it; those whose folder holds its region.parquet are skipped) through
    engine queues, each then written to its folder as its ``sweep`` writes one
    (``runs.folders.run_region`` with a :class:`ServedBatch`). ``update(n)``: n more cells
    decided.

    The maps go in order into queues (:func:`queues`: a first short one, then doubling up to
    the cell limit); a queue's bodies are built when it starts (``checked_runner``: each
    configuration checked as ``check_batched`` checks it; a refusal is a ParameterError
    naming ``label(folder)``), so the first scenario never waits for the last body's set-up
    and the host holds one queue's bodies at a time. In a queue, configurations of one
    program's shapes and static settings, with a certificate or all without, share an engine
    (``Engine``'s ``bodies``); every engine's bodies are stacked to one length, so each
    program compiles once for the whole run."""
    say = say or (lambda _msg: None)
    early_stop = not full_length
    todo = [i for i, (folder, _) in enumerate(maps) if not (Path(folder) / REGION).exists()]
    if not todo:
        return
    cells = forces.size * durations.size
    first = _built(maps[todo[0]], slots, early_stop, label)
    _, devices, per_device = slot_layout(first[2], slots)
    limit = max(QUEUE_CELLS, QUEUE_REFILLS * per_device * devices)
    parts = queues(len(todo), cells, limit)
    stack, prepared = padded_size(max(len(p) for p in parts)), set()
    for part in parts:
        groups = _groups(
            [first if k == 0 else _built(maps[todo[k]], slots, early_stop, label) for k in part],
            early_stop,
        )
        for key in list(groups):  # each queue's bodies released before the next are built
            members = groups.pop(key)
            people = Population(
                [c for _, c, _ in members],
                forces,
                durations,
                slots=slots,
                early_stop=early_stop,
                runners=[r for _, _, r in members],
                stack=stack,
            )
            if key not in prepared:  # its program: compiled, or loaded from the cache, once
                prepared.add(key)
                _prepare(people.engine, len(members), say)
            maps_of = [(folder, config) for folder, config, _ in members]
            del members  # the runners: the engine holds what it needs of them
            say(f"{len(maps_of)} maps ({len(maps_of) * cells} cells) in one engine queue")
            _run_queue(people, maps_of, forces, durations, slots, full_length, update)
            del people


def _groups(
    built: list[tuple[Path, Config, Any]], early_stop: bool
) -> dict[Any, list[tuple[Path, Config, Any]]]:
    """Built maps by compiled program: the runner's shapes and static settings, and whether
    it has a certificate (an engine's bodies share both)."""
    groups: dict[Any, list[tuple[Path, Config, Any]]] = {}
    for folder, config, runner in built:
        key = (
            runner._shape_key(1, runner.static._replace(n_control=None)),
            certificate(runner, early_stop) is None,
        )
        groups.setdefault(key, []).append((folder, config, runner))
    return groups


def _built(
    item: tuple[Path, Config | Callable[[], Config]],
    slots: int | None,
    early_stop: bool,
    label: Callable[[Path], str],
) -> tuple[Path, Config, Any]:
    """A map's folder, configuration and checked runner (``checked_runner``), a refusal named
    by ``label(folder)``."""
    folder, config = Path(item[0]), item[1]
    try:
        config = config if isinstance(config, Config) else config()
        runner = checked_runner(config, slots=slots, early_stop=early_stop, physics="mjx")
    except ParameterError as exc:
        raise ParameterError(f"{label(folder)}: {exc}") from None
    return folder, config, runner


def _prepare(engine: Engine, bodies: int, say: Callable[[str], None]) -> None:
    """``engine``'s program compiled (or loaded from the cache) before its queue's first
    progress update, with a line saying so."""
    t0 = time.perf_counter()
    say(
        f"preparing the engine ({bodies} bodies, each lane its own; compiled on first use, "
        "or loaded from the cache) ..."
    )
    engine.block_fn()
    if time.perf_counter() - t0 > 1:
        say(f"engine ready ({time.perf_counter() - t0:.0f} s)")


def _run_queue(
    people: Population,
    members: list[tuple[Path, Config]],
    forces: np.ndarray,
    durations: np.ndarray,
    slots: int | None,
    full_length: bool,
    update: Callable[[int], None] | None,
) -> None:
    """One queue's maps (``people``: bodies of one program) through its engine, then each
    written to its folder."""
    columns = people.run(range(len(members)), update=update)
    for i, (folder, config) in enumerate(members):
        run_region(
            folder,
            config,
            Grid.of(forces, durations, config),
            slots=slots,
            full_length=full_length,
            progress=False,
            run_batch=people.batch(i, columns.pop(i)),
        )


def queues(
    count: int,
    cells: int,
    limit: int = QUEUE_CELLS,
    first: int = FIRST_QUEUE,
    bodies: int = QUEUE_BODIES,
) -> list[range]:
    """The bodies 0..count-1 split into consecutive queues: at most ``limit`` cells and
    ``bodies`` bodies each (at least one body), the first of at most ``first`` bodies and
    each next one twice the one before, so that the first scenario waits for a few bodies'
    set-up only."""
    per = max(1, min(bodies, limit // max(1, cells)))
    size, start, out = max(1, min(first, per)), 0, []
    while start < count:
        out.append(range(start, min(count, start + size)))
        start += size
        size = min(per, 2 * size)
    return out


class ServedBatch(LazyBatch):
    """A body's batch function whose cells already ran in a :class:`Population`'s queue: it
    streams their summary columns to ``run_sweep`` as the engine would (a sweep folder records
    the same engine settings: the slots, early stopping, the MJX path)."""

    def __init__(
        self, config: Config, columns: dict[str, np.ndarray], *, slots: int, early_stop: bool
    ):
        super().__init__(config, slots=slots, early_stop=early_stop, physics="mjx")
        self.columns = columns
        self._row = {
            (float(f), float(d)): i
            for i, (f, d) in enumerate(zip(columns["force"], columns["duration"]))
        }

    @property
    def runner(self):
        return None

    def can_stream(self) -> bool:
        return True

    queue = "one"  # what a sweep folder records: its cells ran with per-lane bodies
    checked = True  # its cells ran from a runner built through checked_runner

    def engine_record(self) -> dict[str, Any]:
        assert self.slots is not None  # (given to __init__, an int)
        return {
            "slots": int(self.slots),
            "early_stop": bool(self.early_stop),
            "physics": "mjx",
            "queue": self.queue,
        }

    def use_engine(self, slots: int | None, early_stop: bool, physics: str | None = None) -> None:
        """A folder started with other engine settings cannot be served these results."""
        if (slots, early_stop, physics or "mjx") != (self.slots, self.early_stop, "mjx"):
            raise ValueError(
                f"this folder was started with {slots} slots, early stop "
                f"{early_stop}, {physics} physics; the population ran "
                f"{self.slots} slots, early stop {self.early_stop}, mjx"
            )

    def prepare(self, batch: int, say: Callable[[str], None] | None = print) -> None:
        pass

    def stream(self, forces: np.ndarray, durations: np.ndarray):
        rows = np.array(
            [self._row[(float(f), float(d))] for f, d in zip(forces, durations)], np.int64
        )
        yield np.arange(rows.size), {name: v[rows] for name, v in self.columns.items()}

    def __call__(self, forces: np.ndarray, durations: np.ndarray):
        _, columns = next(self.stream(forces, durations))
        return summary_frame(columns, self.config.controller.convention, extra=False)
