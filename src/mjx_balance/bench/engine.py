"""The engine's time per control period, split into its parts, on each physics path
(``mjx-balance bench engine``).

What runs. The cells of a force x duration grid (by default the default sweep's durations and
forces 0-155 N every 5 N: 256 cells of 12 s) go through the continuous-batching engine as
``sweep`` runs them: ``rollout.BatchRunner`` with the engine's defaults (slots per device, the
block of control periods, the refill buffer, certified early stop, every local device), all
cells through one queue (a sweep's chunks share one queue too: chunking only decides when a
chunk file is written). The runs are the engines' own ``stream`` with a probe
(:class:`Recorder`, ``rollout.engine.Probe``) that clocks each part of the loop and keeps what
the replay needs.

Three kinds of figures (``how`` in the table and the JSON):

- **in run**: clocked inside the timed runs (the mean over ``runs``): the host's work between
  the compiled calls: the queue and the results in Python, the transfers host -> device
  (``device_put``) and device -> host (``np.asarray`` / ``device_get``), and on the C path the
  MuJoCo C physics (``mujoco.rollout`` on its thread pool) and the decoding of its samples.
  The compiled calls themselves (dispatch to ready) are clocked too (``device call``, not in
  the sum: the isolated parts split them).
- **isolated**: each stage of a control period as a compiled function of its own, with the
  engine's ``vmap`` over the slots and ``shard_map`` over the devices, timed on the stage's
  inputs captured from the first timed run, over many periods in one ``scan`` (as the engine's
  block: each device loops on its own): the median of ``repeats`` calls after a compiling one,
  less the median of a no-op with the same arguments and as many outputs (a call's own
  cost). Of every
  100 control periods (an MJX block; 100 calls on the C path) the first ``sampled`` are
  replayed and stand for the 100. The MJX path replays a block from the state it started with,
  one stage call at a time, to get each stage's inputs (with ``sampled = block`` the replay
  ends in the engine's own state, bit for bit, which the bench checks); the C path replays each
  sampled call from its recorded inputs and checks its outputs against the call's, bit for bit.
  ``compiled calls' own cost``: a no-op with the engine call's arguments and donation and as
  many outputs, dispatched as the engine does, times the number of calls.
- **remainder**: the end-to-end time minus the sum of the parts, printed, never hidden: what no
  part holds (inside the calls: the block's loop, the dead-slot resets, the output packing; on
  the host: loop glue), the error of timing stages apart (a stage alone writes its outputs,
  which the engine's loop may keep in place), and on a shared machine the load's drift between
  the runs and the replay. It is split into its side inside the compiled calls (their time in
  run minus the isolated parts) and its side on the host.

The stages, per control period, over every slot (busy or vacant):

- physics steps: MJX: ``substeps`` x (``mjx.step`` + reading the sample, the fall rules and
  the accumulators) + one ``mjx.kinematics`` (``kernel.period`` after the solve); the bare
  steps (``mjx.step`` x substeps + one ``mjx.kinematics``) are timed as information. C: the
  rollout (in run); the samples' decoding on the host (in run) and their folding into the
  accumulators on the device (``cpath.fold_period``, isolated) are parts of their own.
- QP build: ``kernel.prepare_batch`` and ``kernel.conclude_batch`` (the solve apart): the
  state from the measurement buffer, the delay prediction or offset-free target where set, the
  solve's statistics, the input buffer;
  on the MJX path also the reset of a dead slot before the solve and the selection after it.
  The QP's matrices never change (condensed and factorised once, ``admm.build_admm``): per
  solve only its vectors move, inside ``admm_solve``; they are timed apart as information.
- ADMM: ``kernel.solve_batch`` over the slots: one ``while_loop`` per device (or per tile of
  ``engine.tile`` slots solved one after the other, ``--admm-tile``), which runs until its
  slowest slot stops. Iterations are counted per busy slot and per loop and period (the
  slowest slot's, what the loop costs).
- certificate: ``slots.certify`` (the check runs every ``CHECK_EVERY`` periods).
- refill, harvest, vacate: the engine's compaction (decided slots out, new cells in).

The replay (bench/replay.py) times the engines' own parts, the functions ``slots.block`` and
``cpath.call`` are made of; its bit-for-bit checks above confirm that it ran them as the
engine did.
"""

