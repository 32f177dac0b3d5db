"""The output folder of a sweep: manifest, configuration, chunk files, merged results.

``DIR/manifest.json`` records the package version, the configuration and what was computed
(the region's grid and chunk size, the table's forces), and, in ``runs``, one provenance record
per run that worked in the folder (:func:`provenance`: versions, physics path, device, git
commit, command line, start and end times, how it ended); ``DIR/config.toml`` holds the
configuration as TOML. Only the configuration and the grids decide whether a run may resume a
folder; the provenance records differ between runs by design and are never compared. A folder made with another configuration is refused; a folder that lost
its manifest is taken up again when its config.toml matches the run's (the region sweep then
checks its chunk files against the grid before it rewrites the manifest). Every file is
written atomically (a temporary file in the same folder, then ``os.replace``), so a file is
either complete or absent, with the mode the umask gives (:func:`write_atomic`, figures through
:func:`write_figure`). Region chunks live in ``DIR/chunks/chunk-NNNNN.parquet``; a chunk file
is used only if it reads back with exactly its cells (:func:`read_chunk`), and the merge
streams the chunks into ``DIR/region.parquet`` one at a time (:func:`merge_chunks`).

One run at a time per folder: :func:`folder_lock` holds an exclusive ``flock`` on
``DIR/.lock`` (which names the holder's PID and start time) and a second run is refused at once
(:class:`FolderBusy`), or waits for the lock when asked to (``wait=True``).

The table keeps every scenario it evaluates in ``DIR/table_runs/part-NNNNN.parquet``, one file
per batch call, written as the call returns (:class:`TableCells`): a rerun, or a table over
other forces in the same folder, reads them back instead of running them again.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import threading
import uuid
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np
import pandas as pd

from ..runtime.version import __version__
from ..measures.outcomes import OUTCOMES, SUMMARY_COLUMNS
from ..model.params import Config, ParameterError, dumps_config, load_config

GRID_TOL = 1e-9  # how far a value may sit beyond a limit (float error) and still count
MANIFEST = "manifest.json"
REGION = "region.parquet"
TABLE = "table.csv"
TABLE_RUNS = "table_runs.parquet"
TABLE_CELLS = "table_runs"  # folder: the table's evaluated scenarios, one file per batch call
CONFIG = "config.toml"
LOCK = ".lock"

_UMASK_LOCK = threading.Lock()

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------------
# Provenance: what ran, where and when (manifest "runs").

def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


# This process's run: one record per output folder it works in, updated at every manifest
# write and when the folder's lock is let go (end time, status).
_RUN: dict[str, Any] = {"run_id": uuid.uuid4().hex[:12], "started": _now(), "command": None,
                        "physics": "mjx"}


@contextmanager
def run_context(*, command: str | None = None, physics: str | None = None) -> Iterator[None]:
    """The command line (or API call) and the physics path that this process's manifest
    records name, while in the block (an outer context's command is kept: the command line
    that called the API is what ran)."""
    saved = dict(_RUN)
    if command is not None and _RUN["command"] is None:
        _RUN["command"] = command
    if physics is not None:
        _RUN["physics"] = physics
    try:
        yield
    finally:
        _RUN["command"], _RUN["physics"] = saved["command"], saved["physics"]


def note_physics(physics: str) -> None:
    """The physics this process's work in the current run context uses (the rollout, once
    built, says which path it runs: "mjx", or "mujoco" for MuJoCo C)."""
    _RUN["physics"] = physics


def _distribution_version(name: str) -> str | None:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return None


def versions() -> dict[str, str | None]:
    """The versions of the package and of what computes its results (no import of JAX)."""
    return {"package": __version__, "python": platform.python_version(),
            "jax": _distribution_version("jax"), "jaxlib": _distribution_version("jaxlib"),
            "mujoco": _distribution_version("mujoco"),
            "mujoco_mjx": _distribution_version("mujoco-mjx")}


def device_record() -> dict[str, Any]:
    """JAX's devices when JAX has started in this process (platform, device kind, count); else
    the host's CPU (the scalar reference runs there, or JAX has not started yet)."""
    if "jax" in sys.modules:
        try:
            from jax._src import xla_bridge

            if xla_bridge._backends:  # noqa: SLF001 - started: asking starts nothing new
                import jax

                devices = jax.local_devices()
                return {"platform": devices[0].platform, "kind": devices[0].device_kind,
                        "count": len(devices)}
        except Exception:  # noqa: BLE001 - fall back to the host
            pass
    return {"platform": "cpu", "kind": platform.processor() or platform.machine(),
            "count": os.cpu_count() or 1}


