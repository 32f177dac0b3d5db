"""SIGINT and SIGTERM at many instants of a real sweep (or cohort): each run must end with exit 130 / 143,
one line on stderr, no traceback, the run recorded ``interrupted`` in the manifest; the same
command then resumes it to the region an uninterrupted run computes.

    python docs/scripts/signal_instants.py [--instants 10] [--command sweep|cohort]
        [--out /tmp/signal_instants]

(--instants per signal: 10 gives 20 runs stopped, each resumed.)

With ``--kill`` the process is killed without a word instead (SIGKILL: power loss, the OOM
killer), at ``--instants`` instants of the command (sweep, cohort, table, simulate or report):
the next run must record the killed one ``killed``, complete, and write every table (each
.csv and .parquet file of the folder) byte for byte as the uninterrupted run did.

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
    "table": (["table", "--forces", "20,80", "--set", "scenario.t_end=2"], "table.csv"),
    "simulate": (["simulate", "--forces", "0,60,120", "--durations", "0.1,0.3", "--set",
                  "scenario.t_end=2"], "summary.csv"),
    "report": (["report", "--scale", "tiny", "--studies", "backward"], "report.json"),
}
COMMAND = "sweep"


def start(out: Path) -> subprocess.Popen:
    argv = COMMANDS[COMMAND][0]
    return subprocess.Popen([sys.executable, "-m", "mjx_balance", "-q", *argv, "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_manifest(out: Path, proc: subprocess.Popen) -> float:
    """When the run's folder has its manifest (the report: when its folder exists; each of
    its stages' folders has its own manifest)."""
    marker = out if COMMAND == "report" else out / "manifest.json"
    while not marker.exists():
        if proc.poll() is not None:
            raise RuntimeError(f"ended before its manifest: {proc.stderr.read()}")
        time.sleep(0.005)
    return time.perf_counter()


def region(out: Path) -> pd.DataFrame:
    path = out / COMMANDS[COMMAND][1]
    frame = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    return frame.reset_index(drop=True)


def instant(span: float, k: int, n: int) -> float:
    """The k-th of n instants spread over ``span`` seconds (the last just before its end)."""
    return span * k / max(n - 1, 1) * 0.98


def stopped(out: Path, at: float, signum: int) -> tuple[subprocess.Popen, str]:
    """Start the command into ``out``, send ``signum`` ``at`` seconds after its manifest
    appeared; the ended process and its stderr."""
    proc = start(out)
    t0 = wait_for_manifest(out, proc)
    time.sleep(max(0.0, at - (time.perf_counter() - t0)))
    os.kill(proc.pid, signum)
    _, err = proc.communicate()
    return proc, err


def tables(out: Path) -> dict[str, bytes]:
    """Every table a run wrote (each .csv and .parquet file under ``out``), by relative path."""
    return {str(p.relative_to(out)): p.read_bytes()
            for p in sorted(out.rglob("*")) if p.suffix in (".csv", ".parquet")}


def leftovers(out: Path) -> int:
    """Temporary files of an atomic write the kill cut short, still in the folder."""
    return sum(1 for p in out.rglob("*") if p.name.startswith(".") and p.name.endswith(".tmp"))


def killed(args, span: float, whole: Path) -> int:
    """SIGKILL at ``args.instants`` instants; each folder rerun and compared byte for byte."""
    expected = tables(whole)
    print(f"| instant [s] | killed | recorded | rerun exit | tables identical "
          f"(of {len(expected)}) | temporary files left |")
    print("|---|---|---|---|---|---|")
    failures = 0
    for k in range(args.instants):
        at = instant(span, k, args.instants)
        out = args.out / f"KILL-{k:02d}"
        proc, _ = stopped(out, at, signal.SIGKILL)
        was_killed = proc.returncode == -signal.SIGKILL
        again = start(out)
        _, err = again.communicate()
        manifest = out / "manifest.json"
        first = json.loads(manifest.read_text())["runs"][0]["status"] if manifest.exists() else "-"
        got = tables(out)
        same = sum(got.get(name) == data for name, data in expected.items())
        # killed mid-work: the rerun records it "killed"; a kill after the work ended finds
        # the run "completed"
        ok = (again.returncode == 0 and got == expected and "Traceback" not in err
              and first in ("killed", "completed", "-"))
        failures += not ok
        print(f"| {at:.2f} | {'yes' if was_killed else 'no (ended first)'} | {first} | "
              f"{again.returncode} | {same} | {leftovers(out)} |" + ("" if ok else " <- FAILED"))
    print(f"{failures} failed of {args.instants}")
    return 1 if failures else 0


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--instants", type=int, default=10)
    parser.add_argument("--out", type=Path, default=Path("/tmp/signal_instants"))
    parser.add_argument("--command", choices=sorted(COMMANDS), default="sweep")
    parser.add_argument("--kill", action="store_true", help="SIGKILL instead of INT and TERM")
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
    if args.kill:
        print(f"uninterrupted: {span:.1f} s from the manifest to the end, "
              f"{len(tables(whole))} tables")
        return killed(args, span, whole)
    expected = region(whole)
    print(f"uninterrupted: {span:.1f} s from the manifest to the end, {len(expected)} cells")
    print("| signal | instant [s] | exit | stderr lines | recorded | resumed to the same region |")
    print("|---|---|---|---|---|---|")
    failures = 0
    for signum, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        for k in range(args.instants):
            at = instant(span, k, args.instants)
            out = args.out / f"{signum.name}-{k:02d}"
            proc, err = stopped(out, at, signum)
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
