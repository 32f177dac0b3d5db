"""``mjx-balance sensitivity``: the reproduction table under every reading of the study
(``mjx_balance.studies.sensitivity``).

The parser is built without the library (``--help`` stays light); the command imports it when
it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .common import in_folder, load_run_config, planner, progress_enabled
from ..studies.defaults import DEFAULT_FORCES, READINGS  # light: no JAX
from .options import (
    cluster_option,
    common_options,
    engine_options,
    figure_options,
    wait_option,
    yes_option,
)


def add_parser(sub: Any) -> None:
    """The ``sensitivity`` sub-command's options (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "sensitivity",
        help="the robustness table under every reading of the study (paper/joint "
        "convention x plain/offset-free MPC, both energy definitions): each "
        "reading's table in DIR/<reading>/ (resumable), then "
        "sensitivity.csv (the spread per force), sensitivity.png, "
        "sensitivity.txt (what holds under every reading)",
    )
    p.add_argument(
        "--forces", default=DEFAULT_FORCES, help="table forces [N], start:stop:step or a comma list"
    )
    p.add_argument("--readings", default=",".join(READINGS), help="comma list of readings to run")
    engine_options(p)
    cluster_option(p)
    wait_option(p)
    yes_option(p)
    figure_options(p)
    common_options(
        p,
        out_help="output folder: one table folder per reading, sensitivity.csv, "
        "sensitivity.png, sensitivity.txt",
    )
    p.set_defaults(target="mjx_balance.cli.sensitivity:sensitivity_command")


def sensitivity_command(args: Any) -> int:
    """Every reading's table, then the spread: ``mjx_balance.sensitivity`` with the options
    resolved (every input checked first, the plan line, the lock)."""
    from .. import api  # lazy: JAX, MuJoCo; not for --help

    out = Path(args.out)
    readings = [r.strip() for r in args.readings.split(",") if r.strip()]

    def work() -> None:
        api.sensitivity(
            load_run_config(args),
            out=out,
            forces=args.forces,
            readings=readings,
            slots=args.slots,
            full_length=args.full_length,
            physics=args.physics or "auto",
            cluster=args.cluster,
            progress=progress_enabled(args),
            wait=getattr(args, "wait", False),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock
