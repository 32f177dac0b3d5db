"""Helpers the commands share when they run: the run's configuration from the options, one
push's configuration and duration, progress on or off, the chosen physics path, and the work
in an output folder under its lock.

Light at import (the parser imports the command modules): what needs the library below the
configuration imports it when called.
"""

from __future__ import annotations

import argparse
import errno
import logging
import sys
from pathlib import Path
from typing import Any, Callable

from ..model.params import Config
from ..model.config_files import run_config

WRITE_FAILED = 1  # exit code of a run whose writing failed (2: bad arguments, before any work)


def base_config(args: argparse.Namespace, overrides: bool = True) -> Config:
    """The --config file's configuration (or the defaults) with --subject in place of its
    [subject] and the --set overrides on top (--convention not applied). ``overrides=False``:
    without them (the base of a --sweep file, which the overrides go on top of: a value may
    only be valid with the file's others)."""
    return run_config(
        getattr(args, "config", None),
        None,
        getattr(args, "set", None) if overrides else None,
        getattr(args, "subject", None),
    )


def load_run_config(args: argparse.Namespace) -> Config:
    """The run's configuration: --config file (or defaults) with --subject, --set overrides,
    then --convention on top."""
    return run_config(
        getattr(args, "config", None),
        getattr(args, "convention", None),
        getattr(args, "set", None),
        getattr(args, "subject", None),
    )


def one_push(args: argparse.Namespace) -> tuple[Config, float]:
    """(configuration, duration) of a one-push command (``animate``, ``view``): --t-end
    applied, the duration checked as ``sweep`` checks it (whole physics steps in [0, t_end],
    snapped to them) and every other rule of the configuration checked before any work."""
    from ..runs.grid import check_durations  # lazy: the runs floor loads JAX

    config = load_run_config(args)
    if args.t_end is not None:
        config = config.replace(scenario={"t_end": args.t_end})
    duration = float(
        check_durations(
            [args.duration],
            config.scenario.t_end,
            "--duration",
            physics_dt=config.scenario.physics_dt,
        )[0]
    )
    config.replace(scenario={"duration": duration})
    return config, duration


def guard_work(
    args: argparse.Namespace,
    config: Config,
    n_scenarios: int,
    what: str,
    *,
    chunk_size: int | None = None,
    extra: int = 0,
    reference: bool = False,
    note: str = "",
    setup: tuple[float, str] = (0.0, ""),
    during: tuple[float, str] = (0.0, ""),
) -> None:
    """Say the planned work (one line: scenarios, estimated time and disk) and refuse it above
    the limit unless --yes, before anything is compiled or written. ``extra``: scenarios
    beyond ``n_scenarios`` (a table's); ``reference``: run one at a time by the scalar
    reference (its rate), not by the batched engine; ``note``: what the work will give,
    appended to the line after a semicolon; ``setup``: (seconds, what) spent before the first
    scenario, ``during``: (seconds, what) of set-up spread over the run, each counted in the
    line and the limit."""
    from ..runs import chunks  # lazy: the runs floor loads JAX

    t_end = config.scenario.t_end
    rate = chunks.REFERENCE_SECONDS_PER_SECOND if reference else chunks.SIMULATED_SECONDS_PER_SECOND
    floor = 0.0 if reference else chunks.RATE_WINDOW  # the reference runs every window whole
    startup = chunks.REFERENCE_STARTUP if reference else chunks.ENGINE_STARTUP
    disk = {} if not reference else {"bytes_per_scenario": reference_bytes(config)}
    logging.getLogger("mjx_balance").info(
        chunks.planned_work(
            n_scenarios,
            t_end,
            chunk_size,
            what,
            rate=rate,
            setup=setup,
            during=during,
            startup=startup,
            window_floor=floor,
            **disk,
        )
        + (f" (+ about {extra:,} table scenarios)" if extra else "")
        + (f"; {note}" if note else "")
    )
    if not getattr(args, "yes", False):
        chunks.check_planned_work(
            n_scenarios + extra,
            t_end,
            what,
            rate=rate,
            setup_s=setup[0] + during[0] + startup[1],
            window_floor=floor,
        )


def table_scenarios(config: Config, n_forces: int) -> int:
    """``runs.acting_time.table_scenarios`` (the planning estimate of a table's scenarios)."""
    from ..runs.acting_time import table_scenarios as estimate  # lazy: the runs floor: JAX

    return estimate(config, n_forces)


def planner(args: argparse.Namespace) -> Any:
    """The ``plan`` callable an API function calls with its ``runs.chunks.PlannedWork`` once
    everything is checked: :func:`guard_work` with these options (--yes)."""

    def plan(work: Any) -> None:
        guard_work(
            args,
            work.config,
            work.scenarios,
            work.what,
            chunk_size=work.chunk_size,
            extra=work.extra,
            reference=work.reference,
            note=work.note,
        )

    return plan


def reference_bytes(config: Config) -> int:
    """Disk for one push of the scalar reference: its time series, a float per column and
    physics step (parquet compresses it; an upper bound)."""
    from ..reference.loop import TIMESERIES_COLUMNS  # lazy: MuJoCo

    steps = config.scenario.n_control * config.scenario.substeps
    return 8 * steps * len(TIMESERIES_COLUMNS)


def verbosity(args: argparse.Namespace) -> int:
    """-1 with -q, 1 with -v, else 0 (-q wins)."""
    return -1 if getattr(args, "quiet", 0) else (1 if getattr(args, "verbose", 0) else 0)


def progress_enabled(args: argparse.Namespace) -> bool:
    """Progress bars: on unless -q."""
    return verbosity(args) >= 0


def chosen_physics(args: Any, definition: Any) -> str:
    """--physics, else the --sweep file's [sweep] physics, else auto."""
    return getattr(args, "physics", None) or getattr(definition, "physics", None) or "auto"


def in_folder(out: Path, work: Callable[[], None], *, wait: bool = False, lock: bool = True) -> int:
    """Run ``work`` holding the folder's lock (``wait``: waiting for another run to let go of
    it, else refused at once; ``lock`` False: ``work`` is an API function that takes it
    itself); a failed write ends in one line, exit code 1."""
    from ..store.folder import folder_lock  # lazy: the store floor loads pandas

    try:
        if not lock:
            work()
            return 0
        with folder_lock(out, wait=wait):
            work()
    except OSError as exc:
        print(f"mjx-balance: error: {_write_failure(out, exc)}", file=sys.stderr)
        return WRITE_FAILED
    return 0


def _write_failure(out: Path, exc: OSError) -> str:
    """One line: which write in which folder failed, why, and what to do."""
    reason = exc.strerror or (str(exc).splitlines() or [type(exc).__name__])[0]
    where = f" ({Path(exc.filename).name})" if exc.filename else ""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        fix = f"free some space on the disk of {out}"
    elif exc.errno == errno.EFBIG:
        fix = "raise the file-size limit (ulimit -f)"
    else:
        fix = "fix the cause"
    return (
        f"writing in {out} failed: {reason}{where}; what was finished is kept: {fix}, "
        "then run the same command again to resume"
    )
