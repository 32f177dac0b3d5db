"""Batch functions: how a sweep evaluates scenarios.

A *batch function* ``run_batch(forces, durations)`` takes two equal-length float arrays and
returns one summary row per scenario, in order (a DataFrame with outcome strings or a dict of
columns with integer outcome codes). By default it is ``rollout.BatchRunner(config).run_frame``
(:func:`default_batch`, built lazily by :class:`LazyBatch`); every sweep function takes it as
an argument, so the bookkeeping (chunking, resume, bisection) can be tested with a cheap
stand-in.
"""

from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np
import pandas as pd

from ..measures.outcomes import SUMMARY_COLUMNS, summary_frame
from ..model.params import Config, ParameterError
from .chunks import chunk_slices
from ..rollout import BatchRunner
from ..rollout.cpath import PATHS
from ..rollout.cpath import resolve
from ..reference.loop import simulate_scenario
from ..store.provenance import note_physics

RunBatch = Callable[[np.ndarray, np.ndarray], "pd.DataFrame | dict[str, np.ndarray]"]


def default_batch(config: Config, **engine: Any) -> RunBatch:
    """The batched rollout for this configuration on the continuous-batching engine (compiled
    on first call); ``engine``: ``slots``, ``early_stop``, ``physics`` ("mjx" or "c"; see
    ``rollout.BatchRunner``)."""
    return BatchRunner(config, **engine).run_frame


class LazyBatch:
    """The default batch function, built on its first call (a finished sweep builds nothing).

    slots: per device (None: the engine's default); early_stop: stop certified recoveries
    (False: ``--full-length``); physics: "auto", "mjx" or "c" (``rollout.cpath.resolve``). A
    sweep folder records all three and resumes with them.
    """

    queue = "each"  # its cells run with this body alone (runs.population: "one")
    # whether its configuration was checked as runs.folders.check_batched checks it before
    # its cells ran (runs.population's served maps: built through checked_runner)
    checked = False

    def __init__(
        self,
        config: Config,
        *,
        slots: int | None = None,
        early_stop: bool = True,
        physics: str = "auto",
    ):
        if physics not in PATHS:
            raise ValueError(f"physics must be one of {', '.join(PATHS)}, got {physics!r}")
        self.config = config
        self.slots = slots
        self.early_stop = early_stop
        self.asked_physics = physics
        self._physics: str | None = None if physics == "auto" else physics
        self._run: RunBatch | None = None

    @property
    def physics(self) -> str:
        """The physics path that runs ("mjx" or "c"; "auto" resolved on first use)."""
        if self._physics is None:
            self._physics = resolve(self.asked_physics, self.config)
        return self._physics

    def use_engine(self, slots: int | None, early_stop: bool, physics: str | None = None) -> None:
        """Run with these engine settings (rebuilt if it was built with others)."""
        runner = getattr(self._run, "__self__", None)
        if runner is not None and (
            early_stop != self.early_stop
            or (slots is not None and slots != runner.engine.slots)
            or (physics is not None and physics != runner.physics)
        ):
            self._run = None
        self.slots, self.early_stop = slots, early_stop
        if physics is not None:
            self._physics = physics

    def _built(self) -> RunBatch:
        if self._run is None:
            options = (
                {}
                if self.slots is None and self.early_stop
                else {"slots": self.slots, "early_stop": self.early_stop}
            )
            self._run = default_batch(self.config, physics=self.physics, **options)

        note_physics("mujoco" if self.physics == "c" else "mjx")
        return self._run

    @property
    def runner(self):
        """The BatchRunner behind the batch function (built now if needed), or None for a
        stand-in batch function."""
        return getattr(self._built(), "__self__", None)

    @property
    def wants_padding(self) -> bool:
        """The engine runs a fixed set of slots: padding a call would only add work."""
        return not self.can_stream()

    def can_stream(self) -> bool:
        """Whether :meth:`stream` works: the engine of a runner without trajectories."""
        runner = self.runner
        return runner is not None and hasattr(runner, "stream") and not runner.trajectories

    def engine_record(self) -> dict[str, Any] | None:
        """What a sweep folder records about the engine (results depend on it); None for a
        stand-in."""
        if not self.can_stream():
            return None
        return {
            "slots": int(self.runner.engine.slots),
            "early_stop": bool(self.early_stop),
            "physics": self.physics,
        }

    def __call__(self, forces: np.ndarray, durations: np.ndarray):
        return self._built()(forces, durations)

    def stream(self, forces: np.ndarray, durations: np.ndarray):
        """(indices, summary columns) as scenarios are decided (``BatchRunner.stream``)."""
        return self.runner.stream(forces, durations)

    def prepare(self, batch: int, say: Callable[[str], None] | None = print) -> None:
        """Build the rollout and compile it for ``batch`` scenarios now (before a progress bar
        starts, so that its rate and time left are those of the runs)."""
        say = say or (lambda _msg: None)
        start = time.perf_counter()
        if self._run is None:
            say(
                f"building the rollout ({'MuJoCo C' if self.physics == 'c' else 'MJX'} physics) ..."
            )
        runner = self.runner
        if runner is not None and hasattr(runner, "prepare"):  # rollout.BatchRunner
            if not runner.is_prepared():
                say("compiling the rollout ...")
            runner.prepare()
        seconds = time.perf_counter() - start
        if seconds > 1:
            say(f"rollout ready ({seconds:.0f} s)")


