"""The region sweep and the robustness table run into an output folder, as every caller runs
them: grids read as the command line reads them, the batch function of the continuous-batching
engine, the persistent compilation cache on, the folder's lock held.

The public API (``api.sweep``, ``api.table``), the command line and the studies (compare,
landscape, sensitivity) all call these, so the three run a folder the same way.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
import numbers
import os
from typing import Any, NamedTuple

import numpy as np

from ..control.qp import build_qp, float32_conditioning, qp_bytes
from ..model.params import Config, ParameterError
from ..model.mjcf import build_model
from ..reference.loop import reference_controller
from ..rollout.runner import BatchRunner
from ..runtime import cache
from ..store.folder import folder_lock, require_lock
from .acting_time import TableResult, run_table, table_batch_size
from .batch import LazyBatch, ReferenceBatch
from .chunks import memory_budget, scenario_bytes
from .grid import Grid, Values, check_durations, duration_values, grid_values, is_bool, parse_pairs
from .region import SweepResult, run_sweep

log = logging.getLogger("mjx_balance")


def size_value(value: Any, name: str) -> int | None:
    """An optional size (``chunk``, ``slots``, ``batch``): None, or a whole number >= 1 (Python
    or NumPy integer, or a float with no fraction); anything else is refused with a
    ParameterError (a ValueError) naming ``name``."""
    if value is None:
        return None
    if is_bool(value) or not isinstance(value, numbers.Real):
        raise ParameterError(
            f"{name} = {value!r}: must be a whole number >= 1 (or None for "
            f"the default); got {type(value).__name__}"
        )
    if not (math.isfinite(value) and float(value) == int(value) and value >= 1):  # type: ignore[call-overload,operator]  # typeshed's numbers.Real has no int() or >=
        raise ParameterError(
            f"{name} = {value!r}: must be a whole number >= 1 (or None for the default)"
        )
    return int(value)  # type: ignore[call-overload]  # typeshed's numbers.Real has no int()


FLOAT32_RANGE = (1.1754944e-38, 3.4028235e38)  # float32's smallest normal, largest finite


def _gib(n: int) -> str:
    return f"{n / 2**30:.3g} GiB"


def check_memory(config: Config, *, batched: bool = True) -> None:
    """Refuse (ParameterError), before anything is built, a horizon whose dense QP (and, on the
    batched path, one scenario) does not fit the memory budget (``chunks.memory_budget``: a
    quarter of the available memory). Sizes in Python integers: any horizon is answered."""
    horizon = config.controller.horizon
    need = qp_bytes(horizon) + (scenario_bytes(config) if batched else 0)
    budget = memory_budget()
    if need > budget:
        raise ParameterError(
            f"controller.horizon = {horizon}: the MPC's dense QP ({2 * horizon} inputs, "
            f"{6 * horizon} constraint rows){' and one scenario' if batched else ''} need "
            f"about {_gib(need)}, more than the memory budget of {_gib(budget)} (a quarter of "
            "the available memory); use a shorter horizon (the study's: 20)"
        )


FLOAT32_MAX = 3.4028235e38


def check_float32_grid(values: "np.ndarray", name: str) -> None:
    """Refuse grid values that the batched path's float32 cannot hold (they would become inf)."""
    big = np.asarray(values, np.float64)
    big = big[np.abs(big) > FLOAT32_MAX]
    if big.size:
        raise ParameterError(
            f"{name}: {big[0]:g} does not fit the batched path's float32 "
            f"(largest {FLOAT32_MAX:.3g}); the scalar reference (simulate) "
            "runs in float64"
        )


def check_batched(config: Config, *grids: tuple) -> None:
    """Refuse (ParameterError), before any work or any file, a configuration (and ``grids``:
    (values, name) pairs) that the batched path (float32 ADMM, MJX) cannot run meaningfully,
    naming the value and the bound:

    - grid values beyond float32's range;
    - memory (:func:`check_memory`);
    - the ADMM's settings must be float32 numbers whose reciprocals are too (rho, the
      tolerances; sigma when not 0): 1e-300 becomes 0 in float32;
    - the QP must build (a Riccati solution, finite matrices) from the weights and bounds;
    - float32 must resolve it: κ(H)·ε_float32 < 1 (``qp.float32_conditioning``), which bounds
      horizon x control_dt for an unstable body (measured: docs/reliability.md)."""
    for values, name in grids:
        check_float32_grid(values, name)
    check_memory(config)
    cache.enable()  # the checks below run small jitted programs: through the persistent cache
    check_closed_loop(config)


@functools.lru_cache(maxsize=16)
def check_closed_loop(config: Config) -> None:
    """The configuration-only part of :func:`check_batched` (ADMM settings, the QP and its
    conditioning, the closed loop's build), remembered per configuration: the command line
    checks before it makes the folder and ``run_region`` checks again, at no second cost.
    A refused configuration raises each time (exceptions are not remembered)."""
    checked_runner(config)


