"""Region sweeps on a Dask cluster: the driver keeps the store, the workers compute chunks.

``run_sweep(..., cluster=SPEC)`` (``mjx-balance sweep --cluster SPEC``; docs/cluster.md) runs
the chunks of a region sweep as Dask tasks, one task per chunk:

- SPEC ``local:N`` starts a ``distributed.LocalCluster`` of N worker processes with one thread
  each (a workstation, the tests); any other text is the address of a running scheduler
  (``tcp://host:8786``) or its scheduler file (``*.json``, ``dask scheduler --scheduler-file``):
  a SLURM, PBS or SGE allocation through dask-jobqueue, GPU boxes with one worker per GPU; a
  ``distributed.Client`` is used as it is.
- The driver owns the output folder: the manifest, the chunk plan, the resume check and the
  merge stay in ``region.py``; a worker computes one chunk's summary rows and returns them,
  and the driver writes each returned chunk once, atomically, through the store's code
  (:meth:`ClusterBatch.compute_chunks`). No shared filesystem is needed.
- A worker builds the chunk's runner once per configuration and engine settings and keeps it
  (``_RUNNERS``, a module dictionary of the worker process): the compiled program is reused
  by every later chunk, and loaded from the persistent compilation cache (``runtime/cache.py``)
  when the worker's cache folder holds it.
- A chunk's bytes do not depend on where it ran: every worker runs the slot count the folder's
  manifest records (asked of one worker for a new folder, so GPU workers get their own
  default), with the driver's ``jax_enable_x64`` setting, and the engine's results do not
  depend on the schedule (docs/engine.md). Workers must agree with the driver on the package,
  JAX, jaxlib, MuJoCo and Python versions and on the deterministic XLA flags, and with each
  other on the device kind; a worker that does not is refused, when connecting
  (:func:`check_workers`) and again by every task (a worker that joins later).
- Faults are Dask's own: a task on a worker that dies is run again on another worker (tasks
  are pure, each with an explicit key derived from the configuration, the engine settings and
  its cells); the driver writes a chunk only once. A killed driver leaves the written chunks,
  and the same command resumes from them (``region.py``).

The robustness table (``run_table(..., cluster=SPEC)``, ``mjx-balance table --cluster SPEC``)
uses the same connection, checks and runners: the driver keeps the bisection and the table's
store (``store.folder.TableCells``), and each round's batch calls run as tasks (each call split
into about one task per worker, :meth:`ClusterBatch.evaluate_calls`, worker side
:func:`compute_cells`) whose rows come back, reassembled in order, before the driver keeps
them: the same part files, runs and table as a local table.

Dask is an optional extra (``pip install "mjx_balance[cluster]"``); this module imports it only
when a cluster is asked for.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import platform
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

import numpy as np
import pandas as pd

from ..model.params import Config, ParameterError
from .batch import LazyBatch, chunk_frames, evaluate, streams
from .chunks import chunk_slices
from ..store.folder import config_dict, same_values
from ..store.provenance import versions
from ..runtime import xla as _xla
from ..runtime import cache
from ..runtime.fingerprint import numerics

EXTRA = 'pip install "mjx_balance[cluster]"'
LOCAL = "local:"
# What the driver and every worker must agree on (store.provenance.versions() names, plus the XLA
# flags).
CHECKED = (
    "package",
    "jax",
    "jaxlib",
    "mujoco",
    "mujoco_mjx",
    "python",
    "deterministic_xla",
    "xla_flags",
    "matmul_precision",
)
WAIT_FOR_WORKERS_S = 300.0  # how long a scheduler may take to get its first worker


class ClusterError(ParameterError):
    """The cluster cannot run this sweep (no Dask, no workers, workers of other versions)."""


# ---------------------------------------------------------------------------------------------
# What a process runs: checked on the driver and on every worker.


def local_facts() -> dict[str, Any]:
    """The versions and settings that decide a chunk's bytes, in this process."""
    found = versions()
    facts: dict[str, Any] = {name: found.get(name) for name in CHECKED[:5]}
    facts["python"] = ".".join(platform.python_version_tuple()[:2])
    flags = os.environ.get("XLA_FLAGS", "")
    facts["deterministic_xla"] = all(f in flags for f in _xla.DETERMINISTIC_XLA_FLAGS)
    # the numerics that change results (runtime/fingerprint.py; x64 travels with each task)
    found = numerics()
    facts["xla_flags"], facts["matmul_precision"] = found["xla_flags"], found["matmul_precision"]
    return facts


