"""Files of an output folder: their names, and atomic writes (a file is complete or absent).

Every file is written to a temporary file in the same folder, then renamed with ``os.replace``,
with the mode the umask gives (:func:`write_atomic`; figures through :func:`write_figure`).
"""

from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path
from typing import Any, Callable

import pandas as pd

MANIFEST = "manifest.json"
REGION = "region.parquet"
TABLE = "table.csv"
TABLE_RUNS = "table_runs.parquet"
TABLE_CELLS = "table_runs"  # folder: the table's evaluated scenarios, one file per batch call
CONFIG = "config.toml"
LOCK = ".lock"

_UMASK_LOCK = threading.Lock()


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
