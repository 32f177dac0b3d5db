"""``mjx-balance compare``: several configurations on one grid, one figure and one table."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..runs import DEFAULT_SWEEP
from . import progress_enabled
from .sweep import _in_folder


def compare_command(args: Any) -> int:
    """Each --config's region map and table in OUT/<name>/, then compare.csv and compare.png."""
    from ..studies.compare import load_configs, run_compare

    configs = load_configs(args.config)
    out = Path(args.out)
    engine = {"slots": args.slots, "full_length": args.full_length,
              "physics": args.physics or "auto", "cluster": args.cluster}

    def work() -> None:
        run_compare(out, configs, args.forces or DEFAULT_SWEEP["forces"],
                    args.durations or DEFAULT_SWEEP["durations"],
                    args.table_forces or DEFAULT_SWEEP["table_forces"],
                    progress=progress_enabled(args), **engine)

    return _in_folder(out, work, wait=getattr(args, "wait", False))