_GIT: dict[str, Any] = {}


def git_record() -> dict[str, Any]:
    """The git commit of the package's checkout (and whether it has uncommitted changes), when
    it runs from one; empty when it does not or git is missing (computed once per process)."""
    if _GIT:
        return dict(_GIT.get("record", {}))
    record: dict[str, Any] = {}
    here = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                                text=True, timeout=10)
        if commit.returncode == 0 and commit.stdout.strip():
            record["git_commit"] = commit.stdout.strip()
            dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                                   cwd=here, capture_output=True, text=True, timeout=30)
            if dirty.returncode == 0:
                record["git_dirty"] = bool(dirty.stdout.strip())
    except (OSError, subprocess.SubprocessError):
        pass
    _GIT["record"] = record
    return dict(record)


def default_command() -> str:
    """The command line of this process, as a shell would take it back."""
    argv = list(sys.argv) or ["python"]
    if argv and argv[0].endswith(("/mjx-balance", "mjx_balance/__main__.py")):
        argv[0] = "mjx-balance" if argv[0].endswith("mjx-balance") else "python -m mjx_balance"
    return " ".join(shlex.quote(a) for a in argv)


def provenance() -> dict[str, Any]:
    """This run's provenance record (see the module docstring; docs/outputs.md, ``runs``)."""
    return {"run_id": _RUN["run_id"], "command": _RUN["command"] or default_command(),
            "started": _RUN["started"], "ended": None, "status": "running",
            **versions(), "physics": _RUN["physics"], "device": device_record(), **git_record()}


def _with_run(manifest: dict[str, Any], **changes: Any) -> dict[str, Any]:
    """``manifest`` with this run's record in its ``runs`` (added, or refreshed)."""
    runs = manifest.get("runs")
    runs = [r for r in runs if isinstance(r, dict)] if isinstance(runs, list) else []
    mine = next((r for r in runs if r.get("run_id") == _RUN["run_id"]), None)
    if mine is None:
        mine = provenance()
        runs.append(mine)
    else:
        mine["device"] = device_record()
        mine["physics"] = _RUN["physics"]
    mine.update(changes)
    manifest["runs"] = runs
    return manifest


def _finish_run(folder: Path, status: str) -> None:
    """Record the end time and how the run ended in the folder's manifest, if this run wrote
    one; a failure here (the disk that just failed the run) is not reported again."""
    path = folder / MANIFEST
    try:
        manifest = json.loads(path.read_text())
        runs = manifest.get("runs") if isinstance(manifest, dict) else None
        if not isinstance(runs, list) or not any(
                isinstance(r, dict) and r.get("run_id") == _RUN["run_id"] for r in runs):
            return
        write_text(json.dumps(_with_run(manifest, ended=_now(), status=status), indent=2) + "\n",
                   path)
    except Exception:  # noqa: BLE001 - provenance never fails a run
        pass