def worker_device() -> tuple[str, str]:
    """(platform, device kind) of this process's first JAX device (starts JAX)."""
    import jax

    device = jax.devices()[0]
    return device.platform, device.device_kind


def differences(expected: dict[str, Any], got: dict[str, Any]) -> list[str]:
    """``name got (driver: expected)`` for each checked fact that differs."""
    names = {"package": "mjx_balance", "deterministic_xla": "deterministic XLA flags"}
    return [
        f"{names.get(k, k)} {got.get(k)} (driver: {expected.get(k)})"
        for k in CHECKED
        if got.get(k) != expected.get(k)
    ]


def check_workers(client: Any, expected: dict[str, Any] | None = None) -> dict[str, Any]:
    """Refuse (ClusterError) a cluster whose workers run other versions than ``expected``
    (this process's, :func:`local_facts`); returns {worker address: facts}."""
    expected = expected or local_facts()
    try:
        facts = client.run(local_facts)
    except Exception as exc:
        raise ClusterError(
            f"the cluster's workers cannot run mjx_balance ({type(exc).__name__}: "
            f"{exc}); install the same mjx_balance, JAX and MuJoCo on every "
            "worker"
        ) from None
    problems = [
        f"worker {address}: {', '.join(differences(expected, got))}"
        for address, got in sorted(facts.items())
        if differences(expected, got)
    ]
    if problems:
        raise ClusterError(
            "refusing the cluster: a chunk's results must not depend on where it ran, and "
            f"{len(problems)} of {len(facts)} worker(s) run other versions than this process: "
            + "; ".join(problems)
            + ". Install the same versions on every worker (and start "
            "them with the same environment), then run the same command again"
        )
    return facts


# ---------------------------------------------------------------------------------------------
# The worker's side: one task per chunk.


@dataclass(frozen=True)
class ChunkSpec:
    """What a worker needs to compute any chunk of one sweep (sent with every task)."""

    config: Config
    slots: int | None
    early_stop: bool
    chunk_size: int
    x64: bool
    facts: dict[str, Any] = field(default_factory=dict)  # the driver's (local_facts)
    device: tuple[str, str] | None = None  # the sweep's (platform, device kind)
    batch: Any = None  # a stand-in batch function (tests), else None: the engine
    physics: str = "auto"  # the physics path (auto: resolved on the worker, then recorded)

    def runner_key(self, slots: int | None = None) -> str:
        settings = {
            "config": config_dict(self.config),
            "x64": self.x64,
            "slots": self.slots if slots is None else slots,
            "early_stop": self.early_stop,
            "physics": self.physics,
        }
        return json.dumps(settings, sort_keys=True, default=str)


# This worker process's runners: one per configuration and engine settings, built (and
# compiled, on its first chunk) once and kept for every later chunk.
_RUNNERS: dict[str, Any] = {}
_FACTS: dict[str, Any] = {}


def _x64(spec: ChunkSpec):
    import jax

    return jax.enable_x64(spec.x64)


def _runner(spec: ChunkSpec) -> Any:
    if spec.batch is not None:
        return spec.batch
    key = spec.runner_key()
    run = _RUNNERS.get(key)
    if run is None:
        cache.enable()  # the persistent compilation cache, where the worker has one
        run = _RUNNERS[key] = LazyBatch(
            spec.config, slots=spec.slots, early_stop=spec.early_stop, physics=spec.physics
        )
    return run


def _check_here(spec: ChunkSpec) -> None:
    """Refuse to compute on a worker that differs from the driver (or from the sweep's device)."""
    if not _FACTS:
        _FACTS.update(local_facts())
    problems = differences(spec.facts, _FACTS) if spec.facts else []
    if spec.device is not None and spec.batch is None:
        here = worker_device()
        if tuple(here) != tuple(spec.device):
            problems.append(
                f"device {here[0]} {here[1]} (the sweep's: {spec.device[0]} {spec.device[1]})"
            )
    if problems:
        raise ClusterError(
            f"worker on {platform.node()} (PID {os.getpid()}) refused: " + ", ".join(problems)
        )


def worker_engine_record(spec: ChunkSpec) -> dict[str, Any] | None:
    """The engine record (slots per device, early stopping) of this worker's runner for
    ``spec``; the runner is kept, under the resolved slot count too."""
    _check_here(spec)
    with _x64(spec):
        run = _runner(spec)
        record = run.engine_record()
    if record is not None:
        resolved = dataclasses.replace(spec, physics=record.get("physics", spec.physics))
        _RUNNERS.setdefault(resolved.runner_key(record["slots"]), run)
    return record


