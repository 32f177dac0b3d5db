"""The ``mjx-balance`` command line: the top layer, which nothing in the library imports.

This module parses arguments and dispatches; each command lives in a module of this package
and drives the library below it:

    simulate      cli.simulate:simulate_command  scalar MuJoCo C + OSQP, one scenario at a time
    bench         cli.bench:pipeline_command     whole closed loop: MJX + ADMM vs reference vs IPOPT
    bench solver  cli.bench:solver_command       batched ADMM vs OSQP vs CasADi/IPOPT
    bench physics cli.bench:physics_command      where the time goes; MJX vs MuJoCo C
    sweep         cli.sweep:sweep_command        force x duration region map (MJX + ADMM)
    landscape     cli.landscape                  area, sustained limit, energy over Q x R scales
    table         cli.sweep:table_command        max acting time per force (batched bisection)
    basin         cli.basin:basin_command        recovery basin over initial CoM states
    sensitivity   cli.sensitivity                the table under every reading of the study
    animate       cli.animate:animate_command    stick-figure GIF of one push (reference)
    report        cli.report:report_command      HTML report: the study's experiments and studies
    model         cli.model:model_command        the MJCF of the configured body
    view          cli.model:view_command         one push replayed in MuJoCo's passive viewer

simulate, sweep and table are thin layers over the Python API (``mjx_balance.api``): they
resolve their options into its arguments, then write figures and print.

Conventions: ``python -m mjx_balance`` is ``mjx-balance``; ``--version`` prints the package's,
JAX's, jaxlib's and MuJoCo's versions; messages and progress go through ``logging`` (logger
``mjx_balance``: information on stdout, warnings and errors on stderr; ``-q`` keeps only
warnings and errors and turns progress bars off, ``-v`` adds debug messages); ``--help`` shows
every default; ``--set SECTION.KEY=VALUE`` overrides the configuration of any command that
takes ``--config``; ``--no-cache`` turns JAX's persistent compilation cache off
(``mjx_balance.runtime.cache``).

A command module is imported only when its command runs (after :func:`use_host_cores`, which
must see JAX not yet imported).

Exit codes: 0 success, 1 failure during the work, 2 bad usage. Bad arguments end in one line on
stderr and exit code 2, before any work and before anything is written: values and paths are checked by the argparse types below (argparse prints its usage,
then ``mjx-balance CMD: error: argument --X: ...``), a configuration that breaks a rule by
``params`` (ParameterError: ``mjx-balance: error: ...``). An OSError during the work (a place
that passed the checks but refuses the write, a full disk) is a failure: one line, exit code 1.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import math
import os
import shlex
import sys
from pathlib import Path

from ..runtime.xla import deterministic_flags
from ..model.params import CONVENTIONS, Config, ParameterError, run_config

log = logging.getLogger("mjx_balance")

EPILOG = """exit codes: 0 success; 1 failure during the work (a refused write, a full disk, a run
that broke); 2 bad usage (an unknown option, a bad value or configuration), reported before any
work and before anything is written."""


def base_config(args: argparse.Namespace, overrides: bool = True) -> Config:
    """The --config file's configuration (or the defaults) with the --set overrides on top
    (--convention not applied). ``overrides=False``: without them (the base of a --sweep file,
    which the overrides go on top of: a value may only be valid with the file's others)."""
    return run_config(getattr(args, "config", None), None,
                      getattr(args, "set", None) if overrides else None)


def load_run_config(args: argparse.Namespace) -> Config:
    """The run's configuration: --config file (or defaults), --set overrides, then --convention
    on top."""
    return run_config(getattr(args, "config", None), getattr(args, "convention", None),
                      getattr(args, "set", None))


def one_push(args: argparse.Namespace) -> tuple[Config, float]:
    """(configuration, duration) of a one-push command (``animate``, ``view``): --t-end
    applied, the duration checked as ``sweep`` checks it (whole physics steps in [0, t_end],
    snapped to them) and every other rule of the configuration checked before any work."""
    from ..runs.grid import check_durations

    config = load_run_config(args)
    if args.t_end is not None:
        config = config.replace(scenario={"t_end": args.t_end})
    duration = float(check_durations([args.duration], config.scenario.t_end, "--duration",
                                      physics_dt=config.scenario.physics_dt)[0])
    config.replace(scenario={"duration": duration})
    return config, duration


# ---------------------------------------------------------------------------------------------
# Argument types: each returns the parsed value or raises ArgumentTypeError with the rule.

def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def finite_float(text: str) -> float:
    """A finite number."""
    return _number(text)


def nonnegative_float(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


def _integer(text: str, minimum: int) -> int:
    try:
        value = float(text.strip())  # "1e4" is a whole number too
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not (math.isfinite(value) and value.is_integer() and value >= minimum):
        raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {text!r}")
    return int(value)


def positive_int(text: str) -> int:
    """An integer >= 1."""
    return _integer(text, 1)


def nonnegative_int(text: str) -> int:
    """An integer >= 0."""
    return _integer(text, 0)


def positive_int_list(text: str) -> list[int]:
    """A comma list of integers >= 1, at least one."""
    items = [item for item in text.split(",") if item.strip()]
    if not items:
        raise argparse.ArgumentTypeError("give at least one integer")
    return [positive_int(item) for item in items]


def batch_sizes(text: str) -> str:
    """``text`` when it is a comma list of integers >= 1 (the command splits it)."""
    positive_int_list(text)
    return text


def input_file(text: str) -> str:
    """An existing, readable UTF-8 text file (a TOML or CSV input)."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text!r} not found")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r} is not a file")
    try:
        path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text!r} cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not UTF-8 text (byte {exc.start}); expected a text file") from None
    return text


def sweep_file(text: str) -> str:
    """A sweep definition: a TOML file, or the name of one the package ships
    (``region_dense_paper``; ``mjx_balance/sweeps/``)."""
    from ..runs.definitions import find_sweep

    path = Path(text)
    if not path.exists() and path.parent == Path("."):
        try:
            return str(find_sweep(text))
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return input_file(text)


def setting(text: str) -> str:
    """A --set SECTION.KEY=VALUE (its value is checked with the configuration)."""
    from ..model.params import parse_override

    try:
        parse_override(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix(f"--set {text!r}: ")) from None
    return text


def input_folder(text: str) -> str:
    """An existing folder."""
    if not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is not a folder")
    return text


def _unwritable(path: Path) -> str | None:
    """Why ``path`` cannot be created (with its missing parents) or written in, or None.

    Permissions as os.access sees them; a place that still refuses the write (a special file
    system, root on a read-only mount) ends in main's one-line OSError message."""
    existing = path
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if not existing.is_dir():
        return f"{str(existing)!r} is not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{str(existing)!r} is not writable"
    return None


def out_folder(text: str) -> str:
    """An output folder: an existing folder to reuse or one that can be created."""
    if not text.strip():
        raise argparse.ArgumentTypeError("give a folder name")
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a folder")
    reason = _unwritable(path)
    if reason:
        raise argparse.ArgumentTypeError(f"cannot write {text!r}: {reason}")
    return text


def out_gif(text: str) -> str:
    """An output GIF file: a name ending in .gif, not a folder, in a place that can be written."""
    return _output_file(text, ".gif")


# ---------------------------------------------------------------------------------------------

def out_file(text: str) -> str:
    """An output file: a name, not a folder, in a place that can be written."""
    return _output_file(text)


def _output_file(text: str, suffix: str | None = None) -> str:
    """``text`` as an output file name (ending in ``suffix`` if given), or ArgumentTypeError."""
    name = "a file name" + (f" ending in {suffix}" if suffix else "")
    if not text.strip():
        raise argparse.ArgumentTypeError(f"give {name}")
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a folder; give {name}")
    if suffix and path.suffix.lower() != suffix:
        raise argparse.ArgumentTypeError(f"{text!r}: the file name must end in {suffix}")
    reason = _unwritable(path.parent)
    if reason:
        raise argparse.ArgumentTypeError(f"cannot write {text!r}: {reason}")
    return text


class HelpFormatter(argparse.RawDescriptionHelpFormatter,
                    argparse.ArgumentDefaultsHelpFormatter):
    """Every option's default in its help ("(default: ...)"), unless the help already says it
    or there is none to say (no value, a flag); descriptions and epilogs as written."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("default" in text or action.default in (None, False, argparse.SUPPRESS)
                or not action.option_strings):
            return text
        return text + " (default: %(default)s)"


def _conventions(p: argparse.ArgumentParser) -> None:
    """-q, -v, --no-cache: accepted before or after the command (mjx-balance -q sweep ...)."""
    p.add_argument("-q", "--quiet", action="count", default=argparse.SUPPRESS,
                   help="only warnings and errors; no progress bars")
    p.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                   help="debug messages too")
    p.add_argument("--no-cache", action="store_true", default=argparse.SUPPRESS,
                   help="do not use JAX's persistent compilation cache (default: on, in "
                        "$MJX_BALANCE_CACHE_DIR or the user's cache folder, "
                        "~/.cache/mjx_balance/jax on Linux; MJX_BALANCE_CACHE_DIR=off turns it "
                        "off too)")


def _config_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--convention", choices=CONVENTIONS, default=None,
                   help="controller convention (default: the configuration's, 'paper')")
    p.add_argument("--config", type=input_file, default=None,
                   help="TOML configuration file (body, controller, scenario)")
    p.add_argument("--set", type=setting, action="append", default=None,
                   metavar="SECTION.KEY=VALUE",
                   help="override one value of the configuration, e.g. --set "
                        "controller.horizon=30 --set scenario.t_end=6 (repeatable; checked "
                        "as in a TOML file; applied after --config and a sweep definition)")


def _common(p: argparse.ArgumentParser, out_required: bool = True,
            out_help: str = "output folder", out_type=out_folder) -> None:
    _config_options(p)
    p.add_argument("--out", type=out_type, required=out_required, default=None, help=out_help)


def _yes(p: argparse.ArgumentParser) -> None:
    p.add_argument("--yes", action="store_true",
                   help="run even when the planned work is beyond the limit (2,000,000 scenarios "
                        "or an estimated 24 h on a 2-core CPU)")


def _wait(p: argparse.ArgumentParser) -> None:
    p.add_argument("--wait", action="store_true",
                   help="when another run holds the --out folder, wait for it to end "
                        "(default: refuse at once, naming that run)")


def cluster_spec(text: str) -> str:
    """A Dask cluster: local:N, a scheduler address or a scheduler file (sweep/cluster.py)."""
    from ..runs.cluster import ClusterError, parse_cluster

    try:
        parse_cluster(text)
    except ClusterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _cluster(p: argparse.ArgumentParser) -> None:
    p.add_argument("--cluster", type=cluster_spec, default=None, metavar="SPEC",
                   help="run the scenarios on a Dask cluster (a region map's chunks, a table's "
                        "bisection calls): local:N (N worker processes "
                        "here), a scheduler address (tcp://host:8786) or a scheduler file "
                        '(.json); needs pip install "mjx_balance[cluster]" (docs/cluster.md)')


def _engine_options(p: argparse.ArgumentParser) -> None:
    """Options of the continuous-batching engine (sweep, table, bench)."""
    p.add_argument("--full-length", action="store_true",
                   help="run every scenario to t_end (no early stop of certified recoveries; "
                        "falls still end a scenario), for validation")
    p.add_argument("--slots", type=positive_int, default=None,
                   help="scenarios in flight per device (default: 32 on a CPU, 4096 on a GPU; "
                        "64 on the C path); "
                        "results are bit-identical for any chunk, device count or order at one "
                        "slot count, so a sweep folder keeps the count it started with")
    _physics(p)


def _physics(p: argparse.ArgumentParser) -> None:
    p.add_argument("--physics", choices=("auto", "mjx", "c"), default=None,
                   help="physics of the batched closed loop: mjx (MuJoCo MJX in JAX, float32), "
                        "c (MuJoCo C on a thread pool, float64, the reference's physics; the "
                        "ADMM stays in JAX) or auto (the faster on this machine: "
                        "docs/engine.md; default: a --sweep file's [sweep] physics, else auto); "
                        "a sweep folder keeps the path it started with")


def _bench_pipeline_arguments(p: argparse.ArgumentParser) -> None:
    """Options of ``mjx-balance bench`` (the pipeline benchmark)."""
    p.add_argument("--scenarios", type=positive_int, default=1024,
                   help="scenarios through MJX + ADMM (continuous batching and --full-length)")
    p.add_argument("--reference", type=nonnegative_int, default=16,
                   help="of those, how many through the scalar reference (0: skip)")
    p.add_argument("--ipopt", type=nonnegative_int, default=8,
                   help="of those, how many through CasADi/IPOPT + MuJoCo C, with the "
                        "reference's outcome mix (0: skip)")
    p.add_argument("--workers", type=positive_int, default=os.cpu_count() or 2,
                   help="worker processes of the reference and the study toolchain")
    _engine_options(p)
    p.add_argument("--repeats", type=positive_int, default=1, help="timed MJX runs (median)")
    p.add_argument("--t-end", type=positive_float, default=None,
                   help="scenario length [s] (default 12)")
    p.add_argument("--osqp-max-iter", type=positive_int, default=None,
                   help="reference OSQP iteration cap (default: the configuration's, 20000)")
    p.add_argument("--memory-scaling", type=positive_int_list,
                   default=None, help="comma list of sweep sizes (cells), e.g. 10000,100000")
    p.add_argument("--memory-t-end", type=positive_float, default=0.02,
                   help="t_end of those sweeps [s]")
    p.add_argument("--memory-chunk", type=positive_int, default=None,
                   help="chunk size of those sweeps")
    p.add_argument("--memory-timeout", type=positive_float, default=900.0,
                   help="seconds per sweep")
    p.add_argument("--no-cache-times", action="store_true",
                   help="skip measuring the engine's compile time with an empty and with a "
                        "filled persistent compilation cache (two fresh processes, one compile "
                        "each; JSON keys compile_first_s, compile_cached_s, "
                        "compile_cached_hits, compile_cached_compiles)")
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")


class _Version(argparse.Action):
    """--version: the package's, JAX's, jaxlib's and MuJoCo's versions (no import of JAX)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="print the versions of mjx_balance, JAX, jaxlib and MuJoCo and exit"):
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text())
        parser.exit(0)


def version_text() -> str:
    """One line: ``mjx-balance 0.1.0 (jax 0.10.2, jaxlib 0.10.2, mujoco 3.17.0, ...)``."""
    from ..store.folder import versions

    v = versions()
    return (f"mjx-balance {v['package']} (jax {v['jax']}, jaxlib {v['jaxlib']}, "
            f"mujoco {v['mujoco']}, mujoco-mjx {v['mujoco_mjx']}, python {v['python']})")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mjx-balance", formatter_class=HelpFormatter, epilog=EPILOG,
        description="Standing-balance recovery under constrained MPC: pushes, sweeps, tables.")
    parser.add_argument("--version", action=_Version)
    _conventions(parser)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    conventions = argparse.ArgumentParser(add_help=False)
    _conventions(conventions)
    add_parser = sub.add_parser

    def command(name: str, **kwargs) -> argparse.ArgumentParser:
        return add_parser(name, formatter_class=HelpFormatter, epilog=EPILOG,
                          parents=[conventions], description=kwargs.get("help"), **kwargs)

    sub.add_parser = command  # every command: the conventions' options, defaults, epilog

    p = sub.add_parser("simulate", help="scalar reference closed loop (MuJoCo C + OSQP) for a few pushes")
    p.add_argument("--force", default="0,20,50,80,100,120", help="comma-separated forces [N]")
    p.add_argument("--duration", default="0.1", help="comma-separated push durations [s]")
    p.add_argument("--full-window", action="store_true",
                   help="time axes of the figures up to t_end (default: trimmed to the action, "
                        "the last settle or fall plus a margin)")
    _common(p)
    p.set_defaults(target="mjx_balance.cli.simulate:simulate_command")

    p = sub.add_parser("bench", help="pipeline benchmark: batched MJX + ADMM vs the scalar reference "
                                     "vs CasADi/IPOPT, scenarios per second (or: bench solver)")
    _bench_pipeline_arguments(p)
    _common(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:pipeline_command")
    bench = p.add_subparsers(dest="bench", required=False, metavar="{solver,physics}")
    p = bench.add_parser("solver", help="batched ADMM vs OSQP vs CasADi/IPOPT, solves per second",
                         description="batched ADMM vs OSQP vs CasADi/IPOPT, solves per second",
                         formatter_class=HelpFormatter, epilog=EPILOG, parents=[conventions])
    p.add_argument("--batch", type=batch_sizes, default="1,16,256,4096,16384",
                   help="comma-separated batch sizes")
    p.add_argument("--states", type=positive_int, default=4096, help="number of test states")
    p.add_argument("--dtype", choices=("float32", "float64"), default="float32")
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")
    _common(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:solver_command")
    p = bench.add_parser("physics", help="where a CPU sweep's time goes: bare MJX step, closed "
                                         "loop, pipeline, ADMM, MuJoCo C (mujoco.rollout) and "
                                         "a C path's bound, per scenario-step",
                         description="per scenario-step costs of the physics paths side by "
                                     "side (bench/physics.py explains each figure)",
                         formatter_class=HelpFormatter, epilog=EPILOG, parents=[conventions])
    p.add_argument("--slots", type=positive_int, default=64,
                   help="scenarios side by side (split over the host devices / C threads)")
    p.add_argument("--seconds", type=positive_float, default=2.0,
                   help="simulated window of each scenario [s]")
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")
    _common(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:physics_command")

    p = sub.add_parser("sweep", help="recoverable region over a force x duration grid")
    p.add_argument("--forces", default=None, help="start:stop:step or a comma list [N]")
    p.add_argument("--durations", default=None, help="start:stop:step or a comma list [s]")
    p.add_argument("--sweep", type=sweep_file, default=None,
                   help="sweep definition: a TOML file or the name of a shipped one "
                        "(default, region_dense_paper, study_...; see mjx_balance/sweeps/)")
    p.add_argument("--chunk", type=positive_int, default=None,
                   help="scenarios per chunk (default: from memory budget)")
    p.add_argument("--reference", type=input_file, default=None,
                   help="CSV of points (force, duration) to draw over the map")
    _engine_options(p)
    _cluster(p)
    _yes(p)
    _wait(p)
    _common(p)
    p.set_defaults(target="mjx_balance.cli.sweep:sweep_command")

    p = sub.add_parser("table", help="max acting time per force (robustness table) and the "
                                     "sustained-push limit")
    p.add_argument("--forces", default=None,
                   help="comma list or start:stop:step [N] (default: the --sweep file's table_forces, "
                        "else the study's 5,10,15,20,30,40,50,60,80,100,120)")
    p.add_argument("--sweep", type=sweep_file, default=None,
                   help="sweep definition: a TOML file or the name of a shipped one "
                        "(study_table_paper, ...; see mjx_balance/sweeps/)")
    _engine_options(p)
    _cluster(p)
    _yes(p)
    _wait(p)
    _common(p)
    p.set_defaults(target="mjx_balance.cli.sweep:table_command")

    p = sub.add_parser("compare", help="several configurations on one grid: their recovery "
                                       "boundaries in one figure, their numbers in one table")
    p.add_argument("--config", type=sweep_file, action="append", required=True,
                   metavar="FILE", help="a TOML configuration, or a sweep definition (a file "
                                        "or a shipped name such as study_offset_free: its "
                                        "configuration, not its grid); repeat for each; the "
                                        "folder name is the file's stem")
    p.add_argument("--forces", default=None,
                   help="start:stop:step or a comma list [N] (default: the default sweep's, "
                        "0:150:10)")
    p.add_argument("--durations", default=None,
                   help="start:stop:step or a comma list [s] (default: the default sweep's)")
    p.add_argument("--table-forces", default=None,
                   help="forces of each configuration's max-acting-time table [N] (default: "
                        "the default sweep's, 20,50,80,100,120)")
    _engine_options(p)
    _cluster(p)
    _wait(p)
    p.add_argument("--out", type=out_folder, required=True,
                   help="output folder: one sweep folder per configuration, compare.csv, "
                        "compare.png")
    p.set_defaults(target="mjx_balance.cli.compare:compare_command")

    from .landscape import add_parser as landscape_parser  # light: no library import

    landscape_parser(sub)

    from .basin import add_parser as basin_parser  # light: no library import

    basin_parser(sub)

    from .sensitivity import add_parser as sensitivity_parser

    sensitivity_parser(sub)

    p = sub.add_parser("animate", help="stick-figure GIF of one push (matplotlib, no OpenGL)")
    p.add_argument("--force", type=finite_float, required=True, help="push force [N]")
    p.add_argument("--duration", type=nonnegative_float, default=0.1, help="push duration [s]")
    p.add_argument("--fps", type=positive_float, default=25.0, help="frames per second")
    p.add_argument("--t-end", type=positive_float, default=None,
                   help="simulate only this long [s]")
    p.add_argument("--no-fast-forward", action="store_true",
                   help="every frame at real speed (default: 8x speed once the body has "
                        "settled)")
    _common(p, out_help="output GIF file", out_type=out_gif)
    p.set_defaults(target="mjx_balance.cli.animate:animate_command")

    p = sub.add_parser("report", help="HTML report: the study's experiments (both conventions) "
                                      "and the studies beyond it, with their saved tables")
    p.add_argument("--scale", choices=("tiny", "default", "dense"), default="default",
                   help="tiny: 2 s runs on tiny grids (tests); default: the study's table and "
                        "coarse region maps; dense: dense region maps (GPU)")
    p.add_argument("--backend", choices=("mjx", "reference"), default=None,
                   help="batch function of the table and region maps (default: mjx; tiny: reference)")
    p.add_argument("--studies", default="all",
                   help="comma list of studies (ankle_only, backward, delay, older_adult, "
                        "recovery_definition, push_height), 'all' or 'none'")
    p.add_argument("--conventions", default=None, help="experiments' conventions (default: paper,joint)")
    p.add_argument("--sweeps", type=input_folder, default=None,
                   help="folder of the study sweep definitions (default: the shipped ones, "
                        "mjx_balance/sweeps/)")
    p.add_argument("--html-only", action="store_true",
                   help="redraw figures and report.html from the tables saved in --out")
    _cluster(p)
    _physics(p)
    p.add_argument("--convention", choices=CONVENTIONS, default=None,
                   help="the studies' convention (default: the configuration's, 'paper'); the "
                        "study's experiments run every convention of --conventions")
    p.add_argument("--config", type=input_file, default=None,
                   help="TOML configuration file (body, controller, scenario)")
    p.add_argument("--set", type=setting, action="append", default=None,
                   metavar="SECTION.KEY=VALUE",
                   help="override one value of the configuration (repeatable; see sweep --help)")
    p.add_argument("--out", type=out_folder, required=True,
                   help="output folder (tables, figures, report.html)")
    p.set_defaults(target="mjx_balance.cli.report:report_command")

    p = sub.add_parser("model", help="write the MJCF (MuJoCo XML) of the configured body (its "
                                     "time step: scenario.physics_dt)")
    _config_options(p)
    p.add_argument("--out", type=out_file, required=True, help="output MJCF file, e.g. body.xml")
    p.set_defaults(target="mjx_balance.cli.model:model_command")

    p = sub.add_parser("view", help="replay one push in MuJoCo's interactive (passive) viewer "
                                    "(needs a display)")
    p.add_argument("--force", type=finite_float, required=True, help="push force [N]")
    p.add_argument("--duration", type=nonnegative_float, default=0.1, help="push duration [s]")
    p.add_argument("--t-end", type=positive_float, default=None,
                   help="simulate only this long [s] (default: the configuration's t_end)")
    p.add_argument("--speed", type=positive_float, default=1.0,
                   help="playback speed (1: real time)")
    p.add_argument("--loop", action="store_true", help="replay until the viewer is closed")
    _config_options(p)
    p.set_defaults(target="mjx_balance.cli.model:view_command")
    return parser


def use_host_cores() -> None:
    """Give XLA's CPU platform one device per core (a power of two, at most 8) before JAX
    starts, so that the batched rollout, which shards each batch over the local devices, keeps
    every core busy: XLA runs one device's rollout on one thread (BENCHMARKS.md, "Devices").
    Skipped when XLA_FLAGS already sets a host device count, when JAX is already imported, or
    with MJX_BALANCE_HOST_DEVICES=1 (any value sets the count)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_force_host_platform_device_count" in flags or "jax" in sys.modules:
        return
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    wanted = int(os.environ.get("MJX_BALANCE_HOST_DEVICES", min(cores, 8)))
    count = 1 << (max(1, wanted).bit_length() - 1)
    if count > 1:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={count}".strip()


class ConsoleHandler(logging.Handler):
    """Messages of the command line: information on stdout (the streams of the moment, so that
    a caller's redirection sees them), warnings and errors on stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            stream = sys.stdout if record.levelno < logging.WARNING else sys.stderr
            stream.write(self.format(record) + "\n")
            stream.flush()
        except Exception:  # noqa: BLE001 - logging's own convention
            self.handleError(record)


def verbosity(args: argparse.Namespace) -> int:
    """-1 with -q, 1 with -v, else 0 (-q wins)."""
    return -1 if getattr(args, "quiet", 0) else (1 if getattr(args, "verbose", 0) else 0)


def progress_enabled(args: argparse.Namespace) -> bool:
    """Progress bars: on unless -q."""
    return verbosity(args) >= 0


def _logging(level: int):
    """Route the package's messages to the console at ``level`` for one command; returns a
    function that puts the logger back as it was."""
    logger = logging.getLogger("mjx_balance")
    saved = (logger.level, logger.propagate)
    handler = ConsoleHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False

    def restore() -> None:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]
    return restore


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    use_host_cores()
    deterministic_flags()
    if getattr(args, "no_cache", False):
        from ..runtime import cache

        cache.disable()
    restore = _logging({-1: logging.WARNING, 0: logging.INFO, 1: logging.DEBUG}[verbosity(args)])
    try:
        from ..store.folder import run_context

        words = sys.argv[1:] if argv is None else list(argv)
        with run_context(command=" ".join(shlex.quote(w) for w in ["mjx-balance", *words])):
            return _run(args)
    finally:
        restore()


def _run(args: argparse.Namespace) -> int:
    module, func = args.target.split(":")
    command = getattr(importlib.import_module(module), func)
    try:
        return int(command(args) or 0)
    except ParameterError as exc:
        print(f"mjx-balance: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a failure during the work: a refused write, a full disk
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"mjx-balance: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
