"""``mjx-balance report``: run (or resume) the report's experiments and studies, then write
DIR/report.html (report.run_report, report.build_report)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from ..model.params import CONVENTIONS, ParameterError
from .common import in_folder, load_run_config, progress_enabled
from .options import (
    cluster_option,
    config_options,
    convention_list,
    input_folder,
    out_folder,
    physics_option,
    reference_file,
)


def add_parser(sub: Any) -> None:
    """The ``report`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "report",
        help="HTML report: the study's experiments (both conventions) "
        "and the studies beyond it, with their saved tables; its "
        "figures are PNG at screen size, embedded in the page (no "
        "--figure-format / --figure-size: the figure commands "
        "take them)",
    )
    p.add_argument(
        "--scale",
        choices=("tiny", "default", "dense"),
        default="default",
        help="tiny: 2 s runs on tiny grids (tests); default: the study's table and "
        "coarse region maps; dense: dense region maps (GPU)",
    )
    p.add_argument(
        "--backend",
        choices=("mjx", "reference"),
        default=None,
        help="batch function of the table and region maps (default: mjx; tiny: reference)",
    )
    p.add_argument(
        "--studies",
        default="all",
        help="comma list of studies (ankle_only, backward, delay, older_adult, "
        "recovery_definition, controllers, push_height), 'all' or 'none'",
    )
    p.add_argument(
        "--sweeps",
        type=input_folder,
        default=None,
        help="folder of the study sweep definitions (default: the shipped ones, "
        "mjx_balance/sweeps/)",
    )
    p.add_argument(
        "--html-only",
        action="store_true",
        help="redraw figures and report.html from the tables saved in --out",
    )
    p.add_argument(
        "--reference",
        type=reference_file,
        action="append",
        default=None,
        metavar="FILE",
        help="reference table CSV (repeatable): scored beside the report's tables "
        "in its first section and DIR/scorecard.csv; its forces join the "
        "table (kept in DIR/references/; docs/outputs.md, 'Reference files'). "
        "The study's Table 2 (shipped: 'study') is scored in the paper "
        "convention without being asked",
    )
    cluster_option(p)
    physics_option(p)
    group = p.add_argument_group(
        "configuration and conventions",
        "--conventions (a list): the study's experiments run under each of them;\n"
        "--convention (one, as in every other command): the studies beyond the study;\n"
        "--config and --set: the base configuration of both",
    )
    group.add_argument(
        "--conventions",
        type=convention_list,
        default=",".join(CONVENTIONS),
        help="the experiments' conventions, a comma list",
    )
    config_options(
        group, convention_help="the studies' convention (default: the configuration's, 'paper')"
    )
    p.add_argument(
        "--out", type=out_folder, required=True, help="output folder (tables, figures, report.html)"
    )
    p.set_defaults(target="mjx_balance.cli.report:report_command")


def report_command(args: Any) -> int:
    """Without --html-only: run everything missing in --out and say where the tables are (on
    stderr); then, or with --html-only alone, draw the figures and report.html:
    ``mjx_balance.report`` with the options resolved."""
    from .. import api  # lazy: the library (JAX, MuJoCo, pandas); not for --help

    html_only = getattr(args, "html_only", False)
    config = None if html_only else load_run_config(args)
    out = Path(args.out)
    result = {}
    loud = progress_enabled(args)  # not -q

    def work() -> None:
        result["path"] = api.report(
            config,
            out=out,
            scale=args.scale,
            backend=args.backend,
            studies=args.studies,
            conventions=None if html_only else _conventions(args.conventions),
            sweeps=args.sweeps,
            reference=args.reference,
            cluster=getattr(args, "cluster", None),
            physics=getattr(args, "physics", None) or "auto",
            html_only=html_only,
            wait=getattr(args, "wait", False),
            progress=None if loud else False,  # -q: only warnings and errors
            say=(lambda text: print(text, file=sys.stderr)) if loud else (lambda _t: None),
        )  # stdout: the page's path alone

    code = in_folder(out, work, lock=False)  # the API takes the folder's lock
    if code:
        return code
    print(f"wrote {result['path']}")
    return 0


def _conventions(text: str | None) -> tuple[str, ...]:
    """--conventions as a tuple (default: every convention); raises for an unknown one."""
    conventions = tuple(text.split(",")) if text else CONVENTIONS
    bad = [c for c in conventions if c not in CONVENTIONS]
    if bad:
        raise ParameterError(f"--conventions: unknown {', '.join(bad)}")
    return conventions
