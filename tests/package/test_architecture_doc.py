"""docs/architecture.md names every module of the package, each on its own line of its table
(``| `runtime/xla.py` | what it holds |``), as test_package_files.py checks the README's API list
against the code."""

from __future__ import annotations

import re
from pathlib import Path

from support import REPO

import mjx_balance

PACKAGE = Path(mjx_balance.__file__).resolve().parent
DOC = REPO / "docs" / "architecture.md"


def modules(root: Path) -> list[str]:
    """Every module under ``root``, as its path relative to it (``runtime/xla.py``)."""
    return sorted(
        path.relative_to(root).as_posix()
        for path in root.rglob("*.py")
        if "__pycache__" not in path.parts
    )


def listed(text: str) -> list[str]:
    """The modules the doc's table lists: the rows that start with a path in backquotes and
    say what it holds."""
    return re.findall(r"^\| `([\w/]+\.py)` \| [^|\s]", text, re.M)


def unlisted(root: Path, text: str) -> list[str]:
    """The modules under ``root`` that have no row in ``text``'s table."""
    return sorted(set(modules(root)) - set(listed(text)))


def test_every_module_has_its_line_in_the_architecture_doc():
    text = DOC.read_text(encoding="utf-8")
    missing = unlisted(PACKAGE, text)
    assert not missing, f"docs/architecture.md lists no line for: {missing}"
    rows = listed(text)
    assert len(rows) == len(set(rows)), f"listed twice: {sorted(rows)}"


def test_the_check_finds_a_module_left_out(tmp_path):
    for name in ("__init__.py", "runtime/__init__.py", "runtime/xla.py", "runtime/new.py"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("")
    doc = (
        "| module | holds |\n|---|---|\n| `__init__.py` | the root |\n"
        "| `runtime/__init__.py` | the floor |\n| `runtime/xla.py` | the flags |\n"
        "named in prose only: `runtime/new.py`\n| `runtime/new.py` | |\n"
    )
    assert unlisted(tmp_path, doc) == ["runtime/new.py"]
