"""Every write site faulted (docs/reliability.md, "Every write site faulted"): a small run of a
command, and again with its k-th file opened for writing failing, for every k.

    python docs/scripts/write_faults.py --command sweep [--out /tmp/write_faults] [--limit N]
        [--per-site] [--shard I/N] [--sites REGEX] [--done EARLIER.txt ...]

The shim ``write_faults.c`` (compiled here with the C compiler, loaded with LD_PRELOAD) counts
every file opened for writing under the run's folder (its tables, chunks, manifests, locks,
exports, figures, the report) and under the compilation cache, in every library of the process
(Python, Arrow, matplotlib, XLA). A first run counts them: the write sites (distinct paths, digits
and temporary names folded) and the opens. Then for each k, a fresh folder and the same command
with the k-th open failing: where the counted run wrote through that open, ``ENOSPC`` or ``EIO``
(in turn) at its first write and every later one, as a full disk or a failing one; where it did
not (a temporary file made, then written through another open), ``EROFS`` at the open itself.
Each faulted run must

- exit non-zero with one line on stderr naming the file and the cause, no traceback; or exit 0
  where the fault struck the compilation cache (a cache that cannot be written costs a compile,
  not the run) or refused to open a folder's lock read-only (a read-only folder is read without
  a lock, by design: store.folder.folder_lock), with every table as the clean run's;
- leave no table (a .csv or .parquet file) that differs from the clean run's other than by
  being absent, and no temporary file;

and the same command rerun without a fault in the same folder must exit 0 with every table byte
for byte the clean run's. Last, a run on an empty compilation cache whose first entry cannot be
written must complete as the clean run. The table printed is the one in docs/reliability.md.
"""

from __future__ import annotations

import argparse
import errno
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
T_END = ["--set", "scenario.t_end=1"]
COMMANDS = {
    "sweep": ["sweep", "--forces", "0,80", "--durations", "0.1,0.5", *T_END],
    "table": ["table", "--forces", "40", *T_END],
    "simulate": ["simulate", "--forces", "0,60", "--durations", "0.2", *T_END],
    "cohort": ["cohort", "--heights", "1.6,1.8", "--masses", "60", "--forces", "0,80",
               "--durations", "0.2", *T_END],
    "report": ["report", "--scale", "tiny", "--studies", "backward"],
    "explore": ["sweep", "--forces", "0,80", "--durations", "0.1,0.5", *T_END],  # its map
}
CELL = (80.0, 0.5)  # explore: the cell clicked (force N, duration s)
CLICK = f"/api/run?map=&force={CELL[0]:g}&duration={CELL[1]:g}"
ERRNOS = (errno.ENOSPC, errno.EIO, errno.EROFS)


def shim(build: Path) -> Path:
    """The shim, compiled into ``build``."""
    library = build / "write_faults.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-w", "-o", str(library),
                    str(HERE / "write_faults.c")], check=True)
    return library


def run(argv, out: Path, cache: Path, library: Path, log: Path, fail_at: int = 0,
        code: int = 0) -> subprocess.CompletedProcess:
    env = dict(os.environ, LD_PRELOAD=str(library), WF_ROOT=f"{out}:{cache}", WF_LOG=str(log),
               WF_FAIL_AT=str(fail_at), WF_ERRNO=str(code),
               MJX_BALANCE_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, "-m", "mjx_balance", "-q", *argv, "--out", str(out)],
                          env=env, capture_output=True, text=True)


def tables(out: Path) -> dict[str, bytes]:
    """Every table under ``out`` (each .csv and .parquet file), by relative path."""
    return {str(p.relative_to(out)): p.read_bytes()
            for p in sorted(out.rglob("*")) if p.is_file() and p.suffix in (".csv", ".parquet")}


def whole(path: Path) -> bool:
    """Whether a table reads back (parquet or CSV)."""
    import pandas as pd

    try:
        (pd.read_parquet if path.suffix == ".parquet" else pd.read_csv)(path)
    except Exception:
        return False
    return True


def temporary(out: Path) -> list[str]:
    return [str(p) for p in out.rglob("*") if p.name.startswith(".") and ".tmp" in p.name]


def site(path: str, out: Path, cache: Path) -> str:
    """A write site: the path under its root with digits and temporary names folded."""
    for root, name in ((out, "OUT"), (cache, "CACHE")):
        if path.startswith(str(root)):
            path = name + path[len(str(root)):]
    path = re.sub(r"/\.([^/]+)\.[^./]+\.tmp$", r"/.\1.*.tmp", path)
    path = re.sub(r"/tmp[a-z0-9_]{6,}", "/tmp*", path)
    path = re.sub(r"[0-9a-f]{16,}", "<hash>", path)
    return re.sub(r"\d+", "#", path)