def compute_chunk(
    spec: ChunkSpec, index: int, forces: np.ndarray, durations: np.ndarray
) -> pd.DataFrame:
    """The summary rows of one chunk (forces[i], durations[i]), as the local sweep writes them."""
    _check_here(spec)
    run = _runner(spec)
    if spec.batch is not None:
        context = _NoContext()
    else:
        context = _x64(spec)
    with context:
        if streams(run):
            [(_, frame)] = list(
                chunk_frames(run, [slice(0, forces.size)], forces, durations, spec.config)
            )
        else:
            frame = evaluate(run, forces, durations, spec.config, pad_to=spec.chunk_size)
    return frame


def compute_cells(
    spec: ChunkSpec, forces: np.ndarray, durations: np.ndarray, pad_to: int | None
) -> pd.DataFrame:
    """The summary rows of the scenarios (forces[i], durations[i]), as the local table's batch
    call gets them (``batch.evaluate``, padded to ``pad_to`` where the function wants it)."""
    _check_here(spec)
    run = _runner(spec)
    with _NoContext() if spec.batch is not None else _x64(spec):
        return evaluate(run, forces, durations, spec.config, pad_to=pad_to)


class _NoContext:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: Any) -> None:
        return None


# ---------------------------------------------------------------------------------------------
# The driver's side.


def parse_cluster(spec: str) -> tuple[str, Any]:
    """``("local", N)`` for ``local:N`` (N >= 1), else ``("address", spec)``: a scheduler's
    address (``tcp://host:8786``) or scheduler file (``dask scheduler --scheduler-file``)."""
    text = str(spec).strip()
    if text.startswith(LOCAL):
        count = text[len(LOCAL) :]
        if not count.isdigit() or int(count) < 1:
            raise ClusterError(f"--cluster {text}: local:N needs a number of workers N >= 1")
        return "local", int(count)
    if not text:
        raise ClusterError(
            "--cluster: empty; give local:N or a scheduler address (tcp://host:8786)"
        )
    if text.endswith(".json"):
        if not os.path.isfile(text):
            raise ClusterError(f"--cluster {text}: no such scheduler file")
        return "address", text
    port = ADDRESS.match(text)
    if port is None or not 0 < int(port.group(1)) < 65536:
        raise ClusterError(
            f"--cluster {text}: not local:N, a scheduler address with its port "
            "(tcp://host:8786) or a scheduler file (.json)"
        )
    return "address", text


# A scheduler's address: [protocol://]host:port (host a name, an IPv4 or a bracketed IPv6).
ADDRESS = re.compile(r"^(?:[a-z]+://)?(?:\[[0-9a-fA-F:.]+\]|[^\s:/\[\]]+):(\d{1,5})/?$")


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ClusterError(
            f"--cluster needs Dask distributed, which is not installed: {EXTRA}"
        ) from None
    return distributed


def connect(spec: Any, say: Callable[[str], None]) -> tuple[Any, Any]:
    """(client, local cluster or None) for a cluster spec, its workers checked."""
    distributed = _distributed()
    quiet = logging.getLogger("distributed")
    if quiet.getEffectiveLevel() < logging.WARNING:  # its INFO lines would drown the sweep's
        quiet.setLevel(logging.WARNING)
    cluster = None
    if isinstance(spec, distributed.Client):
        client = spec
    else:
        kind, value = parse_cluster(spec)
        if kind == "local":
            say(f"starting a local Dask cluster of {value} worker process(es) ...")
            cluster = distributed.LocalCluster(
                n_workers=value, threads_per_worker=1, processes=True, dashboard_address=None
            )
            client = distributed.Client(cluster)
        else:
            # a scheduler file (dask scheduler --scheduler-file F) or an address
            where = (
                {"scheduler_file": value}
                if value.endswith(".json") and os.path.isfile(value)
                else {"address": value}
            )
            try:
                client = distributed.Client(**where, timeout="30s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise ClusterError(
                    f"--cluster {value}: cannot reach the scheduler ({exc})"
                ) from None
    try:
        try:
            client.wait_for_workers(1, timeout=WAIT_FOR_WORKERS_S)
        except TimeoutError:
            raise ClusterError(
                f"the cluster ({client.scheduler.address}) has no worker after "
                f"{WAIT_FOR_WORKERS_S:.0f} s"
            ) from None
        facts = check_workers(client)
    except BaseException:
        close(client, cluster, owned=not isinstance(spec, distributed.Client))
        raise
    say(f"cluster {client.scheduler.address}: {len(facts)} worker(s), versions checked")
    return client, cluster


