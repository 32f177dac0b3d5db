"""``mjx-balance compare``: several configurations on one grid, one figure and one table."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .common import in_folder, progress_enabled
from .options import cluster_option, engine_options, out_folder, sweep_file, wait_option


def add_parser(sub: Any) -> None:
    """The ``compare`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser("compare", help="several configurations on one grid: their recovery "
                                       "boundaries in one figure, their numbers in one table")
    p.add_argument("--config", type=sweep_file, action="append", required=True,
                   metavar="FILE", help="a TOML configuration, or a sweep definition (a file "
                                        "or a shipped name such as study_offset_free: its "
                                        "configuration, not its grid); repeat for each; the "
                                        "folder name is the file's stem")
    p.add_argument("--forces", default=None,
                   help="start:stop:step or a comma list [N] (default: the default sweep's, "
                        "0:150:10)")
    p.add_argument("--durations", default=None,
                   help="start:stop:step or a comma list [s] (default: the default sweep's)")
    p.add_argument("--table-forces", default=None,
                   help="forces of each configuration's max-acting-time table [N] (default: "
                        "the default sweep's, 20,50,80,100,120)")
    engine_options(p)
    cluster_option(p)
    wait_option(p)
    p.add_argument("--out", type=out_folder, required=True,
                   help="output folder: one sweep folder per configuration, compare.csv, "
                        "compare.png")
    p.set_defaults(target="mjx_balance.cli.compare:compare_command")


def compare_command(args: Any) -> int:
    """Each --config's region map and table in OUT/<name>/, then compare.csv and compare.png."""
    from ..runs import DEFAULT_SWEEP  # lazy: the runs floor loads JAX; not for --help
    from ..studies.compare import load_configs, run_compare  # lazy: as above

    configs = load_configs(args.config)
    out = Path(args.out)
    engine = {"slots": args.slots, "full_length": args.full_length,
              "physics": args.physics or "auto", "cluster": args.cluster}

    def work() -> None:
        run_compare(out, configs, args.forces or DEFAULT_SWEEP["forces"],
                    args.durations or DEFAULT_SWEEP["durations"],
                    args.table_forces or DEFAULT_SWEEP["table_forces"],
                    progress=progress_enabled(args), **engine)

    return in_folder(out, work, wait=getattr(args, "wait", False))