def resume_engine(
    run_batch: Any, recorded: dict | None, path: Any, say: Callable[[str], None]
) -> None:
    """Resume with the engine settings the folder was started with (results depend on the slot
    count's compiled program, on early stopping and on the physics path). A folder from before
    they were recorded (lock-step batches run to t_end) resumes with what is asked; one from
    before the physics path was recorded ran MJX. Another physics path asked explicitly is
    refused: a map of mixed physics would be no map."""
    if recorded is None or not hasattr(run_batch, "engine_record"):
        return
    queue = recorded.get("queue", "each")
    if queue != getattr(run_batch, "queue", "each"):
        raise ParameterError(
            f"{path} was started with the cohort's queue {queue!r} (per-lane bodies: 'one'); "
            "its results differ by float rounding from the other queue's: resume it with "
            f"queue {queue!r}, or use another --out folder"
        )
    physics = recorded.get("physics", "mjx")
    asked_physics = getattr(run_batch, "asked_physics", "auto")
    if asked_physics not in ("auto", physics):
        raise ParameterError(
            f"{path} was started with {physics} physics; refusing to resume it with "
            f"--physics {asked_physics} (use --physics {physics} or auto, or another --out "
            "folder)"
        )
    asked = (run_batch.slots, run_batch.early_stop)
    wanted = (int(recorded["slots"]), bool(recorded["early_stop"]))
    if hasattr(run_batch, "use_engine"):
        try:
            run_batch.use_engine(*wanted, physics=physics)
        except TypeError:  # a stand-in without the physics path
            run_batch.use_engine(*wanted)
    else:
        run_batch.slots, run_batch.early_stop = wanted
    if asked[0] not in (None, wanted[0]) or asked[1] != wanted[1]:
        say(
            f"note: {path} was started with {run_batch.slots} slots per device and "
            f"{'early stopping' if run_batch.early_stop else '--full-length'}; keeping that"
        )


def evaluate(
    run_batch: RunBatch,
    forces: np.ndarray,
    durations: np.ndarray,
    config: Config,
    pad_to: int | None = None,
) -> pd.DataFrame:
    """Summary rows for the scenarios (forces[i], durations[i]), in order.

    The batch is padded to ``pad_to`` scenarios by repeating its last one (a batch of a fixed
    size is compiled once), and the padding is dropped. The result has the SUMMARY_COLUMNS in
    order (extra columns after them), outcome as strings, and force/duration equal to the values
    asked for (a float32 rollout hands them back rounded).
    """
    forces = np.asarray(forces, dtype=np.float64)
    durations = np.asarray(durations, dtype=np.float64)
    count = forces.size
    if count == 0:
        return pd.DataFrame(columns=SUMMARY_COLUMNS)
    if pad_to is not None and pad_to > count and getattr(run_batch, "wants_padding", True):
        extra = pad_to - count
        forces_in = np.concatenate([forces, np.full(extra, forces[-1])])
        durations_in = np.concatenate([durations, np.full(extra, durations[-1])])
    else:
        forces_in, durations_in = forces, durations
    frame = summary_frame(run_batch(forces_in, durations_in), config.controller.convention)
    if len(frame) != forces_in.size:
        raise RuntimeError(
            f"batch function returned {len(frame)} rows for {forces_in.size} scenarios"
        )
    frame = frame.iloc[:count].reset_index(drop=True)
    for column, asked in (("force", forces), ("duration", durations)):
        got = frame[column].to_numpy(dtype=np.float64)
        if not np.allclose(got, asked, rtol=1e-5, atol=1e-6):
            raise RuntimeError(f"batch function returned rows for other {column}s than asked")
        frame[column] = asked
    return frame


