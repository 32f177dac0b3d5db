"""The reference tables that ship with the package, by name (``--reference study``).

A shipped reference is a reference file (docs/outputs.md, "Reference files") kept as package
data in ``mjx_balance/data/references/``: published numbers as printed, cited in its
``source`` column, with the measured ``reason`` of every row that differs from ours
(docs/study.md, docs/people.md). ``--reference NAME`` on ``sweep``, ``table`` and ``report``, and
``reference=NAME`` in the Python API, read it as they read a file; a file that happens to be
named like one is given with a path (``./study``).

Importing this module loads neither JAX, MuJoCo nor pandas (the command line's parser uses it).
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

# The largest reference file read (bytes): a published table is a few kB, a lab's trials or
# another model's map a few MB; a file beyond this is refused before it is read.
MAX_BYTES = 256 * 2**20

# name -> (file in data/references/, what it holds)
SHIPPED: dict[str, tuple[str, str]] = {
    "study": (
        "study.csv",
        "K. Shen, A. Chemori, M. Hayashibe, IEEE Access 2020, Table 2: "
        "max acting time and eq. 20 energies of 11 forces, as printed",
    ),
}


# Published measurements of people (data/references/people.csv): a table of its own columns
# (measure, protocol, population, mean, sd, unit, source, doi, quote), held against the
# protocols' predictions (studies/lean.py), not a --reference file of the push map.
PEOPLE = "people.csv"


def people_path() -> Path:
    """The people reference's file (docs/people.md, "People")."""
    return Path(str(resources.files("mjx_balance") / "data" / "references" / PEOPLE))


def read_people() -> "pd.DataFrame":
    """The people reference, one row per measure (``n`` as printed: text)."""
    import pandas as pd  # lazy: this module loads without pandas

    return pd.read_csv(people_path(), comment="#", dtype={"n": str})


def shipped_path(name: str) -> Path:
    """The file of the shipped reference ``name`` (KeyError for another name)."""
    file, _ = SHIPPED[name]
    return Path(str(resources.files("mjx_balance") / "data" / "references" / file))


def resolve(value: str | os.PathLike[str]) -> Path:
    """The file a ``--reference`` value names: a shipped reference's, or the path itself."""
    if isinstance(value, str) and value in SHIPPED:
        return shipped_path(value)
    return Path(value)


def check_size(path: Path) -> None:
    """ValueError naming ``path`` when it is larger than :data:`MAX_BYTES` (nothing read)."""
    try:
        size = path.stat().st_size
    except OSError:
        return  # not there: the reader says so
    if size > MAX_BYTES:
        raise ValueError(
            f"{path}: {size / 2**20:.0f} MiB; a reference file holds at most "
            f"{MAX_BYTES // 2**20} MiB (a published table is a few kB)"
        )


def references() -> dict[str, Path]:
    """Every reference table that ships with the package.

    Returns:
        Name -> its file (a CSV to read with ``comment="#"``, or to pass by name as
        ``reference=`` / ``--reference``): ``"study"``, the study's Table 2 as printed, cited, each
        differing row with its measured reason; ``"people"``, published measurements of people.
    """
    return {name: shipped_path(name) for name in SHIPPED}


def describe() -> str:
    """One line per shipped reference, for help texts."""
    return "; ".join(f"{name}: {what}" for name, (_, what) in SHIPPED.items())
