"""The command line's shared pieces for building parsers: argument types, the help formatter,
the epilog and the flags several commands take.

Argument types return the parsed value or raise ArgumentTypeError with the rule (argparse then
prints its usage and ``mjx-balance CMD: error: argument --X: ...``, exit code 2). The flag
helpers add one group of options to a command's parser:

    conventions        -q, -v, --no-cache (before or after the command)
    config_options     --convention, --config, --set, --subject
    common_options     config_options and --out
    yes_option         --yes (work beyond the limit)
    wait_option        --wait (for another run's lock on --out)
    cluster_option     --cluster (a Dask cluster)
    engine_options     --full-length, --slots and physics_option
    physics_option     --physics (mjx, c or auto)

Light: building a parser imports neither JAX, MuJoCo, pandas nor numpy; the argument types
that need the library import it when they check a value.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import Any, Callable

from ..model.params import CONTROLLER_KINDS, CONVENTIONS, ParameterError
from ..model.config_files import parse_override
from ..model.subject import Subject, parse_subject
from ..studies import references

EPILOG = """exit codes: 0 success; 1 failure during the work (a refused write, a full disk, a run
that broke, a run whose scenarios diverged half or more); 2 bad usage (an unknown option, a bad
value or configuration), reported before any work and before anything is written; 130 Ctrl-C,
143 SIGTERM (what finished is kept: the same command resumes)."""


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


def number_within(low: float, high: float, unit: str) -> Callable[[str], float]:
    """An argument type: a finite number within [``low``, ``high``] ``unit``."""

    def parse(text: str) -> float:
        value = _number(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(
                f"must lie within [{low:g}, {high:g}] {unit}, got {text!r}"
            )
        return value

    parse.__doc__ = f"A finite number within [{low:g}, {high:g}] {unit}."
    return parse


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


MAX_INTEGER = 2**31 - 1  # every count of ours (slots, chunks, scenarios) is an int32 on device


def _integer(text: str, minimum: int) -> int:
    try:
        value = float(text.strip())  # "1e4" is a whole number too
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not (math.isfinite(value) and value.is_integer() and minimum <= value <= MAX_INTEGER):
        raise argparse.ArgumentTypeError(
            f"must be an integer >= {minimum} (at most {MAX_INTEGER:,}), got {text!r}"
        )
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


def reference_file(text: str) -> str:
    """A reference CSV file, or the name of a shipped one (``study``: studies.references)."""
    if text in references.SHIPPED:
        return text
    if text == "people" and not Path(text).exists():
        raise argparse.ArgumentTypeError(
            "the people reference holds people's protocols (lean and release, the waist "
            "pull), not a push table: mjx-balance people --out DIR scores it"
        )
    try:
        references.check_size(Path(text))  # before input_file reads it whole
        return input_file(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(
            f"{exc}; the shipped references: {', '.join(references.SHIPPED)}"
        ) from None


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
            f"{text!r} is not UTF-8 text (byte {exc.start}); expected a text file"
        ) from None
    return text


def sweep_file(text: str) -> str:
    """A sweep definition: a TOML file, or the name of one the package ships
    (``region_dense_paper``; ``mjx_balance/sweeps/``)."""
    from ..runs.definitions import find_sweep  # lazy: the runs floor loads JAX; not for --help

    path = Path(text)
    if not path.exists() and path.parent == Path("."):
        try:
            return str(find_sweep(text))
        except ParameterError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    return input_file(text)


def setting(text: str) -> str:
    """A --set SECTION.KEY=VALUE (its value is checked with the configuration)."""
    try:
        parse_override(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix(f"--set {text!r}: ")) from None
    return text


def controller_kind(text: str) -> str:
    """A --controller KIND: mpc, lqr, pd or package.module:factory (found when the
    configuration is checked)."""
    module, sep, name = text.partition(":")
    identifiers = module.replace(".", "_").isidentifier() and name.replace(".", "_").isidentifier()
    if text in CONTROLLER_KINDS or (sep and identifiers):
        return text
    raise argparse.ArgumentTypeError(
        f"expected {', '.join(CONTROLLER_KINDS)} or package.module:factory, got {text!r}"
    )


def controller_kinds(text: str) -> list[str]:
    """A --controllers LIST: comma-separated --controller KINDs, each named once."""
    kinds = [controller_kind(part.strip()) for part in text.split(",")]
    if len(set(kinds)) != len(kinds):
        raise argparse.ArgumentTypeError(f"a controller named twice in {text!r}")
    return kinds


class ControllerSetting(argparse.Action):
    """--controller KIND as ``--set controller.kind=KIND``, in the command line's order."""

    def __call__(self, parser: Any, namespace: Any, value: Any, option: Any = None) -> None:
        settings = list(getattr(namespace, "set", None) or [])
        namespace.set = settings + [f"controller.kind={value}"]


