"""SIGINT and SIGTERM at many instants of a real sweep (or cohort): each run must end with exit 130 / 143,
one line on stderr, no traceback, the run recorded ``interrupted`` in the manifest; the same
command then resumes it to the region an uninterrupted run computes.

    python docs/scripts/signal_instants.py [--instants 10] [--command sweep|cohort]
        [--out /tmp/signal_instants]

(--instants per signal: 10 gives 20 runs stopped, each resumed.)

The instants are spread from the moment the folder's manifest appears to the end of an
uninterrupted run (measured first), so they fall in start-up, compile or cache load, the
engine's blocks, chunk writes, the merge and the figures. docs/reliability.md records the
table it prints.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

# The work, and the table it ends in (compared with an uninterrupted run's).
COMMANDS = {
    "sweep": (["sweep", "--forces", "0:150:10", "--durations", "0.1:2:0.1", "--set",
               "scenario.t_end=2", "--chunk", "32"], "region.parquet"),
    "cohort": (["cohort", "--heights", "1.6,1.8", "--masses", "60,80", "--forces", "0:150:30",
                "--durations", "0.1:1:0.3", "--set", "scenario.t_end=2"], "cohort.csv"),
}
COMMAND = "sweep"


def start(out: Path) -> subprocess.Popen:
    argv = COMMANDS[COMMAND][0]
    return subprocess.Popen([sys.executable, "-m", "mjx_balance", "-q", *argv, "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_manifest(out: Path, proc: subprocess.Popen) -> float:
    while not (out / "manifest.json").exists():
        if proc.poll() is not None:
            raise RuntimeError(f"ended before its manifest: {proc.stderr.read()}")
        time.sleep(0.005)
    return time.perf_counter()


def region(out: Path) -> pd.DataFrame:
    path = out / COMMANDS[COMMAND][1]
    frame = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    return frame.reset_index(drop=True)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--instants", type=int, default=10)
    parser.add_argument("--out", type=Path, default=Path("/tmp/signal_instants"))
    parser.add_argument("--command", choices=sorted(COMMANDS), default="sweep")
    args = parser.parse_args()
    global COMMAND
    COMMAND = args.command
    shutil.rmtree(args.out, ignore_errors=True)
    whole = args.out / "whole"
    proc = start(whole)
    t0 = wait_for_manifest(whole, proc)
    proc.communicate()
    span = time.perf_counter() - t0
    assert proc.returncode == 0, proc.returncode
    expected = region(whole)
    print(f"uninterrupted: {span:.1f} s from the manifest to the end, {len(expected)} cells")
    print("| signal | instant [s] | exit | stderr lines | recorded | resumed to the same region |")
    print("|---|---|---|---|---|---|")
    failures = 0
    for signum, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        for k in range(args.instants):
            at = span * k / max(args.instants - 1, 1) * 0.98
            out = args.out / f"{signum.name}-{k:02d}"
            proc = start(out)
            t0 = wait_for_manifest(out, proc)
            time.sleep(max(0.0, at - (time.perf_counter() - t0)))
            os.kill(proc.pid, signum)
            _, err = proc.communicate()
            lines = err.strip().splitlines()
            status = json.loads((out / "manifest.json").read_text())["runs"][-1]["status"]
            again = start(out)
            again.communicate()
            same = again.returncode == 0 and region(out).equals(expected)
            # a signal after the work ended (the process exiting) may find nothing to stop
            done = proc.returncode == 0 and status == "completed"
            ok = same and "Traceback" not in err and (
                done or (proc.returncode == code and len(lines) == 1
                         and status == "interrupted"))
            failures += not ok
            print(f"| {signum.name} | {at:.2f} | {proc.returncode} | {len(lines)} | {status} | "
                  f"{'yes' if same else 'NO'} |" + ("" if ok else " <- FAILED"))
    print(f"{failures} failed of {2 * args.instants}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
