"""Files of an output folder: their names, and atomic writes (a file is complete or absent).

Every file is written to a temporary file in the same folder, then renamed with ``os.replace``,
with the mode the umask gives (:func:`write_atomic`; figures through :func:`write_figure`).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
import threading
from pathlib import Path
from typing import Any, Callable

import pandas as pd

from ..measures.units import describe

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


def write_atomic(path: Path, write: Callable[[Path], object]) -> None:
    """Write a file atomically: ``write(tmp)`` to a temporary file beside it, then rename.

    The file gets the mode a plain ``open`` would give it (0o666 less the umask), not
    mkstemp's 0o600, so that collaborators sharing the folder can read it."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise named(exc, path) from exc
    os.close(fd)
    try:
        write(Path(tmp))
        os.chmod(tmp, 0o666 & ~current_umask())
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise named(exc, path) from exc
        raise


def copy_folder(source: Path, target: Path, last: str) -> None:
    """Copy the folder ``source`` into ``target`` (made, or merged into), each file atomically
    and the file ``last`` (the one whose presence marks the folder finished) after every other:
    a copy cut short (a full disk) raises the first error, naming the file, and leaves whole
    files and no ``last``, so it is never read back as a finished folder and the next run
    copies again. Times are kept (``shutil.copy2``); temporary files and the folder's lock (a
    record of who holds it; the copy's own run takes the copy's) are not copied.
    (``shutil.copytree`` writes each file in place and goes on past a failed one, raising a
    list of errors at the end.)"""
    source, target = Path(source), Path(target)
    files = [
        p
        for p in sorted(source.rglob("*"))
        if p.is_file()
        and p.name != LOCK
        and not (p.name.startswith(".") and p.name.endswith(".tmp"))
    ]
    files.sort(key=lambda p: p == source / last)  # stable: the mark last
    for src in files:
        dst = target / src.relative_to(source)
        dst.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(dst, lambda tmp, src=src: shutil.copy2(src, tmp))  # type: ignore[misc]  # mypy cannot infer a lambda with a default argument


_ERRNO_IN_TEXT = re.compile(r"\[errno (\d+)\]", re.IGNORECASE)


def named(exc: OSError, path: Path) -> OSError:
    """``exc`` as an OSError naming the file being written (``path``, not its temporary file)
    with its errno and the system's words for it: Arrow's write errors carry neither (their
    text holds ``[errno 28]``), Python's name the temporary file."""
    code = exc.errno
    if code is None:
        found = _ERRNO_IN_TEXT.search(str(exc))
        code = int(found.group(1)) if found else None
    if code is None:
        return exc
    return OSError(code, os.strerror(code), str(path))  # the errno's subclass (PermissionError...)


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
    except Exception:
        return False
    return True


def readable_figure(path: str | Path) -> bool:
    """Whether ``path`` is a whole figure file of the format its suffix names: a PNG as
    :func:`readable_png` checks it; a PDF that starts with ``%PDF-`` and ends in ``%%EOF``
    (matplotlib writes it last); an SVG that parses as XML with an ``svg`` root. A file cut
    short while being written fails (figures are written atomically, so only a copy or an
    older writer leaves one)."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".pdf", ".svg"):
        return readable_png(path)
    try:
        data = Path(path).read_bytes()
    except OSError:
        return False
    if suffix == ".pdf":
        return data.startswith(b"%PDF-") and data.rstrip().endswith(b"%%EOF")
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(data)
    except ET.ParseError:
        return False
    return root.tag.rsplit("}", 1)[-1] == "svg"


UNITS_KEY = b"mjx_balance.units"  # the parquet schema's metadata: {column: unit} as JSON
UNITS_SUFFIX = ".units.csv"  # a CSV's sidecar: NAME.csv -> NAME.units.csv
FORMATS = ("csv", "parquet", "both")


def with_units(schema: Any) -> Any:
    """A pyarrow schema with each known column's unit (``measures.units``) as its field
    metadata ``{"unit": ...}`` and all of them as JSON under the schema's ``UNITS_KEY``.
    Metadata only: the columns' names, types and values stay as they are, so a file written
    without units (an older chunk) casts to it and compares equal in every check."""
    import pyarrow as pa

    known = {name: describe(name) for name in schema.names}
    fields = [
        field.with_metadata({**(field.metadata or {}), b"unit": known[field.name][0]})  # type: ignore[index]  # not None (the if below); mypy narrows no dict lookup
        if known[field.name] is not None
        else field
        for field in schema
    ]
    units = {name: found[0] for name, found in known.items() if found is not None}
    return pa.schema(fields, metadata={**(schema.metadata or {}), UNITS_KEY: json.dumps(units)})


def write_parquet(frame: pd.DataFrame, path: Path) -> None:
    """Write a table as parquet atomically, with its columns' units in the schema's metadata
    (:func:`with_units`) and ``frame.attrs`` where pandas keeps them (read back by
    ``pd.read_parquet``)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pandas(frame, preserve_index=False)
    if frame.attrs:
        table = table.replace_schema_metadata(
            {**table.schema.metadata, b"PANDAS_ATTRS": json.dumps(frame.attrs)}
        )
    table = table.cast(with_units(table.schema))
    write_atomic(path, lambda tmp: pq.write_table(table, tmp))


