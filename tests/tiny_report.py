"""Tiny reports shared by the report, browser and notebook tests (a module-level cache, so one
pytest session builds each once).

Two sizes: SMALL, the default run's, with two of the studies (backward, whose key number the
overview shows, and ankle_only, a study of two variants; delay's nine variants took 8 s of the
default run on 2 cores), and ALL, every study (the slow run's, the notebook's and the
page-size check's: delay's key number is checked there). The report's code paths are the
same; ALL adds the other studies' sections.
"""

import contextlib
import io
from pathlib import Path

SMALL = "ankle_only,backward"  # (in the catalog's order, as report.json lists them)
ALL = "all"

_CACHE: dict[str, Path] = {}

REFERENCE = """force,max_acting_time,energy_total_01,source,reason
20,0.05,0.1,made-up table for the tests,made-up reason for the test
100,0.02,,made-up table for the tests,
"""


def selected(which: str) -> list:
    """The studies a tiny report of ``which`` (SMALL or ALL) runs."""
    from mjx_balance.studies.catalog import STUDIES

    if which == ALL:
        return list(STUDIES)
    keys = which.split(",")
    return [s for s in STUDIES if s.key in keys]


def tiny_report(tmp_path_factory, which: str = ALL) -> Path:
    """The output folder of ``mjx-balance report --scale tiny --studies WHICH`` (through the
    command line), after checking what the command printed: the numbered stages and the
    tables' folder (on stderr), the page it wrote (on stdout)."""
    if which not in _CACHE:
        from mjx_balance.cli import main

        out = tmp_path_factory.mktemp("tiny_report")
        # a made-up reference table at the tiny plan's table forces (no extra runs): made up,
        # never a published number; one row carries a reason, one has none
        reference = tmp_path_factory.mktemp("reference") / "made_up_reference.csv"
        reference.write_text(REFERENCE)
        stdout, stderr = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            assert (
                main(
                    [
                        "report",
                        "--scale",
                        "tiny",
                        "--studies",
                        which,
                        "--out",
                        str(out),
                        "--reference",
                        str(reference),
                    ]
                )
                == 0
            )
        # both conventions (time series, two weight studies, table, region), every variant,
        # the sensitivity
        stages = 5 * 2 + sum(len(s.variants) for s in selected(which)) + 1
        printed = stdout.getvalue()
        assert printed.startswith("[report 1/")
        assert f"[report {stages}/{stages}, " in printed
        assert f"tables saved in {out} (" in stderr.getvalue()
        # no progress bar where no one watches (stderr is not a terminal here): a bar's
        # carriage returns would make a redirected log of one error line many lines
        assert "\r" not in stderr.getvalue()
        assert printed.endswith(f"wrote {out / 'report.html'}\n")
        _CACHE[which] = out
    return _CACHE[which]
