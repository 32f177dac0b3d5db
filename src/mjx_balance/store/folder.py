"""The output folder of a sweep: manifest, configuration, chunk files, merged results.

``DIR/manifest.json`` records the package version, the configuration and what was computed (the
region's grid and chunk size, the table's forces), and, in ``runs``, one provenance record per
run that worked in the folder (``provenance.py``: versions, physics path, device, git commit,
command line, start and end times, how it ended); ``DIR/config.toml`` holds the configuration as
TOML. Only the configuration and the grids decide whether a run may resume a folder; the
provenance records differ between runs by design and are never compared. A folder made with
another configuration is refused; a folder that lost its manifest is taken up again when its
config.toml matches the run's (the region sweep then checks its chunk files against the grid
before it rewrites the manifest). Every file is written atomically (``files.py``: a temporary
file in the same folder, then ``os.replace``), so a file is either complete or absent, with the
mode the umask gives. Region chunks live in ``DIR/chunks/chunk-NNNNN.parquet``; a chunk file is
used only if it reads back with exactly its cells (:func:`read_chunk`), and the merge streams
the chunks into ``DIR/region.parquet`` one at a time (:func:`merge_chunks`).

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
import shutil
import threading
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np
import pandas as pd

from ..runtime.fingerprint import differences, numerics
from ..runtime.version import __version__
from ..measures.outcomes import DIVERGED_LIMIT, OUTCOMES, SUMMARY_COLUMNS, diverged_share
from ..measures.strategy import with_strategy
from ..model.params import Config, ParameterError, config_warnings
from ..model.config_files import dumps_config, load_config
from .files import (
    CONFIG,
    LOCK,
    MANIFEST,
    TABLE,
    TABLE_CELLS,
    TABLE_RUNS,
    UNITS_SUFFIX,
    named,
    with_units,
    write_parquet,
    write_text,
)
from .provenance import finish_run, with_run

GRID_TOL = 1e-9  # how far a value may sit beyond a limit (float error) and still count

log = logging.getLogger(__name__)


def config_dict(config: Config) -> dict[str, Any]:
    return json.loads(json.dumps(config.to_dict()))


def with_config_warnings(manifest: dict[str, Any], config: Config) -> dict[str, Any]:
    """``manifest`` with the configuration's never-binding limits (``config_warnings``: one
    sentence each) under ``config_warnings``, or without that key when there are none."""
    found = config_warnings(config)
    if found:
        manifest["config_warnings"] = found
    else:
        manifest.pop("config_warnings", None)
    return manifest


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


PUSHES = "pushes"  # a simulate folder's finished pushes, while its run is under way


def record_simulation(
    folder: str | Path, config: Config, forces: Any, durations: Any, pairs: Any = None
) -> set[int]:
    """Start (or resume) a ``simulate`` run in ``folder``, under its lock: this run's
    provenance in the manifest's ``runs`` (running; :func:`folder_lock` records how it ends),
    and its request (the configuration and the pushes: the grid's forces and durations, or the
    given ``pairs``) in ``DIR/pushes/request.json``. The manifest's own ``config`` and
    ``simulate`` describe the tables in the folder: set now for a folder without tables, else
    when this run's tables replace them (:func:`finish_simulation`). Returns the indices of the
    pushes an earlier run of the same request finished (:func:`write_push`); another
    request's pushes are discarded."""
    folder = Path(folder)
    request = _simulation_request(config, forces, durations, pairs)
    kept = folder / PUSHES
    for stale in kept.glob(".*.tmp"):  # a write cut short: no other run holds the folder
        stale.unlink(missing_ok=True)
    if _json_or_none(kept / "request.json") == request:
        done = {
            int(p.name.split(".")[0])
            for p in kept.glob("*.summary.json")
            if (kept / p.name.replace(".summary.json", ".series.parquet")).exists()
        }
    else:
        shutil.rmtree(kept, ignore_errors=True)
        kept.mkdir(parents=True)
        write_text(json.dumps(request) + "\n", kept / "request.json")
        done = set()
    old = _json_or_none(folder / MANIFEST)
    manifest = (
        old
        if isinstance(old, dict) and old.get("kind") == "simulate"
        else {"package": "mjx_balance", "version": __version__, "kind": "simulate"}
    )
    if "simulate" not in manifest:  # no tables yet: the manifest describes this request
        manifest.update(request)
        with_config_warnings(manifest, config)
    write_text(json.dumps(with_run(manifest), indent=2) + "\n", folder / MANIFEST)
    return done