def role(site_name: str) -> str:
    """A write site's file name, its folder left out: the one writer behind a file of that name
    in any of a run's folders (a sweep's region.parquet under paper/ and under joint/)."""
    return site_name.rsplit("/", 1)[-1]


def roles_first(chosen: list[int], sites: dict[int, str], written: dict[int, str]) -> list[int]:
    """``chosen`` with each role's first open (written through and not) before the rest, so
    that a run stopped early has faulted every role once; each part in the order of k."""
    seen, first, rest = set(), [], []
    for k in chosen:
        key = (role(sites[k]), k in written)
        (rest if key in seen else first).append(k)
        seen.add(key)
    return first + rest


def done_before(outputs: list[Path]) -> set[tuple[str, bool]]:
    """The faults an earlier harness's printed table passed ("ok"), as (site, written
    through): an enumeration cut short goes on where it stopped, the counted run's numbering
    aside (the earlier run may have counted other opens before the same site)."""
    row = re.compile(r"^\| \d+ \| (\S+) \| (E[A-Z]+) \|.*\| ok \|$")
    found = set()
    for output in outputs:
        for line in output.read_text().splitlines():
            if match := row.match(line.strip()):
                found.add((match.group(1), match.group(2) != "EROFS"))
    return found


def entries(log: Path, kind: str) -> dict[int, str]:
    """The log's ``kind`` lines ("open", "write", "fault") as count -> path."""
    out = {}
    for line in log.read_text().splitlines() if log.exists() else []:
        word, n, path = line.split(" ", 2)
        if word == kind:
            out.setdefault(int(n), path)
    return out


def struck(log: Path) -> str | None:
    faults = entries(log, "fault")
    return next(iter(faults.values())) if faults else None


def target(path: str) -> str:
    """The file a write to ``path`` makes: an atomic write's target for its temporary file."""
    return re.sub(r"^\.(.+)\.[^.]+\.tmp$", r"\1", Path(path).name)


def verdict(proc, path: str | None, code: int, cache: Path, clean: dict, out: Path) -> str:
    """'' when the faulted run behaved, else what went wrong."""
    lines = proc.stderr.strip().splitlines()
    got = tables(out)
    # a table the clean run also wrote must be its bytes or absent; one it did not keep (a
    # push's series, kept to resume and merged at the end) must be whole
    stray = [n for n, data in got.items() if n in clean and clean[n] != data]
    stray += [n for n in got if n not in clean and not whole(out / n)]
    if stray:
        return f"table {stray[0]} differs from the clean run's or is not whole"
    if "Traceback" in proc.stderr:
        return "traceback"
    if path is None:  # opened but never written: nothing failed
        return "" if proc.returncode == 0 else f"exit {proc.returncode} without a fault"
    if proc.returncode == 0:
        if path.startswith(str(cache)):
            return ""
        if Path(path).name == ".lock" and code == errno.EROFS:
            return ""  # a folder that cannot be opened for writing is read without a lock
        return "exit 0 after a failed write"
    if len(lines) != 1:
        return f"{len(lines)} lines on stderr"
    if os.strerror(code) not in lines[0]:
        return "the cause is not named"
    if target(path) not in lines[0] and Path(path).name not in lines[0]:
        return "the file is not named"
    return ""


def cold_cache(argv, root: Path, library: Path, clean: dict) -> str:
    """A run on an empty compilation cache whose first cache entry cannot be written: it
    must complete with the clean run's tables (a cache that cannot be written costs a compile
    next time, not this run). '' when it does."""
    cache, out, log = root / "cold-cache", root / "cold", root / "cold.log"
    clean_log = root / "clean.log"  # the clean run, on its own empty cache
    if not any(p.startswith(str(root / "cache")) for p in entries(clean_log, "open").values()):
        return ""  # the command compiles nothing (simulate: MuJoCo C and OSQP)
    proc = run(argv, out, cache, library, log, 1, errno.ENOSPC)
    path = struck(log)
    if path is None or not path.startswith(str(cache)):
        return f"the fault struck {path}, not the cache"
    if proc.returncode != 0 or "Traceback" in proc.stderr:
        return f"exit {proc.returncode}: {proc.stderr.strip()[-200:]}"
    return "" if tables(out) == clean else "tables differ"