def subject(text: str) -> Subject:
    """A --subject height=H,mass=M[,sex=female][,ankle_strength=F][,hip_strength=F]."""
    try:
        return parse_subject(text)
    except ParameterError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix(f"--subject {text!r}: ")) from None


def convention_list(text: str) -> str:
    """A comma list of controller conventions (paper, joint), at least one."""
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise argparse.ArgumentTypeError(f"give one or more of {', '.join(CONVENTIONS)}")
    bad = [item for item in items if item not in CONVENTIONS]
    if bad:
        raise argparse.ArgumentTypeError(
            f"unknown {', '.join(bad)}; known: {', '.join(CONVENTIONS)}"
        )
    return ",".join(items)


def input_folder(text: str) -> str:
    """An existing folder (not the empty text, which names the working folder)."""
    if not text.strip() or not Path(text).is_dir():
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
    if path.is_symlink() and not path.exists():
        raise argparse.ArgumentTypeError(
            f"{text!r} is a symbolic link to a missing target ({os.readlink(path)!r})"
        )
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a folder")
    reason = _unwritable(path)
    if reason:
        raise argparse.ArgumentTypeError(f"cannot write {text!r}: {reason}")
    return text


def out_gif(text: str) -> str:
    """An output GIF file: a name ending in .gif, not a folder, in a place that can be written."""
    return _output_file(text, ".gif")


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


def cluster_spec(text: str) -> str:
    """A Dask cluster: local:N, a scheduler address or a scheduler file (runs/cluster.py)."""
    from ..runs.cluster import ClusterError, parse_cluster  # lazy: the runs floor loads JAX

    try:
        parse_cluster(text)
    except ClusterError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


# ---------------------------------------------------------------------------------------------
# The help formatter and the flags several commands share.


class HelpFormatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """Every option's default in its help ("(default: ...)"), unless the help already says it
    or there is none to say (no value, a flag); descriptions and epilogs as written."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if (
            "default" in text
            or action.default in (None, False, argparse.SUPPRESS)
            or not action.option_strings
        ):
            return text
        return text + " (default: %(default)s)"


def conventions(p: argparse.ArgumentParser) -> None:
    """-q, -v, --no-cache: accepted before or after the command (mjx-balance -q sweep ...)."""
    p.add_argument(
        "-q",
        "--quiet",
        action="count",
        default=argparse.SUPPRESS,
        help="only warnings and errors; no progress bars",
    )
    p.add_argument(
        "-v", "--verbose", action="count", default=argparse.SUPPRESS, help="debug messages too"
    )
    p.add_argument(
        "--no-cache",
        action="store_true",
        default=argparse.SUPPRESS,
        help="do not use JAX's persistent compilation cache (default: on, in "
        "$MJX_BALANCE_CACHE_DIR or the user's cache folder, "
        "~/.cache/mjx_balance/jax on Linux; MJX_BALANCE_CACHE_DIR=off turns it "
        "off too)",
    )


def conventions_parent() -> argparse.ArgumentParser:
    """A parent parser (``parents=[...]``) that gives a command the conventions' options."""
    parent = argparse.ArgumentParser(add_help=False)
    conventions(parent)
    return parent


