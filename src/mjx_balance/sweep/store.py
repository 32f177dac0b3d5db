"""The output folder of a sweep: manifest, configuration, chunk files, merged results.

``DIR/manifest.json`` records the package version, the configuration and what was computed
(the region's grid and chunk size, the table's forces); ``DIR/config.toml`` holds the
configuration as TOML. A folder made with another configuration is refused. Every file is
written atomically (a temporary file in the same folder, then ``os.replace``), so a file is
either complete or absent. Region chunks live in ``DIR/chunks/chunk-NNNNN.parquet``; a chunk
file is used only if it reads back with exactly its cells (:func:`read_chunk`), and the merge
streams the chunks into ``DIR/region.parquet`` one at a time (:func:`merge_chunks`).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pandas as pd

from .. import __version__
from ..outcomes import OUTCOMES, SUMMARY_COLUMNS
from ..params import Config, ParameterError, save_config
from .grid import same_values

MANIFEST = "manifest.json"
REGION = "region.parquet"
TABLE = "table.csv"
TABLE_RUNS = "table_runs.parquet"


def write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    """Write a file atomically: ``write(tmp)`` to a temporary file beside it, then rename."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write(Path(tmp))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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


class OutputFolder:
    """The output folder DIR: manifest.json, config.toml, chunks/, region.parquet, table.csv."""

    def __init__(self, path: str | Path, config: Config):
        self.path = Path(path)
        self.config = config
        self.manifest_path = self.path / MANIFEST

    def read_manifest(self) -> dict[str, Any] | None:
        if not self.manifest_path.exists():
            return None
        try:
            return json.loads(self.manifest_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ParameterError(f"{self.manifest_path}: unreadable manifest ({exc}); "
                                 "use another --out folder") from None

    def open(self) -> dict[str, Any]:
        """Create the folder or check that it was made with this configuration."""
        self.path.mkdir(parents=True, exist_ok=True)
        for stale in self.path.glob(".*.tmp"):
            stale.unlink(missing_ok=True)
        manifest = self.read_manifest()
        config = config_dict(self.config)
        if manifest is None:
            if any(self.path.glob("*.parquet")) or (self.path / "chunks").exists():
                raise ParameterError(f"{self.path} holds results but no {MANIFEST}; "
                                     "use another --out folder")
            manifest = {"package": "mjx_balance", "version": __version__, "config": config}
            self.write_manifest(manifest)
            save_config(self.config, self.path / "config.toml")
            return manifest
        differences = config_differences(manifest.get("config", {}), config)
        if differences:
            raise ParameterError(
                f"{self.path} was made with a different configuration; use another --out folder "
                "or the same configuration (its config.toml). Differences: "
                + "; ".join(differences[:6]) + (" ..." if len(differences) > 6 else ""))
        if manifest.get("version") != __version__:
            print(f"note: {self.path} was made by mjx_balance {manifest.get('version')}, "
                  f"this is {__version__}; continuing", file=sys.stderr)
        return manifest

    def write_manifest(self, manifest: dict[str, Any]) -> None:
        write_text(json.dumps(manifest, indent=2) + "\n", self.manifest_path)


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
