"""Tiny folders for the explore page's tests (tests/report/test_explore*.py,
tests/cli/test_explore_cli.py), made on the stand-in rollout (support.FakeThresholdBatch: no
engine is compiled) with a 1-s window, so that a clicked cell's run by the scalar reference
takes about a second.

    sweep_folder   ``mjx-balance sweep`` of support.CLI_GRID (5 forces x 3 durations = 15
                   cells in 4 chunks) and ``mjx-balance table --forces 20,40`` in one folder
    shaped_like    a compare- or cohort-shaped folder of copies of a sweep folder
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

T_END = ["--set", "scenario.t_end=1"]
TABLE_FORCES = "20,40"


def sweep_folder(out: Path) -> Path:
    """A finished sweep folder with its table (the stand-in recovers iff F T < 30 N s; one step
    saves a fall with F T < 35 N s)."""
    import pytest
    from support import DEFAULT_BATCH, FakeThresholdBatch, cli_sweep

    from mjx_balance.cli import main

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(DEFAULT_BATCH, lambda config, **_: FakeThresholdBatch(one_step=35.0))
        assert cli_sweep(out, "-q", *T_END) == 0
        assert main(["-q", "table", "--forces", TABLE_FORCES, *T_END, "--out", str(out)]) == 0
    return out


def shaped_like(kind: str, sweep: Path, out: Path, names: list[str]) -> Path:
    """A ``compare`` folder (``out/<name>/``, compare.csv naming them) or a ``cohort`` folder
    (``out/subjects/<name>/``, a cohort manifest listing them) of copies of ``sweep``."""
    parent = out / "subjects" if kind == "cohort" else out
    parent.mkdir(parents=True)
    for name in names:
        shutil.copytree(sweep, parent / name, ignore=shutil.ignore_patterns(".lock", "explore"))
    if kind == "cohort":
        manifest = {"kind": "cohort", "cohort": {"subjects": [{"id": n} for n in names]}}
        (out / "manifest.json").write_text(json.dumps(manifest))
    else:
        (out / "compare.csv").write_text("name\n" + "\n".join(names) + "\n")
    return out
