"""runtime/signals.py on its own: a signal whose exception the runtime drops is sent again and
ends the work even where no checkpoint runs; a repeated signal does not cut the clean-up of
the first one short; the handlers and the unraisable hook are put back."""

from __future__ import annotations

import os
import signal
import sys
import time

import pytest
from support import signal_where_exceptions_are_dropped

from mjx_balance.runtime import signals


@pytest.mark.parametrize("where", ["gc", "del", "weakref"])
def test_a_dropped_signal_is_sent_again_where_no_checkpoint_runs(where):
    hook = sys.unraisablehook
    started = time.monotonic()
    with pytest.raises(signals.Terminated):
        with signals.honoured():
            signal_where_exceptions_are_dropped(where, signal.SIGTERM)
            while time.monotonic() - started < 10:  # plain Python: no checkpoint
                pass
    # sent again after REDELIVER_S (0.02 s), not found at the block's end after the 10 s loop
    assert time.monotonic() - started < 5
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    assert sys.unraisablehook is hook


def test_a_checkpoint_raises_a_signal_whose_exception_was_dropped(monkeypatch):
    monkeypatch.setattr(signals, "REDELIVER_S", 60.0)  # no re-delivery within the test
    with pytest.raises(signals.Interrupted) as caught:
        with signals.honoured():
            signal_where_exceptions_are_dropped("gc", signal.SIGINT)
            assert signals.pending() == signal.SIGINT
            signals.check()
    assert type(caught.value) is signals.Interrupted and caught.value.code == 130


def test_a_repeated_signal_does_not_cut_the_clean_up_short():
    cleaned = False
    with pytest.raises(signals.Interrupted):
        with signals.honoured():
            try:
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(1000):
                    pass
            finally:  # the clean-up the first Ctrl-C started; a second Ctrl-C comes
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(1000):
                    pass
                cleaned = True
    assert cleaned
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_nothing_pending_nothing_raised():
    with signals.honoured():
        with signals.honoured():  # nested: the outer block's handlers
            signals.check()
    assert signals.pending() is None


def test_a_signal_after_the_console_scripts_work_changes_nothing(tmp_path):
    """The console script's process, its work done: SIGINT and SIGTERM during the rest of its
    life (the interpreter's clean-up at exit) neither print nor change the exit status."""
    import subprocess
    import textwrap

    script = textwrap.dedent("""
        import os, signal, sys, time
        from mjx_balance.cli.main import main
        code = main(["-q", "model", "--out", sys.argv[1]], hold_signals_after=True)
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.2)
        sys.exit(code)
    """)
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "body.xml")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert (tmp_path / "body.xml").exists()


def test_a_ctrl_c_that_osqp_caught_is_delivered():
    """OSQP listens for SIGINT while it solves and ends the solve with status OSQP_SIGINT
    (Python's handler never runs): the reference's solver delivers it as Interrupted."""
    import types

    import osqp

    from mjx_balance.control.osqp_mpc import checked

    caught = types.SimpleNamespace(
        info=types.SimpleNamespace(status_val=osqp.SolverStatus.OSQP_SIGINT)
    )
    solved = types.SimpleNamespace(
        info=types.SimpleNamespace(status_val=osqp.SolverStatus.OSQP_SOLVED)
    )
    assert checked(solved) is solved
    with pytest.raises(signals.Interrupted):
        with signals.honoured():
            checked(caught)
    with pytest.raises(KeyboardInterrupt):  # outside a command or API call: Python's own
        checked(caught)


def test_osqps_interrupted_line_is_dropped_and_nothing_else(capsys):
    """On a Ctrl-C it caught, OSQP writes "Solver interrupted" to sys.stdout before the
    command's own line; osqp_mpc.solved drops that line only, and puts sys.stdout back."""
    import types

    import osqp

    from mjx_balance.control.osqp_mpc import OSQP_INTERRUPTED, solved

    result = types.SimpleNamespace(
        info=types.SimpleNamespace(status_val=osqp.SolverStatus.OSQP_SOLVED)
    )
    stdout = sys.stdout

    class Solver:
        def solve(self, raise_error):
            sys.stdout.write(OSQP_INTERRUPTED)  # as OSQP's PySys_WriteStdout does
            sys.stdout.write("a line of the command's own\n")
            return result

    assert solved(Solver()) is result
    assert capsys.readouterr().out == "a line of the command's own\n"
    assert sys.stdout is stdout


def test_a_ctrl_c_that_osqp_caught_in_another_thread_reaches_the_main_thread():
    """OSQP catches the Ctrl-C in whatever thread solves (the explore server's request
    threads): the signal is sent again, so the main thread's work ends as on any Ctrl-C, and
    the solving thread's work ends too (it was raised in the solving thread only, and the
    main thread served on)."""
    import threading
    import types

    import osqp

    from mjx_balance.control.osqp_mpc import checked

    caught = types.SimpleNamespace(
        info=types.SimpleNamespace(status_val=osqp.SolverStatus.OSQP_SIGINT)
    )
    raised = []

    def solve():
        try:
            checked(caught)
        except KeyboardInterrupt as exc:
            raised.append(type(exc))

    started = time.monotonic()
    with pytest.raises(signals.Interrupted):
        with signals.honoured():
            threading.Thread(target=solve).start()
            while time.monotonic() - started < 10:  # the main thread's own work
                time.sleep(0.01)
    assert time.monotonic() - started < 5 and raised == [signals.Interrupted]


def test_a_thread_stops_at_its_next_checkpoint_while_the_main_thread_cleans_up():
    """After a signal the main thread's clean-up is not cut short (no checkpoint raises there
    once it caught the signal), but another thread's work ends at its next checkpoint: the
    scalar reference checks once a control period, so a clicked cell's run ends within one
    period rather than running on into the process's exit (an abort inside C++ code)."""
    import threading

    from mjx_balance.model.params import Config
    from mjx_balance.reference.loop import simulate_scenario

    ended = []

    def run():
        try:
            simulate_scenario(Config().replace(scenario={"t_end": 2.0}), 20.0, 0.1)
            ended.append("finished")
        except signals.Terminated:
            ended.append("stopped")

    with signals.honoured():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the handler raises here
        except signals.Terminated as exc:
            signals.seen(exc)  # the main thread cleans up: its own checkpoints stay quiet
            signals.check()
            worker = threading.Thread(target=run)
            worker.start()
            worker.join(60)
    assert ended == ["stopped"]


def test_ctrl_c_during_simulate_ends_it(tmp_path):
    """A real simulate (the scalar reference spends most of its time in OSQP's solves), sent
    SIGINT while its pushes run: exit 130, one line, the finished pushes kept."""
    import subprocess

    out = tmp_path / "sim"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mjx_balance",
            "-q",
            "simulate",
            "--forces",
            "60,80,100",
            "--durations",
            "0.2",
            "--set",
            "scenario.t_end=4",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while not (out / "pushes" / "request.json").exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(1.0)  # inside the first push's solves
    os.kill(proc.pid, signal.SIGINT)
    printed, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Solver interrupted" not in printed  # OSQP's own line (osqp_mpc.solved)
    assert err.strip().splitlines() == [
        "mjx-balance: error: interrupted (SIGINT); what "
        "finished is kept: run the same command to resume"
    ]
