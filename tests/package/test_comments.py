"""Comments and docstrings say what the code does and why, not its history: none under src/ or
tests/ cites a tracker entry by number (the word followed by a number, in any case). History
belongs in CHANGELOG.md and the commit log, measurements in BENCHMARKS.md with their commands.

The check reads each file's comments (``tokenize``) and docstrings (``ast``: the module's, every
class's and every function's); other strings (messages, fixtures) are not read."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

from support import REPO

CITED = re.compile(r"\bissues?\s*#?\s*\d+", re.IGNORECASE)


def comments_and_docstrings(text: str) -> list[tuple[int, str]]:
    """(line, text) of every comment and docstring of a module's source."""
    found = [
        (tok.start[0], tok.string)
        for tok in tokenize.generate_tokens(io.StringIO(text).readline)
        if tok.type == tokenize.COMMENT
    ]
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (
                body
                and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)
            ):
                found.append((body[0].lineno, body[0].value.value))
    return sorted(found)


def cited_numbers(root: Path) -> list[str]:
    """``path:line: match`` for every comment or docstring under ``root`` that cites a tracker
    entry by number."""
    bad = []
    for path in sorted(root.rglob("*.py")):
        for line, text in comments_and_docstrings(path.read_text(encoding="utf-8")):
            for match in CITED.finditer(text):
                bad.append(f"{path.relative_to(root)}:{line}: {match.group(0)!r}")
    return bad


def test_no_comment_or_docstring_cites_a_tracker_number():
    bad = cited_numbers(REPO / "src") + cited_numbers(REPO / "tests")
    assert not bad, "history belongs in CHANGELOG.md, not in comments:\n" + "\n".join(bad)


def test_the_check_finds_a_cited_number(tmp_path):
    word = "Issue"  # spelled apart so that this file's own text holds no citation
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "mod.py").write_text(
        f'"""A module, as asked in {word.lower()} 11."""\n\n'
        f"X = 1  # see {word} 28\n\n\n"
        "class C:\n"
        f'    """Fixed under {word.upper()} #7."""\n\n'
        "    def f(self):\n"
        f'        """Done ({word.lower()}s 3 and 4)."""\n'
        f'        return "{word} 5 in a message is not a comment"\n'
    )
    (tmp_path / "pkg" / "clean.py").write_text(
        '"""The issue\'s case, without a number, and an issue of numbers."""\n# tissue 3\n'
    )
    assert cited_numbers(tmp_path) == [
        "pkg/mod.py:1: 'issue 11'",
        "pkg/mod.py:3: 'Issue 28'",
        "pkg/mod.py:7: 'ISSUE #7'",
        "pkg/mod.py:10: 'issues 3'",
    ]
