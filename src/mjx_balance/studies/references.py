"""The reference tables that ship with the package, by name (``--reference study``).

A shipped reference is a reference file (docs/outputs.md, "Reference files") kept as package
data in ``mjx_balance/data/references/``: published numbers as printed, cited in its
``source`` column, with the measured ``reason`` of every row that differs from ours
(docs/studies.md). ``--reference NAME`` on ``sweep``, ``table`` and ``report``, and
``reference=NAME`` in the Python API, read it as they read a file; a file that happens to be
named like one is given with a path (``./study``).

Importing this module loads neither JAX, MuJoCo nor pandas (the command line's parser uses it).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

# name -> (file in data/references/, what it holds)
SHIPPED: dict[str, tuple[str, str]] = {
    "study": ("study.csv", "K. Shen, A. Chemori, M. Hayashibe, IEEE Access 2020, Table 2: "
                           "max acting time and eq. 20 energies of 11 forces, as printed"),
}


def shipped_path(name: str) -> Path:
    """The file of the shipped reference ``name`` (KeyError for another name)."""
    file, _ = SHIPPED[name]
    return Path(str(resources.files("mjx_balance").joinpath("data", "references", file)))


def resolve(value: str | Path) -> Path:
    """The file a ``--reference`` value names: a shipped reference's, or the path itself."""
    if isinstance(value, str) and value in SHIPPED:
        return shipped_path(value)
    return Path(value)


def references() -> dict[str, Path]:
    """Every shipped reference: name -> its file (a CSV to read with ``comment="#"``, or to
    pass by name as ``reference=`` / ``--reference``)."""
    return {name: shipped_path(name) for name in SHIPPED}


def describe() -> str:
    """One line per shipped reference, for help texts."""
    return "; ".join(f"{name}: {what}" for name, (_, what) in SHIPPED.items())
