"""The progress bar of long sweeps (tqdm on stderr), or a silent stand-in, and when to draw
one (:func:`wanted`). Every update is a checkpoint of the work: a pending SIGINT or SIGTERM
whose exception was dropped where it landed is raised there (runtime/signals.py)."""

from __future__ import annotations

import sys

from ..runtime import signals


class NoBar:
    n = 0

    def update(self, n: int) -> None:
        signals.check()
        self.n += n

    def close(self) -> None:
        pass


class CheckedBar:
    """A tqdm bar whose every update is a checkpoint."""

    def __init__(self, bar) -> None:
        self.bar = bar

    def update(self, n: int) -> None:
        signals.check()
        self.bar.update(n)

    def __getattr__(self, name: str):
        return getattr(self.bar, name)


class SafeStream:
    """A stream whose writes cannot fail the run: a closed, full or broken stderr drops the
    bar's output (the bar is a courtesy; the results are in files)."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> int:
        try:
            return self.stream.write(text)
        except (OSError, ValueError, AttributeError):
            return 0

    def flush(self) -> None:
        try:
            self.stream.flush()
        except (OSError, ValueError, AttributeError):
            pass

    def isatty(self) -> bool:
        try:
            return self.stream.isatty()
        except (OSError, ValueError, AttributeError):
            return False


def usable(stream) -> bool:
    """Whether ``stream`` is there and open."""
    return stream is not None and not getattr(stream, "closed", False)


def in_notebook() -> bool:
    """Whether this process is a Jupyter kernel (IPython with a kernel; nothing imported)."""
    ipython = sys.modules.get("IPython")
    shell = getattr(ipython, "get_ipython", lambda: None)() if ipython is not None else None
    return shell is not None and hasattr(shell, "kernel")


def wanted(progress: bool | None) -> bool:
    """Whether to draw progress bars. ``None`` (the Python API's default): where someone
    watches, a terminal on stderr or a Jupyter notebook (its stderr is no terminal; tqdm.auto
    draws a widget there), not where stderr is redirected (a file, a pipe, pytest's capture,
    a CI log) or closed. ``True``: wherever stderr is open. ``False``: never."""
    if progress is not None:
        return bool(progress) and usable(sys.stderr)
    return usable(sys.stderr) and (SafeStream(sys.stderr).isatty() or in_notebook())


def progress_bar(total: int, done: int, enabled: bool | None, desc: str = "scenarios"):
    """A bar of ``total`` scenarios (fixed: it never changes while the bar runs; tqdm shows
    the rate and the time left), ``done`` of them already, or a silent stand-in; ``enabled``
    as :func:`wanted` reads it."""
    if not wanted(enabled):
        bar = NoBar()
        bar.n = done
        return bar
    from tqdm.auto import tqdm

    return CheckedBar(
        tqdm(
            total=total,
            initial=done,
            unit="scen",
            desc=desc,
            dynamic_ncols=True,
            smoothing=0.1,
            file=SafeStream(sys.stderr),
        )
    )
