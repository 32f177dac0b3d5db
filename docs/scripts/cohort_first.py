"""A large cohort's first scenario: how long ``mjx-balance cohort --population N`` takes from
the command to its plan line, to its first engine queue (its first scenarios start), and to its
first subject's region.parquet on disk; then the run is interrupted (SIGINT) and must end in
one line with exit code 130, what finished kept.

    python docs/scripts/cohort_first.py [SUBJECTS] [OUT]

Defaults: 100,000 subjects (``--seed 1``, two cells: 0 and 50 N for 0.1 s, 2-s windows) into a
temporary folder. The compile cache is the user's (a warm cache is the usual case; empty it,
or set MJX_BALANCE_CACHE_DIR to a new folder, for a cold start).
"""

from __future__ import annotations

import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

MARKS = {
    "plan": "planned work:",
    "queue": "in one engine queue",
}


def main(count: int = 100_000, out: str | None = None) -> None:
    folder = Path(out or tempfile.mkdtemp()) / "cohort"
    words = [sys.executable, "-u", "-m", "mjx_balance", "cohort", "--population", str(count)]
    words += ["--seed", "1", "--forces", "0,50", "--durations", "0.1"]
    words += ["--set", "scenario.t_end=2", "--out", str(folder)]
    start = time.perf_counter()
    seen: dict[str, float] = {}
    lines: list[str] = []
    proc = subprocess.Popen(words, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip())
            for name, text in MARKS.items():
                if text in line and name not in seen:
                    seen[name] = time.perf_counter() - start

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    while proc.poll() is None and "region" not in seen:
        if any((folder / "subjects").glob("*/region.parquet")):
            seen["region"] = time.perf_counter() - start
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    code = proc.wait(timeout=300)
    reader.join(timeout=10)
    for name in ("plan", "queue", "region"):
        print(f"{name:>6}: {seen.get(name, float('nan')):6.1f} s")
    print(f"exit code after SIGINT: {code}; last line: {lines[-1] if lines else ''}")
    kept = len(list((folder / "subjects").glob("*/region.parquet")))
    print(f"subjects' maps kept: {kept} of {count}")


if __name__ == "__main__":
    main(*(int(a) if i == 0 else a for i, a in enumerate(sys.argv[1:])))