def current_umask() -> int:
    """The process's umask: from /proc where Linux shows it, else by setting it and setting it
    back (which another thread creating a file at that moment could see)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    """Write a file atomically: ``write(tmp)`` to a temporary file beside it, then rename.

    The file gets the mode a plain ``open`` would give it (0o666 less the umask), not
    mkstemp's 0o600, so that collaborators sharing the folder can read it."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        os.chmod(tmp, 0o666 & ~current_umask())
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_figure(fig: Any, path: str | Path, **savefig: Any) -> Path:
    """Save a matplotlib figure atomically, in the format its file name ends with."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, **savefig))
    return path


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the IEND chunk: length 0, type, CRC


def readable_png(path: str | Path) -> bool:
    """Whether ``path`` is a whole PNG file: its signature, its IEND chunk last, and every
    chunk's CRC (PIL's verify). A file cut short while being written fails."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(PNG_SIGNATURE))
            fh.seek(0, os.SEEK_END)
            if fh.tell() < len(PNG_SIGNATURE) + len(PNG_END):
                return False
            fh.seek(-len(PNG_END), os.SEEK_END)
            tail = fh.read()
    except OSError:
        return False
    if head != PNG_SIGNATURE or tail != PNG_END:
        return False
    from PIL import Image

    try:
        with Image.open(path) as image:
            image.verify()
    except Exception:  # noqa: BLE001 - any failure means: draw it again
        return False
    return True


def write_parquet(frame: pd.DataFrame, path: Path) -> None:
    write_atomic(path, lambda tmp: frame.to_parquet(tmp, index=False))


def write_text(text: str, path: Path) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(text))


def config_dict(config: Config) -> dict[str, Any]:
    return json.loads(json.dumps(config.to_dict()))


def config_differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """What differs between a folder's recorded configuration and this run's. A key the
    folder lacks was added to the package after the folder was made, when its behaviour was
    the default: it counts as the default."""
    defaults = config_dict(Config())
    out = []
    for section in sorted(set(old) | set(new)):
        a = {**defaults.get(section, {}), **old.get(section, {})}
        b = new.get(section, {})
        for key in sorted(set(a) | set(b)):
            if a.get(key) != b.get(key):
                out.append(f"{section}.{key}: folder has {a.get(key)!r}, this run {b.get(key)!r}")
    return out


def record_simulation(folder: str | Path, config: Config, forces: Any, durations: Any) -> None:
    """The manifest of a ``simulate`` folder: the configuration, the pushes and this run's
    provenance (ended now)."""
    manifest = {"package": "mjx_balance", "version": __version__, "kind": "simulate",
                "config": config_dict(config),
                "simulate": {"forces": [float(f) for f in forces],
                             "durations": [float(d) for d in durations]}}
    write_text(json.dumps(_with_run(manifest, ended=_now(), status="completed"), indent=2)
               + "\n", Path(folder) / MANIFEST)


class FolderBusy(ParameterError):
    """Another run holds the output folder's lock."""


_HELD: dict[str, list[int]] = {}  # resolved folder -> [lock file descriptor, nesting depth]


@contextmanager
def folder_lock(path: str | Path, *, wait: bool = False) -> Iterator[None]:
    """Hold the output folder (created if missing) for this run: an exclusive ``flock`` on
    ``DIR/.lock``, which records this process's PID and start time. Another process holding it
    makes this raise :class:`FolderBusy` at once, naming that run, or with ``wait`` print one
    line naming that run (stderr) and wait until it lets go; nested calls in one process share
    the lock. The lock goes with the process, however it ends (the file stays)."""
    folder = Path(path)
    folder.mkdir(parents=True, exist_ok=True)
    key = str(folder.resolve())
    if key in _HELD:
        _HELD[key][1] += 1
        try:
            yield
        finally:
            _HELD[key][1] -= 1
        return
    try:
        fd = os.open(folder / LOCK, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        if exc.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise
        # A folder this process cannot write in (a finished sweep shared read-only): it can
        # read it, and any write it tries fails on its own, so there is nothing to guard.
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 200).decode("utf-8", "replace").strip() or "PID not yet recorded"
        if not wait:
            os.close(fd)
            raise FolderBusy(f"{folder} is in use by another run ({holder}); wait for it to end "
                             "(--wait) or use another --out folder") from None
        log.warning("waiting for %s: in use by another run (%s)", folder, holder)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except BaseException:
            os.close(fd)
            raise
    except BaseException:
        os.close(fd)
        raise
    status = "interrupted"
    try:
        started = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"PID {os.getpid()}, started {started}\n".encode(), 0)
        _HELD[key] = [fd, 1]
        try:
            yield
            status = "completed"
        except Exception:
            status = "failed"
            raise
    finally:
        _HELD.pop(key, None)
        _finish_run(folder, status)
        os.close(fd)  # releases the flock