def config_options(
    p: argparse.ArgumentParser, *, repeat: bool = False, convention_help: str | None = None
) -> None:
    """--convention, --config and --set: the run's configuration. ``repeat``: --config may be
    given more than once (compare's old form, where it named the configurations to compare;
    the command says what more than one means)."""
    p.add_argument(
        "--convention",
        choices=CONVENTIONS,
        default=None,
        help=convention_help or "controller convention (default: the configuration's, 'paper')",
    )
    if repeat:
        p.add_argument(
            "--config",
            type=sweep_file,
            action="append",
            default=None,
            metavar="FILE",
            help="base TOML configuration file (body, controller, scenario) that "
            "every configuration's values go on top of",
        )
    else:
        p.add_argument(
            "--config",
            type=sweep_file,
            default=None,
            help="TOML configuration file (body, controller, scenario), or the name of one "
            "the package ships (human, human_older: the human bodies, docs/model.md)",
        )
    p.add_argument(
        "--set",
        type=setting,
        action="append",
        default=None,
        metavar="SECTION.KEY=VALUE",
        help="override one value of the configuration, e.g. --set "
        "controller.horizon=30 --set scenario.t_end=6 (repeatable; checked "
        "as in a TOML file; applied after --config and a sweep definition)",
    )
    p.add_argument(
        "--controller",
        type=controller_kind,
        action=ControllerSetting,
        dest="controller_kind",
        default=None,
        metavar="KIND",
        help="the controller that balances the body: mpc (the default: the study's "
        "constrained MPC), lqr, pd, or package.module:factory, your own "
        "(docs/model.md, 'Bring your own controller'); the same as --set "
        "controller.kind=KIND",
    )
    p.add_argument(
        "--subject",
        type=subject,
        default=None,
        metavar="height=H,mass=M[,sex=female]",
        help="a person's body from de Leva's (1996) segment table: stature H [m], "
        "mass M [kg], sex male (default) or female, optional ankle_strength "
        "and hip_strength factors (default 1) on the mass-scaled torque "
        "bounds, optional age [yr] (that age's and sex's strength and timing on "
        "--config human: docs/model.md, 'Age and sex'); replaces the --config file's "
        "[subject] and goes under a sweep definition and --set (docs/model.md, 'Subjects')",
    )


def common_options(
    p: argparse.ArgumentParser,
    out_required: bool = True,
    out_help: str = "output folder",
    out_type=out_folder,
) -> None:
    """:func:`config_options` and --out."""
    config_options(p)
    p.add_argument("--out", type=out_type, required=out_required, default=None, help=out_help)


def yes_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--yes",
        action="store_true",
        help="run even when the planned work is beyond the limit (2,000,000 scenarios "
        "or an estimated 24 h on a 2-core CPU)",
    )


def wait_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--wait",
        action="store_true",
        help="when another run holds the --out folder, wait for it to end "
        "(default: refuse at once, naming that run)",
    )


def cluster_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--cluster",
        type=cluster_spec,
        default=None,
        metavar="SPEC",
        help="run the scenarios on a Dask cluster (a region map's chunks, a table's "
        "bisection calls): local:N (N worker processes "
        "here), a scheduler address (tcp://host:8786) or a scheduler file "
        '(.json); needs pip install "mjx_balance[cluster]" (docs/cluster.md)',
    )


def slots_option(p: argparse.ArgumentParser, default: str = "", more: str = "") -> None:
    """--slots: the engine's scenarios in flight per device (``default``: more on the default,
    ``more``: the command's own words after it)."""
    p.add_argument(
        "--slots",
        type=positive_int,
        default=None,
        help=f"scenarios in flight per device (default: 32 on a CPU, 4096 on a GPU{default}){more}",
    )