from __future__ import annotations

import os
import time
from contextlib import contextmanager
from typing import Any, NamedTuple

import jax
import numpy as np

from ..model.params import Config
from ..rollout import BatchRunner, cpath
from ..rollout import engine as engine_mod
from ..rollout.runner import push_steps
from ..runs.grid import grid_cells, parse_grid
from .replay import SAMPLE_GROUP, Agreement, Stages, replay_c, replay_mjx

__all__ = ["Agreement", "Drive", "Recorder", "drive", "measure", "measure_path", "split"]

# The default grid: the default sweep's durations (sweeps/default.toml), forces 0-155 N every
# 5 N (twice its force resolution): 256 cells.
DEFAULT_FORCES = "0:155:5"
DEFAULT_DURATIONS = "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5"

PARTS = {  # key: (label, how) in the table's order; "how" may differ per path (see split)
    "physics": "physics steps",
    "samples_host": "samples: decode (host)",
    "samples": "samples: fold, fall rules, accumulators",
    "qp_build": "QP build (kernel prepare and conclude, the solve apart)",
    "admm": "ADMM iterations (admm_solve)",
    "certificate": "certificate check",
    "refill": "refill, harvest, vacate",
    "call": "compiled calls' own cost (a no-op's)",
    "transfers": "transfers host <-> device",
    "python": "Python driver (queue, results)",
}
INFO = {  # timed, not parts of the sum
    "bare_physics": "of physics: bare mjx.step x substeps + kinematics",
    "qp_vectors": "of ADMM: the per-solve QP vectors and warm start",
    "device_call": "compiled calls, dispatch to ready (in run)",
}


# --------------------------------------------------------------------------------------------
# The instrumented runs: the engines' own loop, with a probe