class OutputFolder:
    """The output folder DIR: manifest.json, config.toml, chunks/, region.parquet, table.csv.

    ``rebuilt`` is True after :meth:`open` took up a folder that had lost its manifest (the
    manifest it returns is then not yet written)."""

    def __init__(self, path: str | Path, config: Config):
        self.path = Path(path)
        self.config = config
        self.manifest_path = self.path / MANIFEST
        self.rebuilt = False

    def read_manifest(self) -> dict[str, Any] | None:
        if not self.manifest_path.exists():
            return None
        try:
            manifest = json.loads(self.manifest_path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ParameterError(f"{self.manifest_path}: unreadable manifest ({exc}); "
                                 "use another --out folder") from None
        problem = manifest_problem(manifest)
        if problem:
            raise ParameterError(f"{self.manifest_path}: not a manifest of this package "
                                 f"({problem}); use another --out folder")
        return manifest

    def open(self) -> dict[str, Any]:
        """Create the folder or check that it was made with this configuration (under the
        folder's lock, which the caller may already hold: see :func:`folder_lock`)."""
        with folder_lock(self.path):
            return self._open()

    def _open(self) -> dict[str, Any]:
        # Leftovers of a run that ended while writing: no other run holds the folder now.
        for stale in [*self.path.glob(".*.tmp"), *self.path.glob("chunks/.*.tmp"),
                      *self.path.glob(f"{TABLE_CELLS}/.*.tmp")]:
            stale.unlink(missing_ok=True)
        manifest = self.read_manifest()
        config = config_dict(self.config)
        if manifest is None:
            manifest = {"package": "mjx_balance", "version": __version__, "config": config}
            if (any(self.path.glob("*.parquet")) or (self.path / "chunks").exists()
                    or (self.path / TABLE_CELLS).exists()):
                self._check_lost_manifest(config)
                self.rebuilt = True
                table = self._lost_table_record()
                if table is not None:
                    manifest["table"] = table
                return manifest
            self.write_manifest(manifest)
            write_text(dumps_config(self.config), self.path / CONFIG)
            return manifest
        differences = config_differences(manifest.get("config", {}), config)
        if differences:
            raise ParameterError(
                f"{self.path} was made with a different configuration; use another --out folder "
                "or the same configuration (its config.toml). Differences: "
                + "; ".join(differences[:6]) + (" ..." if len(differences) > 6 else ""))
        if manifest.get("version") != __version__:
            log.warning("note: %s was made by mjx_balance %s, this is %s; continuing",
                        self.path, manifest.get("version"), __version__)
        try:  # this run's provenance record, even if it finds nothing to do
            self.write_manifest(manifest)
        except OSError:  # a finished folder shared read-only: read, not recorded
            pass
        return manifest

    def _check_lost_manifest(self, config: dict[str, Any]) -> None:
        """Results without a manifest: go on only if config.toml holds this run's configuration."""
        config_path = self.path / CONFIG
        if not config_path.exists():
            raise ParameterError(f"{self.path} holds results but no {MANIFEST} and no {CONFIG}; "
                                 "use another --out folder")
        try:
            recorded = config_dict(load_config(config_path))
        except ParameterError as exc:
            raise ParameterError(f"{self.path} holds results but no {MANIFEST}, and its {CONFIG} "
                                 f"is unusable ({exc}); use another --out folder") from None
        differences = config_differences(recorded, config)
        if differences:
            raise ParameterError(
                f"{self.path} holds results but no {MANIFEST}, and its {CONFIG} differs from this "
                "run's configuration; use another --out folder or that configuration. "
                "Differences: " + "; ".join(differences[:6])
                + (" ..." if len(differences) > 6 else ""))

    def _lost_table_record(self) -> dict[str, Any] | None:
        """The table's record for a rebuilt manifest: the forces of a table.csv that reads back
        whole, next to its table_runs.parquet (else None: the table is made again, from the
        scenarios kept in table_runs/)."""
        if not (self.path / TABLE_RUNS).exists():
            return None
        try:
            forces = pd.read_csv(self.path / TABLE)["force"].to_numpy(dtype=np.float64)
        except Exception:  # noqa: BLE001 - no usable table: no record
            return None
        if forces.size == 0 or not np.isfinite(forces).all():
            return None
        return {"forces": forces.tolist()}

    def write_manifest(self, manifest: dict[str, Any]) -> None:
        """Write the manifest, with this run's provenance record in its ``runs``."""
        write_text(json.dumps(_with_run(manifest), indent=2) + "\n", self.manifest_path)


# What a manifest must hold: its sections and, in each, the keys a run reads.
MANIFEST_KEYS = {"region": ("forces", "durations", "chunk_size"), "table": ("forces",)}


def manifest_problem(manifest: Any) -> str:
    """What is wrong with a manifest read from JSON ("" if nothing): it is an object, its
    configuration an object, and its region and table records objects with their keys (grids
    as lists of numbers, a whole chunk size >= 1)."""
    if not isinstance(manifest, dict):
        return f"a JSON {type(manifest).__name__}, not an object"
    if not isinstance(manifest.get("config", {}), dict):
        return "'config' is not an object"
    for section, keys in MANIFEST_KEYS.items():
        record = manifest.get(section)
        if record is None:
            continue
        if not isinstance(record, dict):
            return f"'{section}' is not an object"
        missing = [key for key in keys if key not in record]
        if missing:
            return f"'{section}' lacks {', '.join(repr(k) for k in missing)}"
        for key in ("forces", "durations")[:len(keys)]:
            values = record[key]
            if not (isinstance(values, list) and values and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)):
                return f"'{section}.{key}' is not a list of numbers"
        size = record.get("chunk_size", 1)
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            return f"'{section}.chunk_size' is not a whole number >= 1"
    engines = {"region.engine": (manifest.get("region") or {}).get("engine"),
               "table_engine": manifest.get("table_engine")}
    for name, engine in engines.items():
        if engine is None:
            continue
        slots = engine.get("slots") if isinstance(engine, dict) else None
        if (isinstance(slots, bool) or not isinstance(slots, int) or slots < 1
                or not isinstance(engine.get("early_stop"), bool)):
            return f"'{name}' is not {{\"slots\": whole number >= 1, \"early_stop\": true/false}}"
        if engine.get("physics", "mjx") not in ("mjx", "c"):
            return f"'{name}.physics' is not \"mjx\" or \"c\""
    return ""


