"""``mjx-balance people``: the people scorecard (``mjx_balance.studies.people``).

The parser is built without the library (``--help`` stays light); the command imports it when
it runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .common import in_folder, planner
from .options import out_folder, slots_option, wait_option, yes_option


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
