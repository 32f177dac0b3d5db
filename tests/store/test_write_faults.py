"""Every write site faulted (docs/scripts/write_faults.py; docs/reliability.md, "Every write
site faulted"): a small simulate run with each of its files opened for writing failing in turn
(ENOSPC or EIO at the write, EROFS at the open) ends in one line naming the file and the cause,
leaves no table that differs from a clean run's, and reruns to the clean run's bytes: its first
four opens (the lock, and a push's request made, written and synced), about 2 minutes; and
explore's click, every one of its opens. The shim
is C, loaded with LD_PRELOAD: the test needs a C compiler and Linux (skipped without them, the
reason said). The slow run: each command's full enumeration is the script's."""

from __future__ import annotations

import shutil
import sys

import pytest
from support import docs_script

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not sys.platform.startswith("linux") or shutil.which("cc") is None,
        reason="the write-fault shim is loaded with LD_PRELOAD and built with cc (Linux)",
    ),
]


def test_every_write_of_a_simulate_run_faulted(tmp_path, monkeypatch, capsys):
    script = docs_script("write_faults")
    monkeypatch.setattr(
        sys,
        "argv",
        ["write_faults.py", "--command", "simulate", "--limit", "4", "--out", str(tmp_path)],
    )
    assert script.main() == 0, capsys.readouterr().out
    printed = capsys.readouterr().out
    assert "0 failed of" in printed and "<- " not in printed
    assert "| ENOSPC |" in printed and "| EIO |" in printed and "| EROFS |" in printed


def test_every_write_of_an_explore_click_faulted(tmp_path, monkeypatch, capsys):
    """explore's click keeps its run in the folder (3 opens: made, written, synced): each
    faulted, the click is still answered with the run and a note naming the cause and the
    file, the server stops on Ctrl-C, and a later server keeps the run whole (about 3 min)."""
    script = docs_script("write_faults")
    monkeypatch.setattr(
        sys, "argv", ["write_faults.py", "--command", "explore", "--out", str(tmp_path)]
    )
    assert script.main() == 0, capsys.readouterr().out
    printed = capsys.readouterr().out
    assert "0 failed of 4" in printed
    assert "| ENOSPC |" in printed and "| EIO |" in printed and "| EROFS |" in printed


def test_the_harness_fails_a_run_that_hides_a_failed_write(tmp_path):
    """The verdict is not vacuous: a run that exits 0 after a fault struck its table, or
    whose one line names neither the file nor the cause, is a failure."""
    script = docs_script("write_faults")
    out = tmp_path / "out"
    out.mkdir()

    class Proc:
        def __init__(self, code, err):
            self.returncode, self.stderr = code, err

    table = str(out / ".summary.csv.abc.tmp")
    cache = tmp_path / "cache"
    hidden = script.verdict(Proc(0, ""), table, 28, cache, {}, out)
    assert hidden == "exit 0 after a failed write"
    vague = script.verdict(
        Proc(1, "mjx-balance: error: something failed\n"), table, 28, cache, {}, out
    )
    assert vague == "the cause is not named"
    named = script.verdict(
        Proc(1, f"mjx-balance: error: {table}: No space left on device\n"),
        table,
        28,
        cache,
        {},
        out,
    )
    assert named == ""
    (out / "summary.csv").write_text("half")
    assert "differs" in script.verdict(Proc(1, ""), table, 28, cache, {"summary.csv": b"x"}, out)
