"""SIGINT and SIGTERM honoured wherever they land.

Python runs a signal's handler in the main thread between two bytecodes of whatever code runs
at that instant. The handler raises :class:`Interrupted` (a ``KeyboardInterrupt``, so every
``finally`` and every clean-up written for Ctrl-C runs: the folder's lock is let go, the
manifest records the run as interrupted, finished chunks stay). When the instant falls inside
code whose exceptions the runtime ignores (a garbage-collection callback such as JAX's
``_xla_gc_callback``, a ``__del__``, a weakref callback), the exception is printed as
"Exception ignored in ..." and dropped, and the run would go on as if no signal came. So:

- the handler also records the signal as *pending*;
- :func:`check`, called at the work's own checkpoints (every block of the engine, every
  scenario of the reference, every unit of a progress bar), raises a pending signal's
  exception;
- an :class:`Interrupted` that the runtime drops (``sys.unraisablehook``) is not printed; the
  signal is sent again a moment later, from a thread, so that it also lands where no
  checkpoint runs (drawing figures, writing tables).

:func:`honoured` installs this for the span of a command or an API call (in the main thread;
nested uses share the outer one). While the first signal's exception unwinds the work, further
signals are recorded only: the clean-up it triggers is not cut short.

Work in other threads (the explore server computes a clicked cell's run in a request's thread):

- its checkpoints (:func:`check`) raise whenever a signal has come, also while the main thread
  cleans up, so that the thread's work ends within one checkpoint and the process does not
  exit with a thread inside MuJoCo's or OSQP's C++ code (that aborts: "terminate called
  without an active exception", exit 134);
- a signal that a library caught in that thread (:func:`received`: OSQP's Ctrl-C) is sent
  again to the process, so that the main thread's handler acts on it as on any signal (it was
  raised in the request's thread only, and the server served on, deaf to later signals).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager
from types import FrameType
from typing import Any, Callable, Iterator

SIGNALS = (signal.SIGINT, signal.SIGTERM)
REDELIVER_S = 0.02  # how soon a dropped signal is sent again (the main thread runs meanwhile)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT), raised where the work is; ``code`` is the command line's exit status."""

    signum = signal.SIGINT
    code = 128 + signal.SIGINT
    name = "SIGINT"


class Terminated(Interrupted):
    """SIGTERM, raised in the main thread as Ctrl-C is."""

    signum = signal.SIGTERM
    code = 128 + signal.SIGTERM
    name = "SIGTERM"


def exception(signum: int) -> Interrupted:
    return Terminated() if signum == signal.SIGTERM else Interrupted()


class _State:
    def __init__(self) -> None:
        self.depth = 0  # nested honoured() blocks
        self.pending: int | None = None  # the first signal not yet seen by the work
        self.seen = False  # the work caught its exception: it is stopping
        self.dropped = False  # its exception was dropped where it landed: raise it again
        self.previous: dict[
            int, Callable[[int, FrameType | None], Any] | int | signal.Handlers | None
        ] = {}
        self.hook: Callable[[sys.UnraisableHookArgs], Any] | None = None
        self.lock = threading.Lock()
        self.timers: list[threading.Timer] = []


_STATE = _State()


def pending() -> int | None:
    """The signal received in the current :func:`honoured` block and not yet acted on."""
    return _STATE.pending


def check() -> None:
    """A checkpoint of long work: raise the pending signal's exception, if a signal came and
    its exception was dropped where it landed (or has not been raised yet). Outside the main
    thread, whenever a signal came (module docstring)."""
    st = _STATE
    if st.pending is None or st.depth == 0:  # no signal in a block still under way
        return
    if threading.current_thread() is not threading.main_thread():
        raise exception(st.pending)
    if not st.seen:
        st.dropped = False  # raised here: a re-delivered copy need not raise it again
        raise exception(st.pending)


def received(signum: int) -> None:
    """A signal that a library caught for itself (OSQP's Ctrl-C during a solve) and reported:
    handled as if Python's handler had seen it (raised where the work is; outside a
    :func:`honoured` block, as Python's KeyboardInterrupt). In a thread other than the main
    one, the signal is also sent to the process again, so that the main thread acts on it."""
    if threading.current_thread() is not threading.main_thread():
        os.kill(os.getpid(), signum)  # the library has put Python's handler back by now
        raise exception(signum) if _STATE.depth else KeyboardInterrupt
    if _STATE.depth == 0:
        raise KeyboardInterrupt
    _handler(signum, None)


def _handler(signum: int, _frame) -> None:
    st = _STATE
    if st.depth == 0 or st.seen:
        return  # the block has ended, or the work is stopping: its clean-up runs on
    if st.pending is None:
        st.pending = signum
    elif not st.dropped:
        return  # a repeated signal while the first one's exception unwinds the work
    st.dropped = False
    raise exception(st.pending)


def _redeliver(signum: int) -> None:
    with _STATE.lock:
        if _STATE.depth > 0 and not _STATE.seen:
            os.kill(os.getpid(), signum)


def _unraisable(unraisable) -> None:
    """The runtime dropped an exception: ours is sent again a moment later, not printed."""
    st = _STATE
    if isinstance(unraisable.exc_value, Interrupted) and st.depth > 0:
        st.dropped = True
        with st.lock:
            timer = threading.Timer(REDELIVER_S, _redeliver, (unraisable.exc_value.signum,))
            timer.daemon = True
            st.timers.append(timer)
            timer.start()
        return
    (st.hook or sys.__unraisablehook__)(unraisable)


def seen(exc: BaseException) -> None:
    """The work caught ``exc`` (the signal's exception): further signals are only recorded."""
    if isinstance(exc, Interrupted):
        _STATE.seen = True
        if _STATE.pending is None:
            _STATE.pending = exc.signum


@contextmanager
def honoured(*, hold_after: bool = False) -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`Interrupted` / :class:`Terminated` in this block,
    wherever they land (module docstring). Outside the main thread, a no-op.

    ``hold_after`` (a process that ends after the block: the console script): from the
    block's end on, the two signals are ignored, so that one arriving after the work, during
    the interpreter's clean-up at exit, neither prints a traceback nor changes the exit status
    the work ended with."""
    st = _STATE
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    st.depth += 1
    if st.depth == 1:
        st.pending, st.seen, st.dropped, st.timers = None, False, False, []
        st.previous = {s: signal.signal(s, _handler) for s in SIGNALS}
        st.hook, sys.unraisablehook = sys.unraisablehook, _unraisable
    try:
        yield
        check()  # a signal dropped in the last instants of the work still ends it
    except Interrupted as exc:
        seen(exc)
        raise
    finally:
        st.depth -= 1
        if st.depth == 0:
            with st.lock:  # no re-delivery from here on: handlers are ours until restored
                for timer in st.timers:
                    timer.cancel()
            sys.unraisablehook, st.hook = st.hook or sys.__unraisablehook__, None
            for s, previous in st.previous.items():
                # ignored, not blocked: a signal goes to any thread that does not block it,
                # and Python resets its own handlers (not SIG_IGN) to the default at exit
                signal.signal(s, signal.SIG_IGN if hold_after else previous)