def close(client: Any, cluster: Any, owned: bool) -> None:
    """Close what :func:`connect` opened (the client only if this run ``owned`` it)."""
    if owned:
        client.close()
    if cluster is not None:
        cluster.close()


def _token(parts: dict[str, Any]) -> str:
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


class ClusterBatch:
    """The batch function of a sweep on a Dask cluster, on the driver (``run_sweep``'s
    ``cluster``). It connects when first needed (a finished sweep starts nothing), stands in
    for the engine's settings (``slots``, ``early_stop``, ``engine_record``, ``use_engine``:
    the manifest's record, see ``batch.resume_engine``) and computes chunks on the workers
    (:meth:`compute_chunks`; a table's batch calls: :meth:`evaluate_calls`). Use it as a
    context manager: it closes what it started."""

    def __init__(
        self, cluster: Any, inner: Any, config: Config, say: Callable[[str], None] | None = print
    ):
        self.cluster = cluster
        self.inner = inner
        self.config = config
        self.say = say or (lambda _msg: None)
        # the engine on the workers (the default batch function), or a stand-in shipped to them
        self.engine = type(inner) is LazyBatch
        self.slots = getattr(inner, "slots", None)
        self.early_stop = getattr(inner, "early_stop", True)
        self.asked_physics = getattr(inner, "asked_physics", "auto")
        self.physics = self.asked_physics  # "auto" until a worker's record resolves it
        self.device: tuple[str, str] | None = None
        self._client = None
        self._local = None
        self._facts: dict[str, Any] = {}

    # -- connection ---------------------------------------------------------------------
    def __enter__(self) -> "ClusterBatch":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        if self._client is not None:
            distributed = _distributed()
            close(self._client, self._local, owned=not isinstance(self.cluster, distributed.Client))
            self._client = self._local = None

    @property
    def client(self) -> Any:
        if self._client is None:
            self._client, self._local = connect(self.cluster, self.say)
            self._facts = local_facts()
        return self._client

    def _spec(self, chunk_size: int = 0) -> ChunkSpec:
        import sys

        x64 = False
        if "jax" in sys.modules:
            import jax

            x64 = bool(jax.config.jax_enable_x64)  # type: ignore[attr-defined]  # jax.config's flags are set at run time
        return ChunkSpec(
            self.config,
            self.slots,
            bool(self.early_stop),
            int(chunk_size),
            x64,
            facts=dict(self._facts),
            device=self.device,
            batch=None if self.engine else self.inner,
            physics=self.physics,
        )

    # -- the engine's settings (batch.resume_engine, region._region_record) ------------------
    def use_engine(self, slots: int | None, early_stop: bool, physics: str | None = None) -> None:
        self.slots, self.early_stop = slots, early_stop
        if physics is not None:
            self.physics = physics

    def engine_record(self) -> dict[str, Any] | None:
        """The engine record of a new folder, from one worker (its default slot count is the
        one of its device, not of the driver's)."""
        if not self.engine:
            record = getattr(self.inner, "engine_record", None)
            return record() if record is not None else None
        client = self.client
        record = client.submit(worker_engine_record, self._spec(), pure=False).result()
        if record is not None:
            self.slots = int(record["slots"])
            self.physics = record.get("physics", self.physics)
        return record

    def prepare(self, batch: int, say: Callable[[str], None] | None = print) -> None:
        """Connect and check the workers; fix the sweep's device (every worker's must match)."""
        client = self.client
        if self.engine:
            devices = client.run(worker_device)
            kinds = sorted({tuple(d) for d in devices.values()})
            if len(kinds) > 1:
                raise ClusterError(
                    "refusing the cluster: its workers run on different devices ("
                    + ", ".join(f"{p} {k}" for p, k in kinds)
                    + "), on which a chunk's last "
                    "bits differ; use workers of one kind"
                )
            self.device = kinds[0]

    # -- the work -------------------------------------------------------------------------
    def compute_chunks(
        self,
        slices: list[slice],
        todo: list[int],
        cell_f: np.ndarray,
        cell_d: np.ndarray,
        chunk_size: int,
        write: Callable[[int, pd.DataFrame], None],
        bar: Any,
    ) -> None:
        """One task per chunk of ``todo``; each returned chunk is checked and written once by
        ``write(index, frame)`` (on the driver), as it arrives."""
        distributed = _distributed()
        client = self.client
        spec = self._spec(chunk_size)
        if self.engine and spec.slots is None:
            raise RuntimeError("the engine's slot count is not set (no engine record)")
        grid = hashlib.sha1(cell_f.tobytes() + cell_d.tobytes()).hexdigest()
        token = _token(
            {
                "runner": spec.runner_key(),
                "chunk": chunk_size,
                "grid": grid,
                "facts": spec.facts,
                "device": spec.device,
                "batch": None if self.engine else _tokenize(self.inner),
            }
        )
        futures = {}
        for index in todo:
            cells = slices[index]
            future = client.submit(
                compute_chunk,
                spec,
                index,
                cell_f[cells],
                cell_d[cells],
                key=f"mjx_balance-chunk-{token}-{index:05d}",
                pure=True,
            )
            futures[future] = index
        written: set[int] = set()
        try:
            for future in distributed.as_completed(list(futures)):
                index = futures[future]
                try:
                    frame = future.result()
                except distributed.KilledWorker as exc:
                    raise RuntimeError(
                        f"chunk {index} was running on every worker that died ({exc}); the "
                        "chunks written so far are kept: run the same command again to resume"
                    ) from None
                future.release()
                if index in written:
                    continue
                cells = slices[index]
                if not (
                    len(frame) == cells.stop - cells.start
                    and same_values(frame["force"], cell_f[cells])
                    and same_values(frame["duration"], cell_d[cells])
                ):
                    raise RuntimeError(f"chunk {index} came back with other cells than asked")
                write(index, frame)
                written.add(index)
                bar.update(cells.stop - cells.start)
        finally:
            left = [f for f, i in futures.items() if i not in written]
            if left:
                client.cancel(left)

    def evaluate_calls(
        self, calls: list[tuple[np.ndarray, np.ndarray]], pad_to: int | None
    ) -> Iterator[pd.DataFrame]:
        """The summary rows of each batch call (forces, durations) of a table round, in order,
        as ``batch.evaluate(..., pad_to=pad_to)`` returns them here: every call is split into
        tasks of at least the engine's slots (so that all the workers share a round), all the
        round's tasks are submitted at once, and each call's rows are yielded, reassembled in
        order, as soon as it and every call before it are done. The engine's rows do not
        depend on how a call is split (docs/engine.md); a stand-in batch function gets every
        task padded to the task size. A task on a worker that dies is run again by Dask."""
        distributed = _distributed()
        client = self.client
        spec = self._spec(pad_to or 0)
        if self.engine and spec.slots is None:
            raise RuntimeError("the engine's slot count is not set (no engine record)")
        workers = max(1, len(client.nthreads()))
        smallest = int(spec.slots) if self.engine and spec.slots is not None else 1
        base = {
            "runner": spec.runner_key(),
            "facts": spec.facts,
            "device": spec.device,
            "batch": None if self.engine else _tokenize(self.inner),
        }
        tasks: list[list[tuple[Any, slice]]] = []
        for forces, durations in calls:
            n = int(forces.size)
            size = max(smallest, -(-n // workers)) if n else 1
            pad = (size if pad_to else None) if size < n else pad_to
            mine = []
            for cells in chunk_slices(n, size) if n else []:
                f, d = forces[cells], durations[cells]
                key = "mjx_balance-cells-" + _token(
                    {
                        **base,
                        "pad": pad,
                        "cells": hashlib.sha1(f.tobytes() + d.tobytes()).hexdigest(),
                    }
                )
                mine.append(
                    (client.submit(compute_cells, spec, f, d, pad, key=key, pure=True), cells)
                )
            tasks.append(mine)
        futures = [future for mine in tasks for future, _ in mine]
        try:
            for (forces, durations), mine in zip(calls, tasks):
                parts = []
                for future, cells in mine:
                    try:
                        frame = future.result()
                    except distributed.KilledWorker as exc:
                        raise RuntimeError(
                            f"a table task was running on every worker that died ({exc}); the "
                            "scenarios kept so far stay: run the same command again to resume"
                        ) from None
                    future.release()
                    if not (
                        len(frame) == cells.stop - cells.start
                        and same_values(frame["force"], forces[cells])
                        and same_values(frame["duration"], durations[cells])
                    ):
                        raise RuntimeError("a table task came back with other cells than asked")
                    parts.append(frame)
                if not parts:
                    yield evaluate(self.inner, forces, durations, self.config)  # no rows
                else:
                    yield parts[0] if len(parts) == 1 else pd.concat(parts, ignore_index=True)
        finally:
            left = [f for f in futures if f.status == "pending"]
            if left:
                client.cancel(left)


def _tokenize(obj: Any) -> str:
    try:
        from dask.base import tokenize

        return tokenize(obj)
    except Exception:
        return f"{id(obj)}-{os.getpid()}"
