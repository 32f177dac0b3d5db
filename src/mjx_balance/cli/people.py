"""``mjx-balance people`` (the people scorecard, ``mjx_balance.studies.people``) and
``mjx-balance pull`` (people's waist pull, ``mjx_balance.studies.pull``).

The parser is built without the library (``--help`` stays light); the command imports it when
it runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .common import in_folder, load_run_config, planner
from .options import (
    common_options,
    number_within,
    out_folder,
    slots_option,
    wait_option,
    yes_option,
)

MAX_RAMP = 600.0  # s: a rise time beyond any window this tool runs (the window checks it too)
ramp_seconds = number_within(0.0, MAX_RAMP, "s")  # a pull's rise time
resolution_newtons = number_within(0.01, 10.0, "N")  # a bracket width


def add_parser(sub: Any) -> None:
    """The ``people`` sub-command's options (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "people",
        help="the people scorecard: every published measure of people's balance recovery "
        "(the people reference) beside what the shipped human bodies (human, human_older) "
        "predict by lean and release and the held waist pull, with agreement within 2 SD "
        "and the measured reason of every difference (people.csv, people_limits.csv, "
        "people.png)",
    )
    slots_option(p)
    wait_option(p)
    yes_option(p)
    p.add_argument(
        "--out",
        type=out_folder,
        required=True,
        help="output folder: people.csv (the scorecard), people_limits.csv (every limit of "
        "every body), people.png, manifest.json",
    )
    p.set_defaults(target="mjx_balance.cli.people:people_command")
    add_pull_parser(sub)


def add_pull_parser(sub: Any) -> None:
    """The ``pull`` sub-command's options."""
    p = sub.add_parser(
        "pull",
        help="the waist pull (DePasquale & Toscano 2009's spring-scale test): the largest "
        "pull at the hip, rising over --ramp seconds and then held to the window's end, "
        "that the body withstands with its feet in place, forward and backward, in N and "
        "in %% of body weight (pull.csv)",
    )
    p.add_argument(
        "--ramp",
        type=ramp_seconds,
        default=5.0,
        help="the pull's rise time [s] before it is held (default 5; 0: applied at once; "
        "at most the window, scenario.t_end)",
    )
    p.add_argument(
        "--resolution",
        type=resolution_newtons,
        default=0.5,
        help="width of the limits' final brackets [N] (default 0.5)",
    )
    slots_option(p)
    wait_option(p)
    yes_option(p)
    common_options(p, out_help="output folder: pull.csv (the limits), manifest.json")
    p.set_defaults(target="mjx_balance.cli.people:pull_command")


def people_command(args: argparse.Namespace) -> int:
    """The scorecard in --out: ``mjx_balance.people`` with the options resolved."""
    from .. import api  # lazy: JAX, MuJoCo; not for --help

    out = Path(args.out)

    def work() -> None:
        api.people(
            out=out,
            slots=args.slots,
            wait=getattr(args, "wait", False),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock


def pull_command(args: argparse.Namespace) -> int:
    """The limits in --out: ``mjx_balance.waist_pull`` with the options resolved (every input
    checked before the folder is touched, the plan line, the lock)."""
    from .. import api  # lazy: JAX, MuJoCo; not for --help

    config = load_run_config(args)
    out = Path(args.out)

    def work() -> None:
        api.waist_pull(
            config,
            resolution=args.resolution,
            ramp=args.ramp,
            slots=args.slots,
            out=out,
            wait=getattr(args, "wait", False),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock
