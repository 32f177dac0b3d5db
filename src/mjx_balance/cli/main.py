"""``mjx-balance``: the parser, built from the command modules, and :func:`main`, which sets
up the process (host devices, XLA flags, compilation cache, logging) and runs one command.

Each command module has ``add_parser(sub)``, which defines its sub-command(s) and sets its
handler (``target``: ``"mjx_balance.cli.MODULE:FUNCTION"``, looked up when the command runs).
Command modules are light at import: they import the library inside their command functions,
so building the parser (and ``--help``) loads neither JAX, MuJoCo nor pandas, and
:func:`use_host_cores` still sees JAX not yet imported when a command starts.

Exit codes: 0 success, 1 failure during the work, 2 bad usage (options.EPILOG).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import shlex
import sys
import warnings

from ..model.params import ParameterError, ParameterWarning, forget_warnings
from ..runtime import signals
from ..runtime.version import InstallError
from ..runtime.xla import deterministic_flags
from . import (
    animate,
    basin,
    bench,
    cohort,
    compare,
    explore,
    landscape,
    lean,
    model,
    people,
    report,
    sensitivity,
    simulate,
    sweep,
)
from .common import verbosity
from .options import EPILOG, HelpFormatter, conventions, conventions_parent

# In the order of ``mjx-balance --help``: sweep adds sweep and table, model adds model and view.
COMMANDS = (
    simulate,
    bench,
    sweep,
    compare,
    cohort,
    landscape,
    basin,
    lean,
    people,
    sensitivity,
    animate,
    report,
    explore,
    model,
)


class _Version(argparse.Action):
    """--version: the package's, JAX's, jaxlib's and MuJoCo's versions (no import of JAX)."""

    def __init__(
        self,
        option_strings,
        dest=argparse.SUPPRESS,
        default=argparse.SUPPRESS,
        help="print the versions of mjx_balance, JAX, jaxlib and MuJoCo and exit; with "
        "--verbose, everything a result depends on (versions, XLA flags, CPU ISA, devices)",
    ):
        super().__init__(option_strings, dest, nargs=0, default=default, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text())
        parser.exit(0)


def version_text() -> str:
    """One line: ``mjx-balance 0.1.0 (jax 0.10.2, jaxlib 0.10.2, mujoco 3.17.0, ...)``."""
    from ..store.provenance import versions  # lazy: the store floor loads pandas; only --version

    v = versions()
    return (
        f"mjx-balance {v['package']} (jax {v['jax']}, jaxlib {v['jaxlib']}, "
        f"mujoco {v['mujoco']}, mujoco-mjx {v['mujoco_mjx']}, python {v['python']})"
    )


# An argument that starts with a minus and a digit is a value, not an option: argparse's own
# rule takes only plain numbers ("-20", "-0.5"), so "--pairs -20:0.1", "--v-com -0.3:0.3:0.05"
# or "--forces -1e3" would end in "expected one argument" (no option of ours starts so).
NEGATIVE_VALUE = re.compile(r"^-\.?\d")


def build_parser() -> argparse.ArgumentParser:
    # allow_abbrev=False: one spelling per option (a prefix such as --force is not --forces)
    parser = argparse.ArgumentParser(
        prog="mjx-balance",
        formatter_class=HelpFormatter,
        epilog=EPILOG,
        allow_abbrev=False,
        description="Standing-balance recovery under constrained MPC: pushes, sweeps, tables.",
    )
    parser.add_argument("--version", action=_Version)
    conventions(parser)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    parent = conventions_parent()
    add_parser = sub.add_parser

    def command(name: str, **kwargs) -> argparse.ArgumentParser:
        p = add_parser(
            name,
            formatter_class=HelpFormatter,
            epilog=EPILOG,
            allow_abbrev=False,
            parents=[parent],
            description=kwargs.get("help"),
            **kwargs,
        )
        p._negative_number_matcher = NEGATIVE_VALUE
        return p

    sub.add_parser = command  # type: ignore[method-assign]  # on purpose: every command gets the conventions' options, defaults, epilog
    for module in COMMANDS:
        module.add_parser(sub)
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
        except (OSError, ValueError, AttributeError):
            pass  # a closed or full stream: the run goes on, its results are in files
        except Exception:
            self.handleError(record)


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


def say_error(text: str) -> None:
    """One line on stderr, if there is a stderr to write to (a closed one is not an error)."""
    try:
        print(f"mjx-balance: error: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None, *, hold_signals_after: bool = False) -> int:
    """Run one command; its exit code. ``hold_signals_after``: the process ends after this
    call (the console script), so SIGINT and SIGTERM are ignored from the end of the work on
    (runtime/signals.honoured)."""
    # Figures are written to files: matplotlib's file-only backend, unless the user chose one
    # (the library itself never switches backends: a notebook keeps its inline figures).
    os.environ.setdefault("MPLBACKEND", "Agg")
    # before the parser: an argument's check may import JAX (``--sweep NAME`` looks the name up
    # in the runs floor), and XLA reads its flags when JAX starts
    use_host_cores()
    deterministic_flags()
    words = sys.argv[1:] if argv is None else list(argv)
    if "--version" in words and {"-v", "--verbose"} & set(words):
        # the environment as a run would have it: after the flags above (this starts JAX)
        from ..store.provenance import environment, environment_text  # lazy: pandas, JAX

        print(environment_text(environment()))
        return 0
    args = build_parser().parse_args(argv)
    if getattr(args, "no_cache", False):
        from ..runtime import cache  # lazy: after use_host_cores, before JAX starts

        cache.disable()
    restore = _logging({-1: logging.WARNING, 0: logging.INFO, 1: logging.DEBUG}[verbosity(args)])
    try:
        # lazy: after use_host_cores (pandas, not --help)
        from ..store.provenance import run_context

        # SIGINT and SIGTERM raise Interrupted / Terminated wherever they land, and a signal
        # whose exception the runtime drops (a GC callback) still ends the work (signals.py)
        with (
            signals.honoured(hold_after=hold_signals_after),
            run_context(command=" ".join(shlex.quote(w) for w in ["mjx-balance", *words])),
            warnings.catch_warnings(),
        ):
            # a never-binding limit is logged where it is found (params.warn_parameter): the
            # Python warning's own copy on stderr would say it twice
            warnings.simplefilter("ignore", ParameterWarning)
            forget_warnings()
            return _run(args)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM, wherever the work was
        if not isinstance(exc, signals.Interrupted):  # raised by Python's own SIGINT handler
            exc = signals.Interrupted()
        say_error(
            f"interrupted ({exc.name}); what finished is kept: run the same command to resume"
        )
        return exc.code
    finally:
        restore()


def console() -> None:
    """The ``mjx-balance`` script: :func:`main`, then the process's exit with its status; a
    signal during the interpreter's clean-up at exit (JAX's) is ignored, not printed."""
    sys.exit(main(hold_signals_after=True))


def _run(args: argparse.Namespace) -> int:
    from ..figures.style import figure_style  # lazy: light; after the parser (--help)

    module, func = args.target.split(":")
    command = getattr(importlib.import_module(module), func)
    try:
        # --figure-format / --figure-size of a command that writes figures (the defaults else)
        with figure_style(getattr(args, "figure_format", None), getattr(args, "figure_size", None)):
            return int(command(args) or 0)
    except ParameterError as exc:
        say_error(str(exc))
        return 2
    except RuntimeError as exc:
        from ..measures.outcomes import NotAResult  # lazy: numpy; only after a failure

        if not isinstance(exc, (NotAResult, InstallError)):
            raise
        say_error(str(exc))  # not results, or an install that cannot run the physics
        return 1
    except OSError as exc:  # a failure during the work: a refused write, a full disk
        where = f"{exc.filename}: " if exc.filename else ""
        say_error(f"{where}{exc.strerror or exc}")
        return 1


if __name__ == "__main__":
    console()
