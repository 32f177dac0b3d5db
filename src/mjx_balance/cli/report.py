"""``mjx-balance report``: run (or resume) the report's experiments and studies, then write
DIR/report.html (report.run_report, report.build_report)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from ..runtime import cache
from ..model.params import CONVENTIONS, ParameterError
from ..report import PLANS, REPORT_JSON, build_report, run_report, selected_studies
from ..studies.experiments import read_record
from ..store.folder import run_context
from . import load_run_config


def report_command(args: Any) -> int:
    """Without --html-only: run everything missing in --out and say where the tables are (on
    stderr); then, or with --html-only alone, draw the figures and report.html."""
    out = Path(args.out)
    if not getattr(args, "html_only", False):
        conventions = _conventions(args.conventions)
        backend = args.backend or PLANS[args.scale].backend
        if backend == "mjx":
            cache.enable()  # the batched rollout compiles: keep its executables
        # what the sweep folders' manifests record as the physics path
        with run_context(physics="mjx" if backend == "mjx" else "mujoco"):
            record = run_report(out, load_run_config(args), PLANS[args.scale],
                                backend=args.backend, study_list=selected_studies(args.studies),
                                conventions=conventions,
                                sweeps=Path(args.sweeps) if args.sweeps else None,
                                cluster=getattr(args, "cluster", None),
                                physics=getattr(args, "physics", None) or "auto")
        print(f"tables saved in {out} ({record['seconds']:.0f} s)", file=sys.stderr)
    else:  # check the record before build_report creates anything
        read_record(out / REPORT_JSON)
    path = build_report(out)
    print(f"wrote {path}")
    return 0


def _conventions(text: str | None) -> tuple[str, ...]:
    """--conventions as a tuple (default: every convention); raises for an unknown one."""
    conventions = tuple(text.split(",")) if text else CONVENTIONS
    bad = [c for c in conventions if c not in CONVENTIONS]
    if bad:
        raise ParameterError(f"--conventions: unknown {', '.join(bad)}")
    return conventions
