"""One tiny report run shared by the report and notebook tests (a module-level cache, so one
pytest session builds it once)."""

import contextlib
import io
from pathlib import Path

_CACHE: dict[str, Path] = {}

REFERENCE = """force,max_acting_time,energy_total_01,source,reason
20,0.05,0.1,made-up table for the tests,made-up reason for the test
100,0.02,,made-up table for the tests,
"""


def tiny_report(tmp_path_factory) -> Path:
    """The output folder of ``mjx-balance report --scale tiny`` (through the command line),
    after checking what the command printed: the numbered stages and the tables' folder (on
    stderr), the page it wrote (on stdout)."""
    if "out" not in _CACHE:
        from mjx_balance.cli import main
        from mjx_balance.studies.catalog import STUDIES

        out = tmp_path_factory.mktemp("tiny_report")
        # a made-up reference table at the tiny plan's table forces (no extra runs): made up,
        # never a published number; one row carries a reason, one has none
        reference = out.parent / "made_up_reference.csv"
        reference.write_text(REFERENCE)
        stdout, stderr = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            assert main(["report", "--scale", "tiny", "--out", str(out),
                         "--reference", str(reference)]) == 0
        # both conventions (time series, two weight studies, table, region), every variant,
        # the sensitivity
        stages = 5 * 2 + sum(len(s.variants) for s in STUDIES) + 1
        printed = stdout.getvalue()
        assert printed.startswith("[report 1/")
        assert f"[report {stages}/{stages}, " in printed
        assert f"tables saved in {out} (" in stderr.getvalue()
        assert printed.endswith(f"wrote {out / 'report.html'}\n")
        _CACHE["out"] = out
    return _CACHE["out"]