def finish_simulation(
    folder: str | Path, config: Config, forces: Any, durations: Any, pairs: Any = None
) -> None:
    """After a ``simulate`` run wrote its tables: the manifest describes them (this run's
    configuration and pushes), and the kept pushes, now in the tables, are removed."""
    folder = Path(folder)
    manifest = _json_or_none(folder / MANIFEST)
    manifest.pop("config_warnings", None)
    manifest.update(_simulation_request(config, forces, durations, pairs))
    with_config_warnings(manifest, config)
    write_text(json.dumps(with_run(manifest), indent=2) + "\n", folder / MANIFEST)
    shutil.rmtree(folder / PUSHES, ignore_errors=True)


def _simulation_request(config: Config, forces: Any, durations: Any, pairs: Any) -> dict[str, Any]:
    pushes = (
        {"pairs": [[float(f), float(d)] for f, d in pairs]}
        if pairs is not None
        else {"forces": [float(f) for f in forces], "durations": [float(d) for d in durations]}
    )
    return {"config": config_dict(config), "simulate": pushes}


def write_push(
    folder: str | Path, index: int, summary: dict[str, Any], series: pd.DataFrame
) -> None:
    """Keep one finished push of a ``simulate`` run: its time series, then its summary row (a
    push counts as finished when its summary is there)."""
    kept = Path(folder) / PUSHES
    kept.mkdir(exist_ok=True)
    write_parquet(series, kept / f"{index:06d}.series.parquet")
    row = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in summary.items()}
    write_text(json.dumps(row) + "\n", kept / f"{index:06d}.summary.json")


def read_pushes(folder: str | Path, count: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The ``count`` pushes of a ``simulate`` run, every one read back from ``DIR/pushes/``
    (a resumed run and one that ran through give the same tables): (summary, series)."""
    kept = Path(folder) / PUSHES
    rows = [json.loads((kept / f"{i:06d}.summary.json").read_text()) for i in range(count)]
    series = [pd.read_parquet(kept / f"{i:06d}.series.parquet") for i in range(count)]
    return (pd.DataFrame(rows, columns=SUMMARY_COLUMNS), pd.concat(series, ignore_index=True))


def _json_or_none(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return None


class FolderBusy(ParameterError):
    """Another run holds the output folder's lock."""


# The folders this process holds: resolved folder -> the holding thread's id. A run takes each
# folder's lock once, where it enters (the command line, an API function, a study for each
# folder it writes); the floors below check that it is held (:func:`require_lock`) instead of
# taking it again. Another thread is refused (or waits) as another process is: it takes a flock
# of its own, and flock locks belong to an open file description, so a second open file
# conflicts even in the same process.
_HELD: dict[str, int] = {}
_HELD_LOCK = threading.Lock()


def _key(path: str | os.PathLike[str]) -> str:
    return str(Path(path).resolve())


def require_lock(path: str | os.PathLike[str]) -> None:
    """Raise RuntimeError unless this thread holds ``path``'s lock (:func:`folder_lock`): a
    function that writes a run's files into a folder checks that the run's entry took it."""
    with _HELD_LOCK:
        holder = _HELD.get(_key(path))
    if holder != threading.get_ident():
        raise RuntimeError(
            f"{path}: the folder's lock is not held by this run; take it once "
            "where the run enters (store.folder.folder_lock)"
        )


@contextmanager
def folder_lock(path: str | os.PathLike[str], *, wait: bool = False) -> Iterator[None]:
    """Hold the output folder (created if missing) for this run: an exclusive ``flock`` on
    ``DIR/.lock``, which records this process's PID and start time. Another process holding it
    makes this raise :class:`FolderBusy` at once, naming that run, or with ``wait`` print one
    line naming that run (stderr) and wait until it lets go; another thread is refused (or
    waits) as another process is. A run takes it once: a second take in the thread that holds
    it raises RuntimeError (the floors below check it with :func:`require_lock`). The lock
    goes with the process, however it ends (the file stays)."""
    folder = Path(path)
    folder.mkdir(parents=True, exist_ok=True)
    key = _key(folder)
    me = threading.get_ident()
    with _HELD_LOCK:
        if _HELD.get(key) == me:
            raise RuntimeError(
                f"{folder}: the folder's lock taken twice in one run; the run's "
                "entry takes it once and the floors below check it"
            )
    try:
        fd = os.open(folder / LOCK, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as exc:
        if exc.errno not in (errno.EACCES, errno.EPERM, errno.EROFS):
            raise
        # A folder this process cannot write in (a finished sweep shared read-only): it can
        # read it, and any write it tries fails on its own, so there is nothing to guard.
        with _held(key, me):
            yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 200).decode("utf-8", "replace").strip() or "PID not yet recorded"
        if not wait:
            os.close(fd)
            raise FolderBusy(
                f"{folder} is in use by another run ({holder}); wait for it to end "
                "(--wait) or use another --out folder"
            ) from None
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
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"PID {os.getpid()}, started {started}\n".encode(), 0)
        except OSError as exc:  # a descriptor's error names no file: name the lock
            raise named(exc, folder / LOCK) from exc
        with _held(key, me):
            try:
                yield
                status = "completed"
            except Exception:
                status = "failed"
                raise
    finally:
        try:
            finish_run(folder, status)  # raises a failed write only after a completed run
        finally:
            os.close(fd)  # releases the flock


