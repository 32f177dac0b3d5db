"""What a command spends before its work: the wall time of tiny runs (work of a second or less),
each with an empty compile cache (cold) and then again with the cache it filled (warm), every
run in a new folder. The plan line counts the fewest and most of these as the start-up
(``runs.chunks.ENGINE_STARTUP``, ``REFERENCE_STARTUP``).

    python docs/scripts/startup.py [OUT]
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SHORT = ["--set", "scenario.t_end=2"]
RUNS = {
    "sweep (2 cells)": ["sweep", "--forces", "0,50", "--durations", "0.1", *SHORT],
    "table (1 force)": ["table", "--forces", "50", *SHORT],
    "cohort (2 subjects x 2 cells)": [
        *("cohort", "--population", "2", "--seed", "1", "--forces", "0,50", "--durations", "0.1", *SHORT)
    ],
    "simulate (1 push)": ["simulate", "--forces", "50", "--durations", "0.1", *SHORT],
}


def main(out: str | None = None) -> None:
    root = Path(out or tempfile.mkdtemp())
    print("command | cold [s] | warm [s]")
    for n, (name, words) in enumerate(RUNS.items()):
        env = {**os.environ, "MJX_BALANCE_CACHE_DIR": str(root / f"cache{n}")}
        seconds = []
        for sitting in ("cold", "warm"):
            command = [sys.executable, "-m", "mjx_balance", "-q", *words]
            start = time.perf_counter()
            subprocess.run([*command, "--out", str(root / f"{n}_{sitting}")], env=env, check=True)
            seconds.append(time.perf_counter() - start)
        print(f"{name} | {seconds[0]:.1f} | {seconds[1]:.1f}", flush=True)


if __name__ == "__main__":
    main(*sys.argv[1:2])
