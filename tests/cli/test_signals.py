"""Signals and streams: each ends with one line and exit 130 (SIGINT), 143
(SIGTERM) or 1, the manifest's run record says ``interrupted`` or ``failed`` with its end time,
and what finished is kept and resumed. Faults are injected at a named point: the stand-in
batch function's second call (where a user's Ctrl-C lands during a sweep), and inside code
whose exceptions the runtime drops (a garbage-collection callback, ``__del__``, a weakref
callback), where a signal's exception raised by the handler would be lost.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from support import DEFAULT_BATCH, TESTS, FakeThresholdBatch, signal_where_exceptions_are_dropped

from mjx_balance.cli import main

ARGS = [
    "sweep",
    "--forces",
    "0,20,40,60",
    "--durations",
    "0.5,1",
    "--chunk",
    "2",
    "--set",
    "scenario.t_end=2",
]


class SignalOnCall(FakeThresholdBatch):
    """The stand-in rollout; on its ``k``-th call the process gets ``signum`` (os.kill: the
    handler runs as for a signal from outside)."""

    def __init__(self, signum: int, k: int = 2):
        super().__init__()
        self.signum, self.k = signum, k

    def __call__(self, forces, durations):
        if len(self.calls) + 1 == self.k:
            self.calls.append(-1)
            os.kill(os.getpid(), self.signum)
        return super().__call__(forces, durations)


@pytest.mark.parametrize(
    "signum, code, name", [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")]
)
def test_a_signal_ends_with_one_line_and_the_run_resumes(
    tmp_path, capsys, monkeypatch, signum, code, name
):
    out = tmp_path / "out"
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_: SignalOnCall(signum))
    assert main(["-q", *ARGS, "--out", str(out)]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"mjx-balance: error: interrupted ({name}); what finished is kept: run the "
        "same command to resume"
    ]
    run = json.loads((out / "manifest.json").read_text())["runs"][-1]
    assert run["status"] == "interrupted" and run["ended"]
    kept = sorted((out / "chunks").glob("chunk-*.parquet"))
    assert len(kept) == 1  # the first chunk, written before the signal
    fake = FakeThresholdBatch()
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_: fake)
    assert main(["-q", *ARGS, "--out", str(out)]) == 0
    assert sum(fake.calls) == 6  # only the 3 chunks not kept
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # the handler was put back


class SignalDropped(FakeThresholdBatch):
    """The stand-in rollout; on its second call the signal lands where exceptions are dropped."""

    def __init__(self, where: str, signum: int):
        super().__init__()
        self.where, self.signum = where, signum

    def __call__(self, forces, durations):
        if len(self.calls) + 1 == 2:
            self.calls.append(-1)
            signal_where_exceptions_are_dropped(self.where, self.signum)
        return super().__call__(forces, durations)


@pytest.mark.parametrize("where", ["gc", "del", "weakref"])
@pytest.mark.parametrize(
    "signum, code, name", [(signal.SIGINT, 130, "SIGINT"), (signal.SIGTERM, 143, "SIGTERM")]
)
def test_a_signal_in_a_callback_whose_exceptions_are_dropped_still_ends_the_run(
    tmp_path, capsys, monkeypatch, where, signum, code, name
):
    out = tmp_path / "out"
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_: SignalDropped(where, signum))
    assert main(["-q", *ARGS, "--out", str(out)]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"mjx-balance: error: interrupted ({name}); what finished is kept: run the "
        "same command to resume"
    ]  # and no "Exception ignored in ..."
    run = json.loads((out / "manifest.json").read_text())["runs"][-1]
    assert run["status"] == "interrupted" and run["ended"]
    assert not (out / "region.parquet").exists()
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_killed_run_is_recorded_killed_by_the_next(tmp_path, monkeypatch):
    """A run that ended without a word (kill -9: its record still says running) is recorded
    as killed by the next run that takes the folder."""
    out = tmp_path / "out"
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_: FakeThresholdBatch())
    assert main(["-q", *ARGS, "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["runs"][-1].update(status="running", ended=None, run_id="a-killed-run")
    (out / "manifest.json").write_text(json.dumps(manifest))
    assert main(["-q", *ARGS, "--out", str(out)]) == 0
    runs = json.loads((out / "manifest.json").read_text())["runs"]
    assert [r["status"] for r in runs] == ["killed", "completed"]


# A fresh process with a stand-in rollout (the sweep tests' fake), for faults of its streams.
SCRIPT = textwrap.dedent("""
    import os, sys
    sys.path.insert(0, sys.argv[1])
    from support import DEFAULT_BATCH, FakeThresholdBatch
    import mjx_balance.runs.batch as batch
    batch.default_batch = lambda config, **_: FakeThresholdBatch()
    if sys.argv[2] == "closed-stderr":
        os.close(2)
        sys.stderr.close()
    from mjx_balance.cli import main
    sys.exit(main(sys.argv[3:]))
