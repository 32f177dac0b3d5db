"""The progress bar of long sweeps (tqdm on stderr), or a silent stand-in."""

from __future__ import annotations

import sys


class NoBar:
    def update(self, _n: int) -> None:
        pass

    def close(self) -> None:
        pass


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


def progress_bar(total: int, done: int, enabled: bool):
    if not enabled or not usable(sys.stderr):
        return NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=done, unit="scen", desc="scenarios", dynamic_ncols=True,
                smoothing=0.1, file=SafeStream(sys.stderr))
