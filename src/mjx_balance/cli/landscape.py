"""``mjx-balance landscape``: recoverable area, sustained-push limit and mean recovery energy
over a grid of Q and R scales, with and without delay (``mjx_balance.studies.landscape``).

The parser is built without the library (``--help`` stays light); the command imports it when
it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..model.config_files import apply_overrides, with_convention
from ..studies.defaults import (
    DEFAULT_DELAYS,
    DEFAULT_SCALES,  # light
    DEFAULT_SWEEP_DURATIONS,
    DEFAULT_SWEEP_FORCES,
    DEFAULT_TABLE_FORCES,
)
from .common import base_config, chosen_physics, in_folder, planner, progress_enabled
from .options import (
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
    """The ``landscape`` sub-command's options (``sub.add_parser`` of ``main.build_parser``,
    which adds the common options, the defaults in the help and the epilog)."""
    p = sub.add_parser(
        "landscape",
        help="the weight landscape: recoverable area, sustained-push limit and "
        "mean recovery energy over a grid of Q and R scales, with and without "
        "delay; each (delay, Q scale, R scale) runs as compare runs a "
        "configuration, in DIR/<delay>/q<q>_r<r>/ (resumable), then "
        "landscape.csv, landscape.png (heatmaps), landscape.txt",
    )
    p.add_argument(
        "--sweep",
        type=sweep_file,
        default=None,
        help="sweep definition whose configuration and grid are the base (a TOML "
        "file or a shipped name, e.g. landscape_weights; its configuration goes "
        "on top of --config); default: the defaults and the default sweep's "
        "grid",
    )
    config_options(p)
    p.add_argument(
        "--q-scales", default=DEFAULT_SCALES, help="factors on controller.q_diag, comma list"
    )
    p.add_argument(
        "--r-scales", default=DEFAULT_SCALES, help="factors on controller.r_diag, comma list"
    )
    p.add_argument(
        "--delays",
        default=DEFAULT_DELAYS,
        help="delay settings, comma list in ms, a trailing c for the "
        "delay-compensated controller (controller.delay_compensation), "
        "e.g. 0,10,100c; each replaces the base's scenario.controller_delay",
    )
    p.add_argument(
        "--forces",
        default=None,
        help="start:stop:step or a comma list [N] (default: the --sweep file's, "
        f"else the default sweep's {DEFAULT_SWEEP_FORCES})",
    )
    p.add_argument(
        "--durations",
        default=None,
        help="start:stop:step or a comma list [s] (default: the --sweep file's, "
        f"else the default sweep's {DEFAULT_SWEEP_DURATIONS})",
    )
    p.add_argument(
        "--table-forces",
        default=None,
        help="forces of each setting's max-acting-time table [N] (default: the "
        f"--sweep file's, else {DEFAULT_TABLE_FORCES})",
    )
    engine_options(p)
    queue_option(p, "setting")
    wait_option(p)
    yes_option(p)
    format_option(p)
    figure_options(p)
    p.add_argument(
        "--out",
        type=out_folder,
        required=True,
        help="output folder: one sweep folder per setting, landscape.csv, "
        "landscape.png, landscape.txt",
    )
    p.set_defaults(target="mjx_balance.cli.landscape:landscape_command")


def landscape_command(args: Any) -> int:
    """Every setting's map and table, then landscape.csv, .png and .txt in --out:
    ``mjx_balance.landscape`` with the options resolved (every input checked before the
    folder is touched, the plan line, the lock)."""
    # lazy: the library (JAX, MuJoCo, pandas) loads when the command runs, not for --help
    from .. import api
    from ..runs import DEFAULT_SWEEP, load_sweep  # lazy: as above

    definition = load_sweep(args.sweep, base_config(args, overrides=False))
    # the command line wins: --set over the --config file and the sweep definition,
    # --convention over all
    config = with_convention(
        apply_overrides(definition.config, getattr(args, "set", None)),
        getattr(args, "convention", None),
    )

    def pick(given: Any, from_file: Any, fallback: Any) -> Any:
        return given if given is not None else (from_file if from_file is not None else fallback)

    out = Path(args.out)

    def work() -> None:
        api.landscape(
            config,
            out=out,
            forces=pick(args.forces, definition.forces, DEFAULT_SWEEP["forces"]),
            durations=pick(args.durations, definition.durations, DEFAULT_SWEEP["durations"]),
            q_scales=args.q_scales,
            r_scales=args.r_scales,
            delays=args.delays,
            table_forces=pick(
                args.table_forces,
                definition.table_forces if args.sweep else None,
                DEFAULT_TABLE_FORCES,
            ),
            slots=args.slots,
            full_length=args.full_length,
            physics=chosen_physics(args, definition),
            queue=args.queue,
            progress=progress_enabled(args),
            wait=getattr(args, "wait", False),
            format=getattr(args, "table_format", None),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock
