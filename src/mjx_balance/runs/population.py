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
from ..rollout.engine import Engine, certificate
from ..rollout.kernel import Accumulators
from ..rollout.runner import push_steps, summarize
from ..store.files import REGION
from .batch import LazyBatch
from .folders import run_region
from .grid import Grid, grid_cells

# Cells in one queue at most (its bodies' grids together): an interrupted population loses at
# most one queue's work, and the host keeps one queue's summaries. At least QUEUE_CELLS, and
# QUEUE_REFILLS times the engine's slots (every device's), so that an accelerator's thousands
# of slots get a queue long enough to keep them busy (docs/studies.md, "Cohorts").
QUEUE_CELLS = 20_000
QUEUE_REFILLS = 40


class Population:
    """The runners and the shared engine of ``configs`` (bodies of one compiled program's
    shapes; the first one's engine settings), for the cells of ``forces`` x ``durations``.
    ``slots``, ``early_stop``: as a sweep's; ``runners``: the configurations' runners, when
    already built."""

    def __init__(
        self,
        configs: Sequence[Config],
        forces: np.ndarray,
        durations: np.ndarray,
        *,
        slots: int | None = None,
        early_stop: bool = True,
        runners: Sequence[Any] | None = None,
    ):
        self.configs = list(configs)
        self.runners = (
            list(runners)
            if runners is not None
            else [
                BatchRunner(c, slots=slots, early_stop=early_stop, physics="mjx")
                for c in self.configs
            ]
        )
        self.engine = Engine(
            self.runners[0], slots=slots, early_stop=early_stop, bodies=self.runners
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
    maps: Sequence[tuple[Path, Config]],
    forces: np.ndarray,
    durations: np.ndarray,
    *,
    slots: int | None = None,
    full_length: bool = False,
    say: Callable[[str], None] | None = None,
    update: Callable[[int], None] | None = None,
) -> None:
    """The region maps of ``maps`` ((folder, configuration) pairs; those whose folder holds its
    region.parquet are skipped) through one engine queue per compiled program: configurations
    of one program's shapes and static settings, with a certificate or all without, share a
    queue (``Engine``'s ``bodies``); each map is then written to its folder as its ``sweep``
    writes one (``runs.folders.run_region`` with a :class:`ServedBatch`). ``update(n)``: n
    more cells decided."""
    say = say or (lambda _msg: None)
    early_stop = not full_length
    groups: dict[Any, list[tuple[Path, Config, Any]]] = {}
    for folder, config in maps:
        if (Path(folder) / REGION).exists():
            continue
        runner = BatchRunner(config, slots=slots, early_stop=early_stop, physics="mjx")
        key = (
            runner._shape_key(1, runner.static._replace(n_control=None)),
            certificate(runner, early_stop) is None,
        )
        groups.setdefault(key, []).append((Path(folder), config, runner))
    cells = forces.size * durations.size
    for members in groups.values():
        people = Population(
            [c for _, c, _ in members],
            forces,
            durations,
            slots=slots,
            early_stop=early_stop,
            runners=[r for _, _, r in members],
        )
        t0 = time.perf_counter()
        say(
            f"preparing the engine ({len(members)} bodies, each lane its own; compiled on "
            "first use, or loaded from the cache) ..."
        )
        people.engine.block_fn()  # before the progress bar's first update
        if time.perf_counter() - t0 > 1:
            say(f"engine ready ({time.perf_counter() - t0:.0f} s)")
        lanes = people.engine.slots * people.engine.n_devices
        for part in queues(len(members), cells, max(QUEUE_CELLS, QUEUE_REFILLS * lanes)):
            say(f"{len(part)} maps ({len(part) * cells} cells) in one engine queue")
            columns = people.run(part, update=update)
            for i in part:
                folder, config, _ = members[i]
                run_region(
                    folder,
                    config,
                    Grid.of(forces, durations, config),
                    slots=slots,
                    full_length=full_length,
                    progress=False,
                    run_batch=people.batch(i, columns.pop(i)),
                )


def queues(count: int, cells: int, limit: int = QUEUE_CELLS) -> list[range]:
    """The bodies 0..count-1 split into consecutive queues of at most ``limit`` cells (at
    least one body each), of equal size but the last."""
    per = max(1, limit // max(1, cells))
    return [range(s, min(count, s + per)) for s in range(0, count, per)]


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