""")


def run_script(mode: str, out: Path, **streams) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", SCRIPT, str(TESTS), mode, *ARGS, "--out", str(out)],
        timeout=300,
        **streams,
    )


def test_a_closed_stderr_does_not_fail_the_run(tmp_path):
    # progress bars and warnings go to stderr: with it closed the run still finishes
    done = run_script("closed-stderr", tmp_path / "out", capture_output=True)
    assert done.returncode == 0
    assert (tmp_path / "out" / "region.parquet").exists()
    assert (tmp_path / "out" / "region.png").exists()


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_full_stdout_does_not_fail_the_run(tmp_path):
    # the log's lines (stdout) on a full disk: dropped, the results are in files
    with open("/dev/full", "w") as full:
        done = run_script("plain", tmp_path / "out", stdout=full, stderr=subprocess.PIPE, text=True)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "Logging error" not in done.stderr
    assert (tmp_path / "out" / "region.parquet").exists()


def test_a_dangling_symlink_as_out_is_refused(tmp_path, capsys):
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "missing" / "target")
    with pytest.raises(SystemExit) as exc:
        main([*ARGS, "--out", str(link)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "symbolic link to a missing target" in err and "Traceback" not in err


SIMULATE = [
    "-q",
    "simulate",
    "--forces",
    "0,20,50",
    "--durations",
    "0.1,0.2",
    "--set",
    "scenario.t_end=0.3",
]


# SIGINT in the slow run only: both signals take the same path through the command line,
# which the sweep's signal tests above check in the default run for each.
@pytest.mark.parametrize(
    "signum, code",
    [(signal.SIGTERM, 143), pytest.param(signal.SIGINT, 130, marks=pytest.mark.slow)],
)
def test_simulate_keeps_each_finished_push_and_resumes(tmp_path, monkeypatch, signum, code):
    """simulate stopped after 2 of its 6 pushes keeps them (DIR/pushes/), records the run as
    interrupted, and the same command runs only the other 4; its tables are those of a run
    that was never stopped, byte for byte."""
    from mjx_balance.reference import loop

    real, ran = loop.simulate_scenario, []

    def counted(config, force, duration, **kw):
        ran.append((force, duration))
        if stop_at is not None and len(ran) == stop_at:
            os.kill(os.getpid(), signum)
        return real(config, force, duration, **kw)

    monkeypatch.setattr(loop, "simulate_scenario", counted)
    stop_at, whole = None, tmp_path / "whole"
    assert main([*SIMULATE, "--out", str(whole)]) == 0
    out, stop_at, ran[:] = tmp_path / "out", 3, []
    assert main([*SIMULATE, "--out", str(out)]) == code  # the 3rd push is cut short
    assert len(list((out / "pushes").glob("*.summary.json"))) == 2
    runs = json.loads((out / "manifest.json").read_text())["runs"]
    assert [r["status"] for r in runs] == ["interrupted"] and not (out / "summary.csv").exists()
    stop_at, ran[:] = None, []
    assert main([*SIMULATE, "--out", str(out)]) == 0
    assert len(ran) == 4 and not (out / "pushes").exists()
    for name in ("summary.csv", "timeseries.parquet"):
        assert (out / name).read_bytes() == (whole / name).read_bytes(), name
    assert json.loads((out / "manifest.json").read_text())["runs"][-1]["status"] == "completed"