class Recorder(engine_mod.Probe):
    """A probe (``rollout.engine.Probe``) that clocks each named part of an engine's loop
    (seconds per name; pauses left out of the total), waits for each compiled call to finish
    inside ``device_call``, and with ``record`` keeps the replay's inputs outside the clock:
    on the MJX path every call's slots and refill offer, on the C path the inputs and outputs
    of the first ``sampled`` calls of every ``SAMPLE_GROUP``."""

    def __init__(self, engine, record: bool = False, sampled: int = 10):
        self.seconds: dict[str, float] = {}
        self.paused_s = 0.0
        self.calls = 0
        self.records: list = []
        self.record, self.sampled = record, sampled
        self.c_path = isinstance(engine, cpath.CEngine)
        self._kept: tuple | None = None
        self.t0 = time.perf_counter()

    @contextmanager
    def __call__(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0

    @contextmanager
    def paused(self):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.paused_s += time.perf_counter() - t0

    def total(self) -> float:
        return time.perf_counter() - self.t0 - self.paused_s

    def before(self, p: int, state, args) -> None:
        self.calls = p + 1
        if not self.record:
            return
        with self.paused():
            if not self.c_path:
                self.records.append((jax.device_get(state), jax.device_get(args)))
            elif p % SAMPLE_GROUP < self.sampled:
                self._kept = (p, jax.device_get(state), *args)

    def after(self, p: int, outputs) -> None:
        if self._kept is not None and self._kept[0] == p:
            self.records.append((*self._kept, *outputs))
            self._kept = None

    def call(self, fn, *args):
        return jax.block_until_ready(fn(*args))


class Drive(NamedTuple):
    """One instrumented engine run."""

    raw: dict  # cell -> results, as Engine.run returns them
    seconds: float  # end to end (paused recording left out)
    parts: dict  # name -> seconds (in run)
    periods: int  # control periods of the engine's loop (every slot)
    calls: int  # compiled calls (host round trips)
    records: list  # what the replay needs (first run only)


def drive(engine, forces, n_push, *, record: bool = False, sampled: int = 10) -> Drive:
    """``engine.run`` over every cell with a :class:`Recorder` (the results' collection
    clocked as ``python``). On the MJX path the records end with the state the last call left
    (every slot vacant)."""
    probe = Recorder(engine, record, sampled)
    out = engine.run(forces, n_push, probe=probe)
    if record and not probe.c_path:
        with probe.paused():
            probe.records.append((jax.device_get(engine._state), None))
    return Drive(
        out, probe.total(), probe.seconds, probe.calls * engine.block, probe.calls, probe.records
    )


def warm_up(engine) -> None:
    """One call of the MJX engine's compiled block on vacant slots with nothing to refill
    (its first execution, outside the runs: vacant slots idle at rest, as after any run)."""
    n = engine.refill * engine.n_devices
    args = engine.offer_args(
        np.full(n, -1, np.int32),
        np.zeros(n),
        np.zeros(n, np.int32),
        np.zeros((n, 4)),
        np.zeros(n, np.int32),
    )
    state = engine._take_state()
    state, *_ = engine.block_fn()(engine.arrays, engine.cert, state, *args)
    engine._state = jax.block_until_ready(state)


# --------------------------------------------------------------------------------------------
# The split


# The isolated stages in each part (seconds of the replay), per path
ISOLATED = {
    "mjx": {
        "physics": ("physics",),
        "qp_build": ("prepare", "conclude"),
        "admm": ("solve",),
        "certificate": ("certify",),
        "refill": ("refill", "harvest"),
        "call": ("call",),
    },
    "c": {
        "samples": ("fold",),
        "qp_build": ("prepare", "conclude"),
        "admm": ("solve",),
        "certificate": ("certify",),
        "refill": ("refill",),
        "call": ("call",),
    },
}
IN_RUN = {"mjx": ("transfers", "python"), "c": ("physics", "samples_host", "transfers", "python")}


def _row(seconds: float, how: str, label: str, unit: tuple[float, int], total: float) -> dict:
    periods, lanes = unit
    return {
        "label": label,
        "how": how,
        "seconds": round(seconds, 4),
        "ms_per_period": round(1e3 * seconds / periods, 4),
        "us_per_slot_period": round(1e6 * seconds / (periods * lanes), 4),
        "share": round(seconds / total, 4),
    }


def split(path: str, drives: list[Drive], replay: dict, lanes: int) -> dict[str, Any]:
    """The parts (in run: the mean over ``drives``; isolated: the replay), the remainder (end to
    end minus their sum; also split into its device and host sides) and the information rows."""
    total = float(np.mean([d.seconds for d in drives]))
    in_run = {
        k: float(np.mean([d.parts.get(k, 0.0) for d in drives]))
        for k in set().union(*(d.parts for d in drives))
    }
    unit = (drives[0].periods, lanes)
    # an isolated part below the resolution of its no-op correction counts as 0 (listed)
    iso = {
        key: max(0.0, sum(replay["seconds"].get(n, 0.0) for n in names))
        for key, names in ISOLATED[path].items()
    }
    below = [
        key
        for key, names in ISOLATED[path].items()
        if sum(replay["seconds"].get(n, 0.0) for n in names) < 0
    ]
    parts = {}
    for key, label in PARTS.items():
        if key in ISOLATED[path]:
            parts[key] = _row(iso[key], "isolated", label, unit, total)
        elif key in IN_RUN[path]:
            parts[key] = _row(in_run.get(key, 0.0), "in run", label, unit, total)
    # the sum and the remainder from the unrounded seconds
    isolated = sum(iso.values())
    summed = isolated + sum(in_run.get(k, 0.0) for k in IN_RUN[path])
    device = in_run.get("device_call", 0.0)
    remainder = _row(
        total - summed, "remainder", "remainder: end to end minus the parts", unit, total
    )
    remainder.update(
        device_s=round(device - isolated, 4),
        host_s=round(total - device - sum(in_run.get(k, 0.0) for k in IN_RUN[path]), 4),
    )
    info = {"device_call": _row(device, "in run", INFO["device_call"], unit, total)}
    for key in ("bare_physics", "qp_vectors"):
        if key in replay["seconds"]:
            info[key] = _row(max(0.0, replay["seconds"][key]), "isolated", INFO[key], unit, total)
    return {
        "seconds": round(total, 4),
        "parts": parts,
        "remainder": remainder,
        "info": info,
        "total": _row(total, "measured", "end to end", unit, total),
        "below_resolution": below,
    }


def measure_path(
    config: Config,
    forces: np.ndarray,
    durations: np.ndarray,
    *,
    physics: str,
    slots: int | None = None,
    runs: int = 2,
    repeats: int = 3,
    sampled: int = 10,
    admm_tile: int | None = None,
    say=print,
) -> dict[str, Any]:
    """The split of one physics path: build and compile the engine, ``runs`` instrumented runs
    of every cell (the first records the replay's inputs), the replay."""
    t0 = time.perf_counter()
    runner = BatchRunner(
        config,
        slots=slots,
        early_stop=True,
        physics=physics,
        admm_tile=admm_tile if physics == "mjx" else None,
    )
    compile_s = runner.prepare()
    engine = runner.engine
    if physics == "mjx":  # the block's first execution, outside the runs
        warm_up(engine)
    build_s = time.perf_counter() - t0
    lanes = engine.slots * engine.n_devices
    say(
        f"  {physics}: engine ready in {build_s:.1f} s ({engine.slots} slots on each of "
        f"{engine.n_devices} device(s), block {engine.block}, refill {engine.refill}, "
        f"ADMM tile {engine.tile or engine.slots})"
    )
    n_push = push_steps(durations, config.scenario.physics_dt)
    drives = []
    for i in range(max(1, runs)):
        drives.append(drive(engine, forces, n_push, record=i == 0, sampled=sampled))
        say(
            f"  {physics}: run {i + 1}: {len(forces)} scenarios in {drives[-1].seconds:.2f} s "
            f"({drives[-1].periods} control periods, {drives[-1].calls} calls)"
        )
    t1 = time.perf_counter()
    stages = Stages(engine, repeats)
    if physics == "mjx":
        replay = replay_mjx(engine, drives[0].records, stages, sampled)
    else:
        replay = replay_c(engine, drives[0].records, stages, sampled, drives[0].periods)
    say(
        f"  {physics}: replayed {replay['sampled_periods']} control periods stage by stage in "
        f"{time.perf_counter() - t1:.1f} s"
    )
    figures = split(physics, drives, replay, lanes)
    raw = drives[0].raw
    figures.update(
        physics=physics,
        slots=engine.slots,
        devices=engine.n_devices,
        lanes=lanes,
        block=engine.block,
        refill=engine.refill,
        admm_tile=engine.tile or engine.slots,
        compile_s=round(compile_s, 3),
        runs=[round(d.seconds, 4) for d in drives],
        scenarios=len(forces),
        scen_per_s=round(len(forces) / figures["seconds"], 3),
        periods=drives[0].periods,
        calls=drives[0].calls,
        certified=int(raw["certified"].sum()),
        occupancy=round(float(raw["periods"].sum()) / (drives[0].periods * lanes), 4),
        admm_iterations=replay["iterations"],
        repeats=stages.repeats,
        call={k: round(v, 6) if isinstance(v, float) else v for k, v in replay["call"].items()},
        replay=dict(sampled_periods=replay["sampled_periods"], **replay["agreement"]),
    )
    if physics == "c":
        figures["threads"] = engine.c.threads
    return figures


def measure(
    config: Config,
    *,
    forces: str = DEFAULT_FORCES,
    durations: str = DEFAULT_DURATIONS,
    paths: tuple[str, ...] = ("mjx", "c"),
    slots: int | None = None,
    runs: int = 2,
    repeats: int = 3,
    sampled: int = 10,
    admm_tile: int | None = None,
    say=print,
) -> dict[str, Any]:
    """:func:`measure_path` of every path on the cells of ``forces`` x ``durations`` (grid
    specifications as ``sweep`` takes them)."""
    f, d = grid_cells(parse_grid(forces, "forces"), parse_grid(durations, "durations"))
    d = np.minimum(d, config.scenario.t_end)
    load = os.getloadavg()
    out: dict[str, Any]
    out = {
        "scenarios": int(f.size),
        "forces": forces,
        "durations": durations,
        "t_end": config.scenario.t_end,
        "cpus": os.cpu_count(),
        "load_average_start": [round(v, 2) for v in load],
        "paths": {},
    }
    for path in paths:
        if path == "c" and cpath.unsupported(config):
            say(f"  c: skipped ({cpath.unsupported(config)})")
            continue
        out["paths"][path] = measure_path(
            config,
            f,
            d,
            physics=path,
            slots=slots,
            runs=runs,
            repeats=repeats,
            sampled=sampled,
            admm_tile=admm_tile,
            say=say,
        )
    out["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    return out