@contextmanager
def _held(key: str, thread: int) -> Iterator[None]:
    """Record ``key``'s lock as held by ``thread`` while the block runs."""
    with _HELD_LOCK:
        _HELD[key] = thread
    try:
        yield
    finally:
        with _HELD_LOCK:
            _HELD.pop(key, None)


class OutputFolder:
    """The output folder DIR: manifest.json, config.toml, chunks/, region.parquet, table.csv.

    ``rebuilt`` is True after :meth:`open` took up a folder that had lost its manifest (the
    manifest it returns is then not yet written)."""

    def __init__(self, path: str | os.PathLike[str], config: Config):
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
            raise ParameterError(
                f"{self.manifest_path}: unreadable manifest ({exc}); use another --out folder"
            ) from None
        problem = manifest_problem(manifest)
        if problem:
            raise ParameterError(
                f"{self.manifest_path}: not a manifest of this package "
                f"({problem}); use another --out folder"
            )
        if manifest.get("kind") is not None:  # simulate's or a cohort's: not a sweep's
            raise ParameterError(
                f"{self.path} holds another kind of output (a "
                f"{manifest['kind']} run's); use another --out folder"
            )
        return manifest

    def open(self) -> dict[str, Any]:
        """Create the folder or check that it was made with this configuration (the run's
        entry holds the folder's lock: :func:`folder_lock`)."""
        require_lock(self.path)
        return self._open()

    def _open(self) -> dict[str, Any]:
        # Leftovers of a run that ended while writing: no other run holds the folder now.
        for stale in [
            *self.path.glob(".*.tmp"),
            *self.path.glob("chunks/.*.tmp"),
            *self.path.glob(f"{TABLE_CELLS}/.*.tmp"),
        ]:
            stale.unlink(missing_ok=True)
        manifest = self.read_manifest()
        config = config_dict(self.config)
        if manifest is None:
            manifest = {
                "package": "mjx_balance",
                "version": __version__,
                "config": config,
                "numerics": numerics(),
            }
            with_config_warnings(manifest, self.config)
            if (
                any(self.path.glob("*.parquet"))
                or (self.path / "chunks").exists()
                or (self.path / TABLE_CELLS).exists()
            ):
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
        if differences and not self.holds_results():
            # A run that failed before its first result (a bad value found late, a signal), or
            # whose numbers were not results (half or more diverged): nothing here is worth
            # keeping, so this run takes the folder over, without the failed run's numbers
            # (which it would otherwise resume from).
            log.warning(
                "note: %s holds no results of the configuration it was made with; "
                "starting it anew with this run's configuration",
                self.path,
            )
            for path in self.computed_files():  # none, or all of them not results
                path.unlink(missing_ok=True)
            manifest = {
                "package": "mjx_balance",
                "version": __version__,
                "config": config,
                "runs": manifest.get("runs", []),
            }
            with_config_warnings(manifest, self.config)
            self.write_manifest(manifest)
            write_text(dumps_config(self.config), self.path / CONFIG)
            return manifest
        if differences:
            raise ParameterError(
                f"{self.path} was made with a different configuration; use another --out folder "
                "or the same configuration (its config.toml). Differences: "
                + "; ".join(differences[:6])
                + (" ..." if len(differences) > 6 else "")
            )
        if manifest.get("version") != __version__:
            log.warning(
                "note: %s was made by mjx_balance %s, this is %s; continuing",
                self.path,
                manifest.get("version"),
                __version__,
            )
        if not isinstance(manifest.get("numerics"), dict):  # a folder from before them
            manifest["numerics"] = numerics()
        try:  # this run's provenance record, even if it finds nothing to do
            self.write_manifest(manifest)
        except OSError:  # a finished folder shared read-only: read, not recorded
            pass
        return manifest

    def check_numerics(self, manifest: dict[str, Any]) -> None:
        """Before computing new rows into this folder: refuse if its results were computed
        under other numerics that change results (x64, XLA flags, matmul precision:
        runtime/fingerprint.py), which would merge rows computed differently; warn for another
        JAX, MuJoCo or CPU ISA. (A finished folder is read under any numerics.)"""
        recorded = manifest.get("numerics")
        if not isinstance(recorded, dict):
            return
        refuse, warn = differences(recorded, numerics())
        warn = [w for w in warn if not w.startswith("package:")]  # said when opened
        if refuse and self.computed_files():  # even numbers that are not results: not mixed
            raise ParameterError(
                f"{self.path} was computed under other numerics ({'; '.join(refuse)}); "
                "resuming would mix rows computed differently. Run with the settings it "
                "was made with (JAX_ENABLE_X64, XLA_FLAGS, JAX_DEFAULT_MATMUL_PRECISION), or "
                "start a fresh folder (another --out, or delete this one)"
            )
        if warn:
            log.warning(
                "note: %s was computed under %s; continuing (each chunk keeps the "
                "numerics it was computed under)",
                self.path,
                "; ".join(warn),
            )

    def computed_files(self) -> list[Path]:
        """What the folder holds computed: a merged table or region, chunk files, kept table
        scenarios (a manifest and config.toml alone are not results)."""
        patterns = ("*.parquet", "*.csv", "chunks/*.parquet", f"{TABLE_CELLS}/*.parquet")
        return [path for pattern in patterns for path in sorted(self.path.glob(pattern))]

    def holds_results(self) -> bool:
        """Whether the folder holds results worth keeping: anything computed
        (:meth:`computed_files`) unless it is all :meth:`not_results`."""
        files = self.computed_files()
        return bool(files) and not self.not_results(files)

    def not_results(self, files: Sequence[Path]) -> bool:
        """Whether every computed file (``files``) carries outcomes and, all together, they are not
        results by the rule that failed the run (``measures.outcomes.check_results``: half or
        more diverged): what a run of extreme settings leaves (every cell diverged). A
        corrected configuration loses nothing by taking such a folder over. The table
        (table.csv, made from its scenarios' files) and the units' sidecars are not judged; any
        other file that cannot be read, or has no outcome column, is a result."""
        outcomes: list[Any] = []
        for path in files:
            if path.name == TABLE or path.name.endswith(UNITS_SUFFIX):
                continue  # made from the scenarios' files (judged) or a sidecar of units
            try:
                if path.suffix == ".csv":
                    frame = pd.read_csv(path, usecols=["outcome"])
                else:
                    frame = pd.read_parquet(path, columns=["outcome"])
            except Exception:  # unreadable, or no outcome column: a result, kept
                return False
            outcomes.extend(frame["outcome"].tolist())
        return bool(outcomes) and diverged_share(outcomes) >= DIVERGED_LIMIT

    def _check_lost_manifest(self, config: dict[str, Any]) -> None:
        """Results without a manifest: go on only if config.toml holds this run's configuration."""
        config_path = self.path / CONFIG
        if not config_path.exists():
            raise ParameterError(
                f"{self.path} holds results but no {MANIFEST} and no {CONFIG}; "
                "use another --out folder"
            )
        try:
            recorded = config_dict(load_config(config_path))
        except ParameterError as exc:
            raise ParameterError(
                f"{self.path} holds results but no {MANIFEST}, and its {CONFIG} "
                f"is unusable ({exc}); use another --out folder"
            ) from None
        differences = config_differences(recorded, config)
        if differences:
            raise ParameterError(
                f"{self.path} holds results but no {MANIFEST}, and its {CONFIG} differs from this "
                "run's configuration; use another --out folder or that configuration. "
                "Differences: "
                + "; ".join(differences[:6])
                + (" ..." if len(differences) > 6 else "")
            )

    def _lost_table_record(self) -> dict[str, Any] | None:
        """The table's record for a rebuilt manifest: the forces of a table.csv that reads back
        whole, next to its table_runs.parquet (else None: the table is made again, from the
        scenarios kept in table_runs/)."""
        if not (self.path / TABLE_RUNS).exists():
            return None
        try:
            forces = pd.read_csv(self.path / TABLE)["force"].to_numpy(dtype=np.float64)
        except Exception:
            return None
        if forces.size == 0 or not np.isfinite(forces).all():
            return None
        return {"forces": forces.tolist()}

    def write_manifest(self, manifest: dict[str, Any]) -> None:
        """Write the manifest, with this run's provenance record in its ``runs``."""
        write_text(json.dumps(with_run(manifest), indent=2) + "\n", self.manifest_path)


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
        for key in ("forces", "durations")[: len(keys)]:
            values = record[key]
            if not (
                isinstance(values, list)
                and values
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
            ):
                return f"'{section}.{key}' is not a list of numbers"
        size = record.get("chunk_size", 1)
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            return f"'{section}.chunk_size' is not a whole number >= 1"
    engines = {
        "region.engine": (manifest.get("region") or {}).get("engine"),
        "table_engine": manifest.get("table_engine"),
    }
    for name, engine in engines.items():
        if engine is None:
            continue
        slots = engine.get("slots") if isinstance(engine, dict) else None
        if (
            isinstance(slots, bool)
            or not isinstance(slots, int)
            or slots < 1
            or not isinstance(engine.get("early_stop"), bool)
        ):
            return f'\'{name}\' is not {{"slots": whole number >= 1, "early_stop": true/false}}'
        if engine.get("physics", "mjx") not in ("mjx", "c"):
            return f'\'{name}.physics\' is not "mjx" or "c"'
    return ""


