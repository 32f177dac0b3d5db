"""The progress bar of long sweeps (tqdm on stderr), or a silent stand-in."""

from __future__ import annotations

import sys


class NoBar:
    def update(self, _n: int) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(total: int, done: int, enabled: bool):
    if not enabled:
        return NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=done, unit="scen", desc="scenarios", dynamic_ncols=True,
                smoothing=0.1, file=sys.stderr)