class TableCells:
    """The table's evaluated scenarios, kept in ``DIR/table_runs/``: each batch call's summary
    rows in one parquet file ``part-NNNNN.parquet``, written atomically as the call returns.
    A cell is a (force, duration) pair; a file that does not read back whole, or holds rows of
    another convention, is ignored (its cells are run again)."""

    def __init__(self, folder: str | Path, convention: str):
        self.path = Path(folder) / TABLE_CELLS
        self.convention = convention
        self.rows: dict[tuple[float, float], dict[str, Any]] = {}
        self.parts = 0
        self.dtypes: pd.Series | None = None
        for part in sorted(self.path.glob("part-*.parquet")):
            self.parts = max(self.parts, int(part.stem.split("-")[1]) + 1)
            try:
                frame = pd.read_parquet(part)
            except Exception:  # noqa: BLE001 - a damaged part is run again
                continue
            if ([c for c in SUMMARY_COLUMNS if c not in frame]
                    or not set(frame["outcome"]) <= set(OUTCOMES)
                    or not (frame["convention"] == convention).all()):
                continue
            self._remember(frame)

    @staticmethod
    def key(force: float, duration: float) -> tuple[float, float]:
        return (round(float(force), 9), round(float(duration), 9))

    def _remember(self, frame: pd.DataFrame) -> None:
        if self.dtypes is None:
            self.dtypes = frame.dtypes
        for row in frame.to_dict("records"):
            self.rows[self.key(row["force"], row["duration"])] = row

    def missing(self, forces: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """Indices of the cells not kept yet."""
        return np.array([i for i, (f, d) in enumerate(zip(forces, durations))
                         if self.key(f, d) not in self.rows], dtype=np.int64)

    def add(self, frame: pd.DataFrame) -> None:
        """Keep a batch call's rows: written to their part file, then remembered."""
        if frame.empty:
            return
        self.path.mkdir(parents=True, exist_ok=True)
        write_parquet(frame, self.path / f"part-{self.parts:05d}.parquet")
        self.parts += 1
        self._remember(frame)

    def frame(self, forces: np.ndarray, durations: np.ndarray) -> pd.DataFrame:
        """The kept rows of these cells, in order (every cell must be kept), with the values
        of force and duration asked for."""
        rows = [{**self.rows[self.key(f, d)], "force": float(f), "duration": float(d)}
                for f, d in zip(forces, durations)]
        frame = pd.DataFrame(rows, columns=list(self.dtypes.index))
        return frame.astype(self.dtypes.to_dict())


def same_values(a: Sequence[float], b: Sequence[float]) -> bool:
    """Equal length and equal values up to GRID_TOL."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=0, atol=GRID_TOL))


def chunk_path(folder: Path, index: int) -> Path:
    return folder / "chunks" / f"chunk-{index:05d}.parquet"


def read_chunk(path: Path, forces: np.ndarray, durations: np.ndarray,
               convention: str) -> tuple[pd.DataFrame | None, str]:
    """A chunk file if it holds exactly the given cells in order, else (None, reason)."""
    if not path.exists():
        return None, "missing"
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:  # noqa: BLE001 - any read failure means: recompute
        return None, f"unreadable ({type(exc).__name__})"
    if len(frame) != forces.size:
        return None, f"{len(frame)} rows, expected {forces.size}"
    missing = [c for c in SUMMARY_COLUMNS if c not in frame]
    if missing:
        return None, f"missing column(s) {', '.join(missing[:3])}"
    if not (same_values(frame["force"], forces) and same_values(frame["duration"], durations)):
        return None, "cells differ from the grid"
    if not set(frame["outcome"]) <= set(OUTCOMES):
        return None, "unknown outcomes"
    if not (frame["convention"] == convention).all():
        return None, "other convention"
    return frame, "ok"


def merge_chunks(folder: Path, slices: list[slice], cell_f: np.ndarray, cell_d: np.ndarray,
                  convention: str, out: Path) -> None:
    """Stream the chunk files into one parquet file, one chunk in memory at a time.

    Each chunk is checked again against its slice of the grid (read_chunk), so the merged file
    holds every cell exactly once and in grid order without ever being held whole.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    # Row groups of ~64k rows: one per chunk would make the file's metadata, which the writer
    # holds until it closes, grow with every chunk (BENCHMARKS.md, memory scaling).
    rows_per_group = 65536
    writer, schema, pending, pending_rows = None, None, [], 0

    def flush() -> None:
        nonlocal pending, pending_rows
        if pending:
            writer.write_table(pa.concat_tables(pending), row_group_size=rows_per_group)
            pending, pending_rows = [], 0

    try:
        for index, cells in enumerate(slices):
            frame, reason = read_chunk(chunk_path(folder, index), cell_f[cells], cell_d[cells],
                                       convention)
            if frame is None:
                raise RuntimeError(f"chunk {index} changed while merging: {reason}")
            table = pa.Table.from_pandas(frame, preserve_index=False)
            if writer is None:
                schema = table.schema
                writer = pq.ParquetWriter(out, schema)
            pending.append(table.cast(schema))
            pending_rows += table.num_rows
            if pending_rows >= rows_per_group:
                flush()
        flush()
    finally:
        if writer is not None:
            writer.close()
