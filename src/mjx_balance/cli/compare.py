"""``mjx-balance compare``: several configurations on one grid, one figure and one table.

The variants are whole configurations (positional FILEs, or --variant NAME=FILE); each one's
values go on top of the base --config (default: the defaults), then --set and --convention on
top of each variant."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..model.params import Config, ParameterError
from ..model.config_files import apply_overrides, with_convention
from ..studies.defaults import (  # light
    DEFAULT_SWEEP_DURATIONS,
    DEFAULT_SWEEP_FORCES,
    DEFAULT_SWEEP_TABLE_FORCES,
)
from .common import in_folder, planner, progress_enabled
from .options import (
    controller_kinds,
    cluster_option,
    config_options,
    engine_options,
    queue_option,
    figure_options,
    format_option,
    out_folder,
    sweep_file,
    wait_option,
    yes_option,
)


def add_parser(sub: Any) -> None:
    """The ``compare`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "compare",
        help="several configurations on one grid: their recovery "
        "boundaries in one figure, their numbers in one table",
    )
    p.add_argument(
        "variants",
        nargs="*",
        type=sweep_file,
        metavar="FILE",
        help="the configurations to compare: TOML configuration files or sweep "
        "definitions (a file or a shipped name such as study_offset_free: its "
        "configuration, not its grid); each one's folder is the file's stem",
    )
    p.add_argument(
        "--variant",
        type=variant,
        action="append",
        default=None,
        metavar="NAME=FILE",
        help="a configuration to compare under a name of its "
        "own (repeatable; after the positional FILEs)",
    )
    config_options(p, repeat=True)
    p.add_argument(
        "--controllers",
        type=controller_kinds,
        default=None,
        metavar="LIST",
        help="every configuration under each of these controllers, comma-separated: "
        "mpc, lqr, pd, package.module:factory (docs/model.md, 'Bring your own "
        "controller'); without FILEs, the base configuration under each, "
        "named by its kind",
    )
    p.add_argument(
        "--forces",
        default=None,
        help="start:stop:step or a comma list [N] (default: the default sweep's, "
        f"{DEFAULT_SWEEP_FORCES})",
    )
    p.add_argument(
        "--durations",
        default=None,
        help="start:stop:step or a comma list [s] (default: the default sweep's, "
        f"{DEFAULT_SWEEP_DURATIONS})",
    )
    p.add_argument(
        "--table-forces",
        default=None,
        help="forces of each configuration's max-acting-time table [N] (default: "
        f"the default sweep's, {DEFAULT_SWEEP_TABLE_FORCES})",
    )
    engine_options(p)
    queue_option(p, "configuration")
    cluster_option(p)
    wait_option(p)
    yes_option(p)
    format_option(p)
    figure_options(p)
    p.add_argument(
        "--out",
        type=out_folder,
        required=True,
        help="output folder: one sweep folder per configuration, compare.csv, compare.png",
    )
    p.set_defaults(target="mjx_balance.cli.compare:compare_command")


def variant(text: str) -> tuple[str, str]:
    """A --variant NAME=FILE: (name, file), the file checked as a positional FILE is."""
    name, sep, path = text.partition("=")
    if not sep or not name.strip() or not path.strip():
        raise argparse.ArgumentTypeError(f"give NAME=FILE, got {text!r}")
    if "/" in name or "\\" in name or name.strip() != name:
        raise argparse.ArgumentTypeError(
            f"{name!r} is not a folder name (letters, digits, '.', '_', '-')"
        )
    return name, sweep_file(path)


def variants_and_base(args: Any) -> tuple[list[tuple[str | None, str]], str | None]:
    """([(name or None, file)], base file or None) from the options."""
    variants = [(None, path) for path in args.variants or []] + list(args.variant or [])
    configs = args.config or []
    if not variants and not getattr(args, "controllers", None):
        raise ParameterError(
            "compare needs at least one configuration: compare FILE ... "
            "or --variant NAME=FILE (--config names the base configuration)"
        )
    if len(configs) > 1:
        raise ParameterError(
            "--config: give one base configuration (the configurations to "
            "compare are the FILEs or --variant NAME=FILE)"
        )
    return variants, (configs[0] if configs else None)


def compare_command(args: Any) -> int:
    """Each variant's region map and table in OUT/<name>/, then compare.csv and compare.png:
    ``mjx_balance.compare`` with the options resolved (its checks, plan line and lock)."""
    from .. import api  # lazy: the library loads JAX; not for --help
    from ..studies.compare import load_base, load_configs  # lazy: as above

    variants, base = variants_and_base(args)
    base_config = load_base(base, getattr(args, "subject", None))
    if variants:
        configs = load_configs(
            [path for _, path in variants],
            base=base_config,
            names=[name for name, _ in variants],
        )
    else:  # --controllers alone: the base configuration under each
        configs = {"base": base_config or Config()}
    configs = {
        name: with_convention(apply_overrides(config, args.set), args.convention)
        for name, config in configs.items()
    }
    out = Path(args.out)

    def work() -> None:
        api.compare(
            configs,
            out=out,
            controllers=args.controllers,
            forces=args.forces,
            durations=args.durations,
            table_forces=args.table_forces,
            slots=args.slots,
            full_length=args.full_length,
            physics=args.physics or "auto",
            cluster=args.cluster,
            queue=args.queue,
            progress=progress_enabled(args),
            format=getattr(args, "table_format", None),
            wait=getattr(args, "wait", False),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock
