"""``mjx-balance lean``: people's lean-and-release protocol (``mjx_balance.studies.lean``).

The parser is built without the library (``--help`` stays light); the command imports it when
it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .common import in_folder, load_run_config, planner
from .options import common_options, number_within, slots_option, wait_option, yes_option


resolution_degrees = number_within(0.001, 1.0, "degrees")  # a bracket width


def add_parser(sub: Any) -> None:
    """The ``lean`` sub-command's options (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "lean",
        help="lean and release (Robinovitch et al. 2002): the largest lean held still and the "
        "largest lean released from rest that recovers with the feet in place, beside "
        "the people reference's measures of that protocol (lean.csv, lean_limits.csv)",
    )
    p.add_argument(
        "--resolution",
        type=resolution_degrees,
        default=0.05,
        help="width of the dynamic limit's final bracket [deg] (default 0.05)",
    )
    slots_option(p)
    wait_option(p)
    yes_option(p)
    common_options(
        p,
        out_help="output folder: lean.csv (people's measures beside ours, agreement within "
        "2 SD), lean_limits.csv (every limit), manifest.json",
    )
    p.set_defaults(target="mjx_balance.cli.lean:lean_command")


def lean_command(args: Any) -> int:
    """The limits in --out: ``mjx_balance.lean_release`` with the options resolved (every
    input checked before the folder is touched, the plan line, the lock)."""
    from .. import api  # lazy: JAX, MuJoCo; not for --help

    config = load_run_config(args)
    out = Path(args.out)

    def work() -> None:
        api.lean_release(
            config,
            resolution=args.resolution,
            slots=args.slots,
            out=out,
            wait=getattr(args, "wait", False),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock
