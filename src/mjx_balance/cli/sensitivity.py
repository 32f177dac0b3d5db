"""``mjx-balance sensitivity``: the reproduction table under every reading of the study
(``mjx_balance.studies.sensitivity``).

Only the parser (:func:`add_parser`) is imported when the command line is built; the command
imports the library when it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def add_parser(sub: Any) -> None:
    """The ``sensitivity`` sub-command's options (``sub.add_parser`` of ``cli.build_parser``)."""
    from . import _cluster, _common, _engine_options, _wait

    p = sub.add_parser(
        "sensitivity", help="the robustness table under every reading of the study (paper/joint "
                            "convention x plain/offset-free MPC, both energy definitions): each "
                            "reading's table in DIR/<reading>/ (resumable), then "
                            "sensitivity.csv (the spread per force), sensitivity.png, "
                            "sensitivity.txt (what holds under every reading)")
    from ..studies.sensitivity import DEFAULT_FORCES, READINGS

    p.add_argument("--forces", default=DEFAULT_FORCES,
                   help="table forces [N], start:stop:step or a comma list")
    p.add_argument("--readings", default=",".join(READINGS),
                   help="comma list of readings to run")
    _engine_options(p)
    _cluster(p)
    _wait(p)
    _common(p, out_help="output folder: one table folder per reading, sensitivity.csv, "
                        "sensitivity.png, sensitivity.txt")
    p.set_defaults(target="mjx_balance.cli.sensitivity:sensitivity_command")


def sensitivity_command(args: Any) -> int:
    """Every reading's table, then the spread (every input checked first)."""
    import logging

    from ..studies.sensitivity import reading_configs, run_sensitivity
    from ..runs.grid import parse_grid
    from . import load_run_config, progress_enabled
    from .sweep import _in_folder

    base = load_run_config(args)
    readings = [r.strip() for r in args.readings.split(",") if r.strip()]
    reading_configs(base, readings)
    parse_grid(args.forces, "forces")
    out = Path(args.out)
    engine = {"slots": args.slots, "full_length": args.full_length,
              "physics": args.physics or "auto", "cluster": args.cluster}

    def work() -> None:
        run_sensitivity(out, base, args.forces, readings=readings,
                        progress=progress_enabled(args),
                        say=logging.getLogger("mjx_balance").info, **engine)

    return _in_folder(out, work, wait=getattr(args, "wait", False))