def serve(folder: Path, library: Path, log: Path, fail_at: int = 0, code: int = 0):
    """``explore FOLDER`` under the shim (every write under FOLDER counted), one click on
    :data:`CLICK`, then Ctrl-C: (HTTP status, its JSON, the server's exit code, its stderr)."""
    import json
    import signal
    import time
    import urllib.request

    env = dict(os.environ, LD_PRELOAD=str(library), WF_ROOT=str(folder), WF_LOG=str(log),
               WF_FAIL_AT=str(fail_at), WF_ERRNO=str(code))
    proc = subprocess.Popen([sys.executable, "-m", "mjx_balance", "explore", str(folder),
                             "--no-browser"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()  # "explore: FOLDER at http://127.0.0.1:PORT/ (...)"
    found = re.search(r"http://127\.0\.0\.1:\d+/", first)
    if found is None:
        proc.kill()
        out, err = proc.communicate()
        return 0, {}, proc.returncode, first + out + err
    try:
        with urllib.request.urlopen(found.group(0).rstrip("/") + CLICK, timeout=300) as answer:
            status, data = answer.status, json.loads(answer.read())
    except urllib.error.HTTPError as exc:
        status, data = exc.code, json.loads(exc.read() or b"{}")
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    return status, data, proc.returncode, err


def kept_frame(folder: Path):
    """The clicked cell's kept run (its columns; the attrs hold when it was computed)."""
    import pandas as pd

    path = folder / "explore" / f"{CELL[0]}_{CELL[1]}.parquet"  # as explore names it
    return pd.read_parquet(path) if path.exists() else None


def explore_faults(args, library: Path) -> int:
    """Every file explore's click writes faulted in turn (see the module's docstring): the
    click is answered (200) with the run and a note naming the file and the cause, no half
    or temporary file is left, the server stops on Ctrl-C (130) without a traceback, and a
    later server on the same folder computes the cell again and keeps it whole."""
    proc = subprocess.run([sys.executable, "-m", "mjx_balance", "-q", *COMMANDS["explore"],
                           "--out", str(args.out / "map")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    clean_dir, log = args.out / "clean", args.out / "clean.log"
    shutil.copytree(args.out / "map", clean_dir)
    status, data, code, err = serve(clean_dir, library, log)
    assert status == 200 and data.get("note") is None and code == 130, (status, data, err)
    clean = kept_frame(clean_dir)
    paths, written = entries(log, "open"), entries(log, "write")
    print(f"explore: {len(paths)} files opened for writing ({len(written)} written through) by "
          f"one click; faulting each (ENOSPC and EIO where written through, else EROFS)")
    print("| k | file | errno | status | note | exit | rerun kept whole and equal | verdict |")
    print("|---|---|---|---|---|---|---|---|")
    failures = 0
    faults = [(k, c) for k in sorted(paths) for c in (ERRNOS[:2] if k in written else ERRNOS[2:])]
    for k, errno_ in faults:
        name = f"k{k:03d}-{errno.errorcode[errno_]}"
        folder, log = args.out / name, args.out / f"{name}.log"
        shutil.copytree(args.out / "map", folder)
        status, data, code, err = serve(folder, library, log, k, errno_)
        path, note = struck(log), str(data.get("note"))
        problem = ""
        if status != 200 or not data.get("summary"):
            problem = f"answered {status}"
        elif path and (os.strerror(errno_) not in note or target(path) not in note):
            problem = "the note does not name the cause and the file"
        elif code != 130 or "Traceback" in err:
            problem = f"the server ended with {code}"
        elif temporary(folder):
            problem = "temporary file left"
        else:
            half = kept_frame(folder) if (folder / "explore").exists() else None
            if half is not None and not half.equals(clean):
                problem = "a kept run differs"
        status2, *_ = serve(folder, library, args.out / f"{name}.rerun.log")
        again = kept_frame(folder)
        same = status2 == 200 and again is not None and again.equals(clean)
        if not same and not problem:
            problem = "the rerun did not keep the run"
        failures += bool(problem)
        shown = site(path, folder, folder) if path else "(not written)"
        print(f"| {k} | {shown} | {errno.errorcode[errno_]} | {status} | {note[:80]} | {code} | "
              f"{'yes' if same else 'NO'} | {problem or 'ok'} |", flush=True)
    print(f"{failures} failed of {len(faults)}")
    return 1 if failures else 0


def shard(text: str) -> tuple[int, int]:
    """``I/N`` read as (I, N), 1 <= I <= N; else the option is refused in one line."""
    found = re.fullmatch(r"(\d+)/(\d+)", text)
    if not found or not 1 <= int(found.group(1)) <= int(found.group(2)):
        raise argparse.ArgumentTypeError(f"{text!r} is not I/N with 1 <= I <= N")
    return int(found.group(1)), int(found.group(2))


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--command", choices=sorted(COMMANDS), default="sweep")
    parser.add_argument("--out", type=Path, default=Path("/tmp/write_faults"))
    parser.add_argument("--limit", type=int, default=0, help="fault at most N opens (0: all)")
    parser.add_argument("--per-site", action="store_true",
                        help="fault each write site's first open written through and its first "
                        "open not written through, instead of every open; each file name's "
                        "first before the rest")
    parser.add_argument("--shard", type=shard, default="1/1",
                        help="I/N: fault only the I-th of every N chosen opens (harnesses side "
                        "by side, each with its own --out)")
    parser.add_argument("--sites", default="",
                        help="fault only the opens whose write site matches this regular "
                        "expression (e.g. 'sensitivity/[a-z_]+/[^.]')")
    parser.add_argument("--done", type=Path, nargs="*", default=[],
                        help="earlier harnesses' printed output: skip the faults their tables "
                        "passed (the same site, written through or not)")
    args = parser.parse_args()
    missing = [str(p) for p in args.done if not p.is_file()]
    if missing:  # before the folder is cleared and the clean runs made
        parser.error(f"--done: no such file: {', '.join(missing)}")
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)
    library = shim(Path(tempfile.mkdtemp(dir=args.out)))
    if args.command == "explore":
        return explore_faults(args, library)
    argv = COMMANDS[args.command]
    cache = args.out / "cache"
    clean_out, log = args.out / "clean", args.out / "clean.log"
    first = run(argv, clean_out, cache, library, log)
    assert first.returncode == 0, first.stderr
    # counted once the cache has settled (the run after the first records the cache entries
    # it checked, verified.json: a write the later runs do not make), so that the k-th open of
    # the counted run is the k-th of every faulted run
    for name in ("settle", "counted"):
        counted = run(argv, args.out / name, cache, library, args.out / f"{name}.log")
        assert counted.returncode == 0, counted.stderr
    clean = tables(clean_out)
    cold = cold_cache(argv, args.out, library, clean)
    paths = entries(args.out / "counted.log", "open")
    written = entries(args.out / "counted.log", "write")
    named = {k: site(p, args.out / "counted", cache) for k, p in paths.items()}  # k -> site
    sites = sorted(set(named.values()))
    n = len(paths) if not args.limit else min(args.limit, len(paths))
    chosen = list(range(1, n + 1))
    if args.per_site:
        firsts = {}
        for k in sorted(paths):
            firsts.setdefault((named[k], k in written), k)
        chosen = roles_first(sorted(firsts.values()), named, written)
    if args.sites:
        chosen = [k for k in chosen if re.search(args.sites, named[k])]
    if args.done:
        passed = done_before(args.done)
        chosen = [k for k in chosen if (named[k], k in written) not in passed]
    index, shards = args.shard
    chosen = chosen[index - 1::shards]
    print(f"{args.command}: {len(paths)} files opened for writing ({len(written)} written "
          f"through), {len(sites)} write sites, {len(clean)} tables; faulting "
          + (f"{len(chosen)} opens (each site's first, written and not)" if args.per_site
             else f"opens 1..{n}"))
    for s in sites:
        print(f"  site {s}")
    print("| k | file | errno | exit | stderr | rerun exit | tables identical | verdict |")
    print("|---|---|---|---|---|---|---|---|")
    failures = 0
    for k in chosen:
        if k in written:  # ENOSPC, EIO in turn
            code = ERRNOS[sorted(written).index(k) % 2]
        else:
            code = errno.EROFS
        out, log = args.out / f"k{k:03d}", args.out / f"k{k:03d}.log"
        proc = run(argv, out, cache, library, log, k, code)
        path = struck(log)
        problem = verdict(proc, path, code, cache, clean, out)
        left = temporary(out)
        if left and not problem:
            problem = f"temporary file left: {left[0]}"
        again = run(argv, out, cache, library, args.out / f"k{k:03d}.rerun.log")
        same = again.returncode == 0 and tables(out) == clean
        if not same and not problem:
            problem = f"the rerun: exit {again.returncode}, tables differ"
        failures += bool(problem)
        shown = site(path, out, cache) if path else "(not written)"
        line = proc.stderr.strip().splitlines()[-1][:90] if proc.stderr.strip() else ""
        print(f"| {k} | {shown} | {errno.errorcode[code]} | {proc.returncode} | {line} | "
              f"{again.returncode} | {'yes' if same else 'NO'} | {problem or 'ok'} |", flush=True)
    print(f"cold cache, its first entry's write failing (ENOSPC): {cold or 'ok'}")
    failures += bool(cold)
    print(f"{failures} failed of {len(chosen) + 1}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