def engine_options(p: argparse.ArgumentParser) -> None:
    """Options of the continuous-batching engine (sweep, table, bench)."""
    p.add_argument(
        "--full-length",
        action="store_true",
        help="run every scenario to t_end (no early stop of certified recoveries; "
        "falls still end a scenario), for validation",
    )
    slots_option(
        p,
        "; 64 on the C path",
        "; results are bit-identical for any chunk, device count or order at one slot count, "
        "so a sweep folder keeps the count it started with",
    )
    physics_option(p)


def queue_option(p: argparse.ArgumentParser, maps: str, auto: bool = False) -> None:
    """--queue of the commands that run several region maps (``maps``: what they are);
    ``auto``: the default is auto (``studies.cohort.resolved_queue``), else each."""
    default = "auto" if auto else "each"
    p.add_argument(
        "--queue",
        choices=("auto", "each", "one") if auto else ("each", "one"),
        default=default,
        help=(
            "auto (default): one on the MJX path without a cluster, each "
            "otherwise, or the queue a resumed folder was started with; "
            if auto
            else ""
        )
        + f"each{'' if auto else ' (default)'}: every {maps}'s map its own "
        f"engine run (the bytes of sweep --subject); one: every {maps}'s map "
        "through one engine queue with per-lane bodies (MJX only; the maps "
        "differ from each's by float rounding; docs/engine.md, "
        '"Per-lane bodies")',
    )


def physics_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--physics",
        choices=("auto", "mjx", "c"),
        default=None,
        help="physics of the batched closed loop: mjx (MuJoCo MJX in JAX, float32), "
        "c (MuJoCo C on a thread pool, float64, the reference's physics; the "
        "ADMM stays in JAX) or auto (the faster on this machine: "
        "docs/engine.md; default: a --sweep file's [sweep] physics, else auto); "
        "a sweep folder keeps the path it started with",
    )


# ---------------------------------------------------------------------------------------------
# Table exports (--format): every table also as CSV and/or parquet (store.files.export_tables)
TABLE_FORMATS = ("csv", "parquet", "both")  # store.files.FORMATS (the parser stays light)


def format_option(p: argparse.ArgumentParser) -> None:
    """``--format csv|parquet|both``: every table also in that format, beside its own file."""
    p.add_argument(
        "--format",
        choices=TABLE_FORMATS,
        default=None,
        dest="table_format",
        help="also write every table as CSV (full precision, units in a "
        "NAME.units.csv beside it), as parquet (units in its schema), or both, "
        "under the same name beside the table's own file, which stays "
        "(default: each table in its own format only: parquet for the region, "
        "scenarios, time series and basin, CSV for table, summary, compare and "
        "landscape; docs/outputs.md, 'Units and exports')",
    )


def write_exports(out: str | Path, args: argparse.Namespace) -> None:
    """The --format copies of every table in ``out`` (and its sub-folders), and copies of an
    earlier --format that are older than their table written again; says which."""
    import logging

    from ..store.files import export_tables_said  # lazy: the store floor loads pandas

    export_tables_said(
        out, getattr(args, "table_format", None), logging.getLogger("mjx_balance").info
    )


# ---------------------------------------------------------------------------------------------
# Figures (--figure-format, --figure-size): figures.style, applied by main around the command


def figure_options(p: argparse.ArgumentParser) -> None:
    """``--figure-format png|svg|pdf`` and ``--figure-size screen|one-column|two-column``."""
    from ..figures.style import FIGURE_FORMATS, FIGURE_SIZES  # lazy: light (no matplotlib)

    p.add_argument(
        "--figure-format",
        choices=FIGURE_FORMATS,
        default="png",
        help="file format of the figures the command writes: png, or vector svg or "
        "pdf (region.png becomes region.svg, ...)",
    )
    p.add_argument(
        "--figure-size",
        choices=tuple(FIGURE_SIZES),
        default="screen",
        help="figure size: screen (each figure's own size), one-column (3.5 in, "
        "89 mm wide) or two-column (7.2 in, 183 mm) for a paper; fonts 7 to "
        "9 pt, every text inside the figure (docs/outputs.md, 'Figures')",
    )