def evaluate_batches(
    run_batch: RunBatch,
    forces: np.ndarray,
    durations: np.ndarray,
    config: Config,
    batch: int | None,
) -> pd.DataFrame:
    """``evaluate`` in calls of exactly ``batch`` scenarios (padded), or one call if None."""
    if batch is None:
        return evaluate(run_batch, forces, durations, config)
    return pd.concat(
        [
            evaluate(run_batch, forces[s], durations[s], config, pad_to=batch)
            for s in chunk_slices(forces.size, batch)
        ],
        ignore_index=True,
    )


def streams(run_batch: Any) -> bool:
    """Whether the batch function runs a queue of cells (the engine), not fixed batches."""
    can = getattr(run_batch, "can_stream", None)
    return can() if can is not None else hasattr(run_batch, "stream")


def chunk_frames(
    run_batch: Any,
    slices: list[slice],
    cell_f: np.ndarray,
    cell_d: np.ndarray,
    config: Config,
    update: Callable[[int], None] | None = None,
):
    """Yield (k, summary rows of ``slices[k]``) as each chunk's last cell is decided, running
    every cell of the chunks through the engine's queue at once (a cluster's worker runs it on
    one chunk: the rows are the same, the engine's results do not depend on the schedule).
    ``update(n)``: n more cells decided."""
    positions = np.concatenate([np.arange(s.start, s.stop) for s in slices])
    owner = np.concatenate([np.full(s.stop - s.start, k) for k, s in enumerate(slices)])
    parts: dict[int, list[pd.DataFrame]] = {}
    left = {k: s.stop - s.start for k, s in enumerate(slices)}
    convention = config.controller.convention
    for index, columns in run_batch.stream(cell_f[positions], cell_d[positions]):
        # the summary columns only, as the fixed-batch path writes them (merge_chunks reads every
        # chunk with the first one's schema)
        frame = summary_frame(columns, convention, extra=False)
        frame["_cell"] = positions[index]
        chunk_of = owner[index]
        for k in np.unique(chunk_of):
            parts.setdefault(int(k), []).append(frame[chunk_of == k])
            left[int(k)] -= int((chunk_of == k).sum())
            if left[int(k)] == 0:
                rows = pd.concat(parts.pop(int(k))).sort_values("_cell")
                cells = slices[int(k)]
                rows = rows.drop(columns="_cell").reset_index(drop=True)
                # the exact grid values (a float32 rollout hands them back rounded)
                rows["force"], rows["duration"] = cell_f[cells], cell_d[cells]
                yield int(k), rows
        if update is not None:
            update(len(index))


class ReferenceBatch:
    """A batch function that runs the scalar reference loop scenario by scenario (results
    memoised, so padding and repeated cells cost nothing): the report's ``reference`` backend."""

    def __init__(self, config: Config):
        self.config = config
        self._done: dict[tuple[float, float], dict[str, Any]] = {}

    def __call__(self, forces: np.ndarray, durations: np.ndarray) -> pd.DataFrame:
        rows = []
        for f, d in zip(np.asarray(forces, float), np.asarray(durations, float)):
            key = (round(float(f), 9), round(float(d), 9))
            if key not in self._done:
                self._done[key] = simulate_scenario(self.config, key[0], key[1], record=False)[0]
            rows.append(self._done[key])
        return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