def checked_runner(config: Config, **runner: Any) -> BatchRunner:
    """The batched closed loop of ``config`` (``BatchRunner(config, **runner)``), built only
    when the configuration passes the checks that need no compile: the ADMM's settings must
    be float32 numbers whose reciprocals are too, the QP must build and float32 must resolve
    it; a failed build is refused too (ParameterError naming the value or the cause). A
    population builds its bodies' runners through this, so each is checked by the one rule
    :func:`check_batched` applies."""
    c = config.controller
    low, high = FLOAT32_RANGE
    for name in ("admm_rho", "admm_eps_abs", "admm_eps_rel", "admm_sigma"):
        value = float(getattr(c, name))
        if name == "admm_sigma" and value == 0:
            continue
        if not (low <= value <= high and low <= 1.0 / value <= high):
            raise ParameterError(
                f"controller.{name} = {value!r}: the batched ADMM computes in float32, where "
                f"this value or its reciprocal is not a normal number (range {low:.3g} to "
                f"{high:.3g})"
            )
    try:
        qp = build_qp(c, config.body, config.scenario.control_dt)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        raise ParameterError(
            f"the MPC's QP cannot be built from this configuration ({type(exc).__name__}: "
            f"{exc}); check controller.q_diag, r_diag and the bounds"
        ) from None
    ratio = float32_conditioning(qp)
    if not ratio < 1.0:
        prediction = c.horizon * config.scenario.control_dt
        raise ParameterError(
            f"the MPC's QP is too ill-conditioned for the batched float32 ADMM: "
            f"cond(H) x eps_float32 = {ratio:.3g} >= 1 (controller.horizon = {c.horizon} x "
            f"scenario.control_dt = {config.scenario.control_dt:g} s: a {prediction:g}-s "
            "prediction of an unstable body, with these weights); shorten the prediction (the "
            "study's: 20 x 0.01 s) or run the scalar reference (mjx-balance simulate)"
        )
    try:  # everything else the batched closed loop builds (models, observer, predictor)
        return BatchRunner(config, **runner)
    except ParameterError:  # (a controller's factory, named by control/law.py)
        raise
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        raise ParameterError(
            f"the batched closed loop cannot be built from this configuration "
            f"({type(exc).__name__}: {exc})"
        ) from None


def check_reference(config: Config) -> None:
    """Refuse (ParameterError), before any run, a configuration the scalar reference cannot
    run: a QP that does not fit memory (:func:`check_memory`), or an MPC (QP and OSQP) or
    MuJoCo model that cannot be built from it."""
    check_memory(config, batched=False)
    try:
        reference_controller(config)
        build_model(config.body, config.scenario.physics_dt)
    except ParameterError:  # (a controller's factory, named by control/law.py)
        raise
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
        raise ParameterError(
            f"the scalar reference cannot be built from this configuration "
            f"({type(exc).__name__}: {exc}); check controller.q_diag, r_diag, the bounds and "
            "the body"
        ) from None


class Pushes(NamedTuple):
    """The pushes of a scalar reference run, checked (:func:`check_pushes`)."""

    forces: list[float]  # the grid's forces, or the pairs' own in order
    durations: list[float]  # likewise
    pairs: list[tuple[float, float]] | None  # the given pairs, or None for the cross product
    todo: list[tuple[float, float]]  # every push in run order


def check_pushes(
    config: Config, forces: Any = None, durations: Any = None, pairs: Any = None, *, flag: str = ""
) -> Pushes:
    """The pushes of ``simulate`` (the command and ``mb.simulate``), every one checked before
    any work: the cross product of ``forces`` and ``durations`` (grids; every force for the
    first duration, then the next), or the given ``pairs`` (``"20:0.7,30:0.45"``, a CSV file
    or (force, duration) pairs, in their order); durations whole physics steps within the
    window; each push's configuration; and the reference's own build (:func:`check_reference`).
    ``flag``: "--" where the values came from the command line's options (the messages name
    them so). ParameterError naming the value and the rule."""
    if pairs is not None:
        f, d = parse_pairs(pairs, f"{flag}pairs")
        d = check_durations(
            d,
            config.scenario.t_end,
            f"{flag}pairs",
            unique=False,
            physics_dt=config.scenario.physics_dt,
        )
        if forces is not None or durations is not None:
            raise ParameterError(
                f"{flag}pairs gives the pushes: leave out {flag}forces and {flag}durations"
            )
        given = list(zip(f.tolist(), d.tolist()))
        result = Pushes(f.tolist(), d.tolist(), given, given)
    else:
        for values, name in ((forces, "forces"), (durations, "durations")):
            if values is None:
                raise ParameterError(f"{flag}{name}: give the pushes' {name} (or {flag}pairs)")
        f = grid_values(forces, f"{flag}forces")
        d = duration_values(durations, config, f"{flag}durations")
        result = Pushes(
            f.tolist(), d.tolist(), None, [(x, y) for y in d.tolist() for x in f.tolist()]
        )
    for duration in result.durations:  # every other rule of each push's configuration
        config.replace(scenario={"duration": float(duration)})
    check_reference(config)
    return result


