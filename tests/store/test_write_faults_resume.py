"""The write-fault harness resumes an enumeration cut short (docs/scripts/write_faults.py
``--done``): the faults an earlier run's printed table passed are read back as (site, written
through or not), and only those; a failed row, a row of another kind and the site list are not.
The harness's runs themselves are the slow run's (tests/store/test_write_faults.py)."""

from __future__ import annotations

from support import docs_script


def test_an_earlier_table_names_the_faults_it_passed(tmp_path):
    earlier = tmp_path / "earlier.txt"
    earlier.write_text(
        "report: 490 files opened for writing (170 written through), 116 write sites\n"
        "  site OUT/.lock\n"
        "| k | file | errno | exit | stderr | rerun exit | tables identical | verdict |\n"
        "|---|---|---|---|---|---|---|---|\n"
        "| 181 | OUT/a/.region.parquet.*.tmp | EROFS | 1 | error: Read-only | 0 | yes | ok |\n"
        "| 182 | OUT/a/.region.parquet.*.tmp | ENOSPC | 1 | error: No space | 0 | yes | ok |\n"
        "| 190 | OUT/b/.table.csv.*.tmp | EIO | 1 | error: one | 0 | yes | 2 lines on stderr |\n"
        "| 191 | OUT/b/.lock | EROFS | 0 |  | 0 | yes | ok |\n"
        "0 failed of 4\n"
    )
    passed = docs_script("write_faults").done_before([earlier])
    assert passed == {
        ("OUT/a/.region.parquet.*.tmp", False),
        ("OUT/a/.region.parquet.*.tmp", True),
        ("OUT/b/.lock", False),
    }