def units_frame(columns: Any) -> pd.DataFrame:
    """The sidecar of a CSV table: one row per column, ``column,unit,description`` (unit and
    description empty for a column ``measures.units`` does not know)."""
    rows = [(str(c), *(describe(str(c)) or ("", ""))) for c in columns]
    return pd.DataFrame(rows, columns=["column", "unit", "description"])


def units_path(path: str | Path) -> Path:
    """Where a CSV's sidecar lies: ``NAME.csv`` -> ``NAME.units.csv``."""
    path = Path(path)
    return path.with_name(path.stem + UNITS_SUFFIX)


def write_csv(frame: pd.DataFrame, path: Path, *, units: bool = True) -> None:
    """Write a table as CSV atomically, every float in full precision (pandas writes the
    shortest text that reads back to the same float: no rounding), and its units beside it in
    ``NAME.units.csv`` (:func:`units_frame`) unless ``units`` is False."""
    path = Path(path)
    write_atomic(path, lambda tmp: frame.to_csv(tmp, index=False))
    if units:
        sidecar = units_frame(frame.columns)
        write_atomic(units_path(path), lambda tmp: sidecar.to_csv(tmp, index=False))


# The tables the commands write under their own names, in the format the product reads back.
TABLES = (
    "region.parquet",
    "table.csv",
    "table_runs.parquet",
    "summary.csv",
    "timeseries.parquet",
    "basin.parquet",
    "pushes.csv",
    "compare.csv",
    "landscape.csv",
    "sensitivity.csv",
    "scorecard.csv",
    "cohort.csv",
    "cohort_summary.csv",
    "cohort_probability.csv",
    "cohort_probability_boundaries.csv",
)


def check_format(fmt: str | None) -> str | None:
    """``fmt`` if it is None (each table in its own format only) or one of :data:`FORMATS`;
    ValueError naming the value otherwise."""
    if fmt is not None and fmt not in FORMATS:
        raise ValueError(
            f"format = {fmt!r}: must be one of {', '.join(FORMATS)} (or None: "
            "each table in the format the product writes it)"
        )
    return fmt


def export_tables(folder: str | os.PathLike[str], fmt: str | None) -> list[Path]:
    """Every table of ``folder`` and its sub-folders (:data:`TABLES`) also in the format(s)
    ``fmt`` asks for, beside it under the same name: ``csv`` (a parquet table also as CSV, with
    its sidecar), ``parquet`` (a CSV table also as parquet), ``both``; None asks for none. A
    copy made earlier that is older than its table (a later run rewrote the table) is written
    again whatever ``fmt`` says, so that no copy disagrees with its table. The table's own file
    stays: resume, ``report`` and ``compare`` read it back. Returns the files written."""
    fmt = check_format(fmt)
    wanted = {None: set(), "csv": {".csv"}, "parquet": {".parquet"}, "both": {".csv", ".parquet"}}[
        fmt
    ]
    written = []
    for name in TABLES:
        for path in sorted(Path(folder).rglob(name)):
            for suffix in sorted({".csv", ".parquet"} - {path.suffix}):
                target = path.with_suffix(suffix)
                stale = target.exists() and target.stat().st_mtime_ns < path.stat().st_mtime_ns
                if suffix not in wanted and not stale:
                    continue
                frame = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
                frame.attrs = {}
                (write_csv if suffix == ".csv" else write_parquet)(frame, target)
                written.append(target)
    return written


def write_text(text: str, path: Path) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(text))


def export_tables_said(out: str | os.PathLike[str], fmt: str | None, say: Any) -> list[Path]:
    """:func:`export_tables`, then one line through ``say`` naming what was written (or that
    every table is already in ``fmt``); nothing said without ``fmt`` and nothing written."""
    written = export_tables(out, fmt)
    names = [str(Path(p).relative_to(out)) for p in written]
    shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
    units = (
        " (units in NAME.units.csv beside each CSV)"
        if any(n.endswith(".csv") for n in names)
        else ""
    )
    if written or fmt is not None:
        say(
            f"wrote {shown} in {out}{units}"
            if written
            else f"--format {fmt}: every table in {out} is already in that format"
        )
    return written