def batch_function(
    config: Config,
    *,
    slots: int | None = None,
    full_length: bool = False,
    physics: str = "auto",
    backend: str = "mjx",
):
    """The batch function of ``sweep`` and ``table``: the batched closed loop of ``config`` on
    the continuous-batching engine, built and compiled on its first call (with the persistent
    compilation cache on, :func:`mjx_balance.runtime.cache.enable`). ``physics``: "mjx", "c"
    (MuJoCo C stepped on a thread pool, the ADMM in JAX) or "auto" (docs/engine.md).
    ``backend`` "reference": the scalar reference loop instead, scenario by scenario
    (:class:`ReferenceBatch`: the report's small plans)."""
    if backend == "reference":
        return ReferenceBatch(config)
    if backend != "mjx":
        raise ParameterError(f"backend must be 'mjx' or 'reference', got {backend!r}")
    return LazyBatch(config, slots=slots, early_stop=not full_length, physics=physics)


def _holding(out: str | os.PathLike[str], lock: bool, wait: bool) -> Any:
    """The folder's lock for this run (``lock``), or a check that the caller's run holds it."""
    if lock:
        return folder_lock(out, wait=wait)
    require_lock(out)
    return contextlib.nullcontext()


def run_region(
    out: str | os.PathLike[str],
    config: Config,
    grid: Grid,
    *,
    run_batch: Any = None,
    chunk: int | None = None,
    slots: int | None = None,
    full_length: bool = False,
    progress: bool | None = None,
    wait: bool = False,
    cluster: Any = None,
    physics: str = "auto",
    say: Any = log.info,
    lock: bool = True,
) -> "SweepResult":
    """The region sweep of ``grid`` (:class:`grid.Grid`, made for ``config``: ``Grid.of``)
    into the folder ``out`` (resumable; ``region.run_sweep``) under its lock (``wait``: wait
    for another run that holds it; ``lock`` False: the caller's run holds it already, as the
    command line's, which runs the table and draws the figures in the same hold).
    ``run_batch``: a batch function (default: :func:`batch_function`); ``cluster``: run the
    chunks on a Dask cluster (``"local:N"``, a scheduler address or file, or a
    ``distributed.Client``; docs/cluster.md); ``say``: where the sweep's lines go (default:
    the ``mjx_balance`` logger; None: nowhere). Returns the SweepResult (the command line
    draws its figures)."""
    if not isinstance(grid, Grid):
        raise TypeError(f"run_region takes a Grid (runs.grid.Grid.of), got {type(grid).__name__}")
    grid.fits(config)
    chunk, slots = size_value(chunk, "chunk"), size_value(slots, "slots")
    batched = run_batch is None or isinstance(run_batch, LazyBatch)  # the batched engine's
    if batched and not getattr(run_batch, "checked", False):
        check_batched(config, (grid.forces, "forces"), (grid.durations, "durations"))
    if run_batch is None:
        run_batch = batch_function(config, slots=slots, full_length=full_length, physics=physics)
    cache.enable()
    with _holding(out, lock, wait):
        return run_sweep(
            out,
            config,
            grid,
            run_batch=run_batch,
            chunk=chunk,
            progress=progress,
            say=say,
            cluster=cluster,
        )


def run_table_folder(
    out: str | os.PathLike[str],
    config: Config,
    forces: Values,
    *,
    run_batch: Any = None,
    batch: int | None = None,
    slots: int | None = None,
    full_length: bool = False,
    progress: bool | None = None,
    wait: bool = False,
    cluster: Any = None,
    physics: str = "auto",
    sustained: bool = True,
    say: Any = log.info,
    lock: bool = True,
) -> "TableResult | None":
    """The max-acting-time table into the folder ``out`` (``runs.acting_time.run_table``:
    resumable, the scenarios it ran kept) under its lock. ``batch``: scenarios per call
    (default: ``runs.acting_time.table_batch_size``; the scalar reference loop,
    :class:`ReferenceBatch`, runs scenario by scenario and bisects, one point per round);
    ``cluster``: run each round's calls on a Dask cluster (as :func:`run_region`; the same
    table); ``sustained``: also the sustained-push limit; ``say`` and ``lock``: as
    :func:`run_region`'s.
    Returns None when the folder already held this table."""
    forces = grid_values(forces, "forces")
    batch, slots = size_value(batch, "batch"), size_value(slots, "slots")
    batched = run_batch is None or isinstance(run_batch, LazyBatch)  # the batched engine's
    if batched and not getattr(run_batch, "checked", False):
        check_batched(config, (forces, "forces"))
    if run_batch is None:
        run_batch = batch_function(config, slots=slots, full_length=full_length, physics=physics)
    if batch is None and not isinstance(run_batch, ReferenceBatch):
        batch = table_batch_size(config, forces.size)
    cache.enable()
    with _holding(out, lock, wait):
        return run_table(
            out,
            config,
            forces,
            run_batch=run_batch,
            batch=batch,
            progress=progress,
            say=say,
            cluster=cluster,
            sustained=sustained,
        )
