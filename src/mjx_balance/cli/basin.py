"""``mjx-balance basin``: the recovery basin over (x_com, v_com) (``mjx_balance.studies.basin``).

The parser is built without the library (``--help`` stays light); the command imports it when
it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .common import in_folder, load_run_config, planner, progress_enabled
from ..studies.defaults import DEFAULT_V, DEFAULT_X, POSTURES  # light: no JAX
from .options import (
    common_options,
    figure_options,
    format_option,
    slots_option,
    wait_option,
    yes_option,
)


def add_parser(sub: Any) -> None:
    """The ``basin`` sub-command's options (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "basin",
        help="the recovery basin: which initial CoM states (x_com, v_com) recover "
        "with no push, with the foot's edges, the capture-point bound and the "
        "push map's end-of-push states (basin.parquet, basin.png; resumable)",
    )
    p.add_argument(
        "--x-com",
        default=DEFAULT_X,
        help="CoM positions relative to the ankle [m], start:stop:step or a list",
    )
    p.add_argument(
        "--v-com", default=DEFAULT_V, help="CoM velocities [m/s], start:stop:step or a list"
    )
    p.add_argument(
        "--posture",
        choices=tuple(POSTURES),
        default="rigid",
        help="posture family realising each (x_com, v_com): "
        + "; ".join(f"{k}: {v}" for k, v in POSTURES.items()),
    )
    p.add_argument(
        "--push-forces",
        default="10:150:20",
        help="forces [N] of the push cells whose end-of-push states are drawn "
        "(reference runs; 'none': no push cells)",
    )
    p.add_argument(
        "--push-durations", default="0.1,0.2,0.5", help="durations [s] of those push cells"
    )
    slots_option(p)
    p.add_argument(
        "--full-length",
        action="store_true",
        help="run every cell to t_end (no early stop of certified recoveries)",
    )
    wait_option(p)
    yes_option(p)
    format_option(p)
    figure_options(p)
    common_options(
        p,
        out_help="output folder: basin.parquet, basin.png, pushes.csv, "
        "basin_cells/ (finished cells, for resuming)",
    )
    p.set_defaults(target="mjx_balance.cli.basin:basin_command")


def basin_command(args: Any) -> int:
    """The basin map in --out: ``mjx_balance.basin`` with the options resolved (every input
    checked before the folder is touched, the plan line, the lock)."""
    from .. import api  # lazy: JAX, MuJoCo; not for --help

    config = load_run_config(args)
    pushes = (
        None
        if str(args.push_forces).strip().lower() == "none"
        else (args.push_forces, args.push_durations)
    )
    if pushes is None:  # no push cells: the durations are still checked, as every option is
        from ..runs.grid import check_durations, parse_grid  # lazy: the runs floor loads JAX

        check_durations(
            parse_grid(args.push_durations, "push durations"),
            config.scenario.t_end,
            "push durations",
            physics_dt=config.scenario.physics_dt,
        )
    out = Path(args.out)

    def work() -> None:
        api.basin(
            config,
            out=out,
            x_com=args.x_com,
            v_com=args.v_com,
            posture=args.posture,
            pushes=pushes,
            slots=args.slots,
            full_length=args.full_length,
            progress=progress_enabled(args),
            format=getattr(args, "table_format", None),
            wait=getattr(args, "wait", False),
            plan=planner(args),
        )

    return in_folder(out, work, lock=False)  # the API takes the folder's lock