class TableCells:
    """The table's evaluated scenarios, kept in ``DIR/table_runs/``: each batch call's summary
    rows in one parquet file ``part-NNNNN.parquet``, written atomically as the call returns.
    A cell is a (force, duration) pair; a file that does not read back whole, or holds rows of
    another convention, is ignored (its cells are run again). ``folder`` None: the rows are
    kept in memory only (a table made without a folder, whose later rounds read back what the
    earlier ones ran)."""

    def __init__(self, folder: str | Path | None, convention: str):
        self.path = None if folder is None else Path(folder) / TABLE_CELLS
        self.convention = convention
        self.rows: dict[tuple[float, float], dict[str, Any]] = {}
        self.parts = 0
        self.dtypes: pd.Series | None = None
        for part in sorted(self.path.glob("part-*.parquet")) if self.path else []:
            self.parts = max(self.parts, int(part.stem.split("-")[1]) + 1)
            try:
                frame = pd.read_parquet(part)
            except Exception:
                continue
            if (
                [c for c in SUMMARY_COLUMNS if c not in frame]
                or not set(frame["outcome"]) <= set(OUTCOMES)
                or not (frame["convention"] == convention).all()
            ):
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
        return np.array(
            [
                i
                for i, (f, d) in enumerate(zip(forces, durations))
                if self.key(f, d) not in self.rows
            ],
            dtype=np.int64,
        )

    def add(self, frame: pd.DataFrame) -> None:
        """Keep a batch call's rows: written to their part file, then remembered."""
        if frame.empty:
            return
        if self.path is not None:
            self.path.mkdir(parents=True, exist_ok=True)
            write_parquet(frame, self.path / f"part-{self.parts:05d}.parquet")
            self.parts += 1
        self._remember(frame)

    def frame(self, forces: np.ndarray, durations: np.ndarray) -> pd.DataFrame:
        """The kept rows of these cells, in order (every cell must be kept), with the values
        of force and duration asked for."""
        assert self.dtypes is not None  # (set with the first kept rows)
        rows = [
            {**self.rows[self.key(f, d)], "force": float(f), "duration": float(d)}
            for f, d in zip(forces, durations)
        ]
        frame = pd.DataFrame(rows, columns=list(self.dtypes.index))
        return frame.astype(self.dtypes.to_dict())


def same_values(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray) -> bool:
    """Equal length and equal values up to GRID_TOL."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=0, atol=GRID_TOL))


def chunk_path(folder: Path, index: int) -> Path:
    return folder / "chunks" / f"chunk-{index:05d}.parquet"


def write_chunk(frame: pd.DataFrame, folder: Path, index: int) -> None:
    """Chunk ``index`` of a region, with the numerics it was computed under
    (``runtime.fingerprint.numerics``) in the parquet file's metadata (``frame.attrs``, which
    pandas keeps there; read back by :func:`chunk_numerics`). The merged region.parquet does
    not carry them: its bytes depend on the rows alone."""
    frame = frame.copy(deep=False)
    frame.attrs = {"numerics": numerics()}
    write_parquet(frame, chunk_path(folder, index))


def chunk_numerics(path: Path) -> dict | None:
    """The numerics a chunk file was computed under (None for a chunk written before them)."""
    found = pd.read_parquet(path).attrs.get("numerics")
    return found if isinstance(found, dict) else None


def read_chunk(
    path: Path, forces: np.ndarray, durations: np.ndarray, convention: str
) -> tuple[pd.DataFrame | None, str]:
    """A chunk file if it holds exactly the given cells in order, else (None, reason)."""
    if not path.exists():
        return None, "missing"
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:
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


def merge_chunks(
    folder: Path,
    slices: list[slice],
    cell_f: np.ndarray,
    cell_d: np.ndarray,
    convention: str,
    out: Path,
) -> None:
    """Stream the chunk files into one parquet file, one chunk in memory at a time.

    Each chunk is checked again against its slice of the grid (read_chunk), so the merged file
    holds every cell exactly once and in grid order without ever being held whole.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    # Row groups of ~64k rows: one per chunk would make the file's metadata, which the writer
    # holds until it closes, grow with every chunk (BENCHMARKS.md, memory scaling).
    rows_per_group = 65536
    writer: pq.ParquetWriter | None
    pending: list[pa.Table]
    writer, schema, pending, pending_rows = None, None, [], 0

    def flush() -> None:
        nonlocal pending, pending_rows
        if pending:
            assert writer is not None  # (opened with the first chunk, before any is pending)
            writer.write_table(pa.concat_tables(pending), row_group_size=rows_per_group)
            pending, pending_rows = [], 0

    try:
        for index, cells in enumerate(slices):
            frame, reason = read_chunk(
                chunk_path(folder, index), cell_f[cells], cell_d[cells], convention
            )
            if frame is None:
                raise RuntimeError(f"chunk {index} changed while merging: {reason}")
            frame.attrs = {}  # the chunk's own metadata stays with the chunk
            frame = with_strategy(frame)  # derived columns: hip_share, strategy
            table = pa.Table.from_pandas(frame, preserve_index=False)
            if writer is None:  # the first chunk's columns, with their units (files.with_units)
                schema = with_units(table.schema)
                writer = pq.ParquetWriter(out, schema)
            pending.append(table.cast(schema))
            pending_rows += table.num_rows
            if pending_rows >= rows_per_group:
                flush()
        flush()
    finally:
        if writer is not None:
            writer.close()
