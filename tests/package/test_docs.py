"""docs/outputs.md names every column the writers produce, and every pointer in the docs and in
the package's comments leads somewhere.

The column lists are taken from the code, not from a copy: the summary schema
(``outcomes.SUMMARY_COLUMNS``, used by summary.csv and region.parquet), the time series of a
tiny scalar reference run (``reference.timeseries_frame`` through ``simulate_scenario``), the
robustness table as ``max_acting_time`` builds it with a stand-in batch function, the keys
``studies.experiments.open_record`` writes into report.json (plus the ones the report adds
later, read from the source) and the manifest records of a sweep folder. A name counts as
documented when it appears in docs/outputs.md in backticks.

The pointers (files, tests, modules, sections) are read as text: see
``test_every_pointer_in_the_docs_and_comments_exists`` for the rules.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import io
import re
import tokenize
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support import REPO

from mjx_balance.measures import outcomes
from mjx_balance.model.params import CONVENTIONS, Config

OUTPUTS = REPO / "docs" / "outputs.md"
MODEL = REPO / "docs" / "model.md"


def documented() -> set[str]:
    """Every `name` in backticks in docs/outputs.md."""
    return set(re.findall(r"`([^`\n]+)`", OUTPUTS.read_text(encoding="utf-8")))


def missing(columns) -> list[str]:
    names = documented()
    return [c for c in columns if c not in names]


def standin_batch(forces, durations):
    """A stand-in for the rollout: recovered iff F * T < 5 N s, else fell (summary columns with
    integer outcome codes, as the batched runner returns them)."""
    forces = np.asarray(forces, float)
    durations = np.asarray(durations, float)
    ok = forces * durations < 5.0
    out = {c: np.zeros(forces.size) for c in outcomes.SUMMARY_COLUMNS if c != "convention"}
    out["force"], out["duration"] = forces, durations
    out["outcome"] = np.where(ok, outcomes.RECOVERED, outcomes.FELL).astype(np.int32)
    out["settle_time"] = np.where(ok, 1.0, np.nan)
    out["fall_time"] = np.where(ok, np.nan, durations)
    return out


def test_summary_columns_are_documented():
    assert missing(outcomes.SUMMARY_COLUMNS) == []


def test_table_columns_are_documented():
    from mjx_balance.runs.acting_time import TABLE_COLUMNS, max_acting_time

    config = Config().replace(scenario={"t_end": 1.0})
    result = max_acting_time(
        [20.0, 100.0], config, run_batch=standin_batch, progress=False, say=None
    )
    columns = list(result.table.columns)
    assert columns == list(TABLE_COLUMNS)
    assert missing(columns) == []
    # the suffixed energies of the table
    assert {
        "energy_total_01",
        "energy_total_max",
        "ending_outcome",
        "monotone",
        "evaluations",
    } <= set(columns)
    # the table's kept scenarios are summary rows
    assert missing(result.runs.columns) == []


def test_timeseries_columns_are_documented():
    from mjx_balance.reference import loop as reference

    config = Config().replace(scenario={"t_end": 0.05, "duration": 0.02})
    summary, frame = reference.simulate_scenario(config, 10.0, 0.02)
    assert isinstance(frame, pd.DataFrame) and len(frame) > 0
    assert list(frame.columns) == list(reference.TIMESERIES_COLUMNS)
    assert missing(frame.columns) == []
    assert missing(summary) == []


def test_report_json_keys_are_documented(tmp_path):
    from mjx_balance.studies import experiments as run

    plan = run.PLANS["tiny"]
    record = run.open_record(
        tmp_path, run.plan_config(Config(), plan), plan, "reference", CONVENTIONS
    )
    keys = set(record)
    # keys the report adds to the record after it is opened (run_report, run_stage, run_study)
    source = Path(run.__file__).read_text(encoding="utf-8")
    keys |= set(re.findall(r"record\[\"(\w+)\"\]", source))
    keys |= set(re.findall(r"record\.setdefault\(\"(\w+)\"", source))
    assert {"config", "conventions", "plan", "stages", "seconds"} <= keys
    assert missing(sorted(keys)) == []
    assert missing(f.name for f in dataclasses.fields(run.Plan)) == []


def test_manifest_records_are_documented():
    from mjx_balance.store import files
    from mjx_balance.store import folder as store

    names = {key for keys in store.MANIFEST_KEYS.values() for key in keys}
    names |= set(store.MANIFEST_KEYS) | {"region.engine", "table_engine", "slots", "early_stop"}
    names |= {files.MANIFEST, files.CONFIG, files.REGION, files.TABLE, files.TABLE_RUNS, files.LOCK}
    assert missing(sorted(names)) == []


@pytest.mark.parametrize("doc", [OUTPUTS, MODEL])
def test_docs_link_each_other_and_the_engine(doc):
    text = doc.read_text(encoding="utf-8")
    assert "engine.md" in text or doc == OUTPUTS
    assert ("outputs.md" if doc == MODEL else "model.md") in text


def test_model_doc_cites_the_study_and_names_the_outcomes():
    text = MODEL.read_text(encoding="utf-8")
    assert "Human-like Balance Recovery Based on Numerical Model Predictive Control" in text
    for name in (*outcomes.OUTCOMES, *CONVENTIONS):
        assert f"`{name}`" in text
    for name in ("energy_ankle", "energy_hip", "work_ankle", "work_hip", "energy_u1", "energy_u2"):
        assert f"`{name}`" in text


def test_readme_points_inside_the_repository():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert "../shared" not in text
    assert "docs/model.md" in text and "docs/outputs.md" in text


def test_every_test_docs_reliability_names_exists():
    """Each ``tests/PATH.py::test_name`` in docs/reliability.md (and each ``::test_name`` after
    it in the same cell, which names a test of the same file) is a test of that file."""
    named, missing = 0, []
    for line in (REPO / "docs" / "reliability.md").read_text().splitlines():
        for cell in line.split("|"):
            path = None
            for match in re.finditer(r"`(tests/[\w/]+\.py)?(?:::(\w+))?`", cell):
                path = match.group(1) or path
                if path is None:
                    continue
                source = REPO / path
                if not source.exists():
                    missing.append(path)
                elif match.group(2):
                    named += 1
                    if not re.search(rf"^def {match.group(2)}\(", source.read_text(), re.M):
                        missing.append(f"{path}::{match.group(2)}")
    assert named > 40 and not missing, missing


# -- pointers: every file, test, module and section the docs and the comments name exists ------

PACKAGE = REPO / "src" / "mjx_balance"
FLOORS = sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists())
# a repository path: a top-level folder, then a path; not the tail of another path (out/docs/x,
# /tmp/tests/x, DIR/src/x); mjx_balance/... is the package's folder under src/
REPO_PATH = re.compile(r"(?<![\w/.~$-])((?:tests|docs|src|sweeps|notebooks|mjx_balance)/[\w./-]*)")
PATTERN = "*<{[$"  # a path followed by one of these is a pattern (tests/test_*.py, cli/<name>.py)
# a module of the package named by its path below src/mjx_balance: rollout/engine.py
FLOOR_FILE = re.compile(rf"(?<![\w/.~$-])((?:{'|'.join(FLOORS)})(?:/\w+)*/\w+\.py)\b")
TEST_FILE = re.compile(r"(?<![\w/.-])(test_\w+\.py)\b")
# a test: FILE::name, or `::name` after a FILE::name on the same line (a test of that file)
TEST_NAME = re.compile(
    r"(?:(?<![\w/.-])((?:tests/[\w/]+/)?test_\w+\.py)|(?<=[\s`(,;]))::(\w+)"
    r"(\.\.\.|…)?"
)
DOTTED = re.compile(r"(?<![\w.])mjx_balance((?:\.\w+)+)")
SECTION = re.compile(r"((?:docs/)?[\w-]+\.md)[,:]?\s+[\"“]([^\"”]+)[\"”]")
SPEC = re.compile(r"SPEC\s*§")


@functools.cache
def named_test_files() -> dict[str, Path]:
    """Every test file by its name (the names are unique across the floors' folders)."""
    return {path.name: path for path in (REPO / "tests").rglob("test_*.py")}


@functools.cache
def defined(path: Path) -> frozenset[str]:
    """The functions defined in a file (tests, and tests as methods of a class)."""
    text = path.read_text(encoding="utf-8")
    return frozenset(re.findall(r"^\s*(?:async\s+)?def (\w+)\(", text, re.M))


@functools.cache
def top_level(path: Path) -> frozenset[str]:
    """The names a module defines at its top level (functions, classes, assignments, imports)
    and, for a package, the names it hands out lazily (``"name": "module"``)."""
    text = path.read_text(encoding="utf-8")
    names = set()
    for node in ast.parse(text).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    if path.name == "__init__.py":
        names |= set(re.findall(r'"(\w+)":\s*"', text))
    return frozenset(names)


@functools.cache
def package_strings() -> frozenset[str]:
    """The package's own strings that start with ``mjx_balance.``: keys and targets, not
    modules (``b"mjx_balance.units"``, the parquet metadata's key)."""
    found = set()
    for path in PACKAGE.rglob("*.py"):
        found |= set(
            re.findall(r"""b?["'](mjx_balance\.[\w.]+)""", path.read_text(encoding="utf-8"))
        )
    return frozenset(found)


@functools.cache
def module_exists(dotted: str) -> bool:
    """Whether ``mjx_balance`` + ``dotted`` (``.runs.grid.parse_grid``) names a module of the
    package, or a name a module defines at its top level (then a class's attribute may follow;
    a function's or a constant's may not)."""
    if "mjx_balance" + dotted in package_strings():
        return True
    parts = dotted.strip(".").split(".")
    here = PACKAGE
    for i, part in enumerate(parts):
        if part.isupper():
            return True  # a placeholder: mjx_balance.cli.MODULE
        if here.is_dir() and (here / part / "__init__.py").exists():
            here = here / part
        elif here.is_dir() and (here / f"{part}.py").exists():
            here = here / f"{part}.py"
        else:
            if part not in top_level(here / "__init__.py" if here.is_dir() else here):
                return False
            return i == len(parts) - 1 or part[:1].isupper()
    return True


@functools.cache
def sections(doc: Path) -> tuple[str, ...]:
    """A Markdown file's section titles: its headings and its bold paragraph leads
    (``**Longest first.**``), lower case, without backticks."""
    titles = []
    for line in doc.read_text(encoding="utf-8").splitlines():
        match = re.match(r"#+\s+(.*)", line) or re.match(r"\*\*(.+?)\*\*", line)
        if match:
            titles.append(match.group(1).replace("`", "").lower())
    return tuple(titles)


def stale(line: str) -> list[str]:
    """The pointers of one line of text that lead nowhere."""
    bad = []
    for match in REPO_PATH.finditer(line):
        path = match.group(1).rstrip("./-")
        parts = path.split("/")
        if (
            len(parts) < 2
            or line[match.end() : match.end() + 1] in set(PATTERN)
            or any(part.split(".")[0].isupper() for part in parts)
        ):
            continue  # a bare folder, a pattern or a placeholder (tests/PATH.py)
        root = PACKAGE if parts[0] == "mjx_balance" else REPO / parts[0]
        if not root.joinpath(*parts[1:]).exists():
            bad.append(path)
    bad += [m.group(1) for m in FLOOR_FILE.finditer(line) if not (PACKAGE / m.group(1)).exists()]
    bad += [m.group(1) for m in TEST_FILE.finditer(line) if m.group(1) not in named_test_files()]
    last = None
    for match in TEST_NAME.finditer(line):
        file, name, cut = match.groups()
        if file:
            last = (file, REPO / file if "/" in file else named_test_files().get(file))
        if cut or last is None or last[1] is None or not last[1].exists():
            continue  # a name cut short (test_...), or a file already reported
        if name not in defined(last[1]):
            bad.append(f"{last[0]}::{name}")
    bad += [
        f"mjx_balance{m.group(1)}" for m in DOTTED.finditer(line) if not module_exists(m.group(1))
    ]
    for match in SECTION.finditer(line):
        doc = next(
            (d for d in (REPO / match.group(1), REPO / "docs" / match.group(1)) if d.exists()), None
        )
        title = match.group(2).replace("`", "").lower()
        if doc is not None and not any(title in t for t in sections(doc)):
            bad.append(f'{match.group(1)}, "{match.group(2)}"')
    bad += [match.group(0) for match in SPEC.finditer(line)]
    return bad


def comments_and_docstrings(text: str) -> list[tuple[int, str]]:
    """(line number, line) of every comment and every line of every docstring (the module's,
    a class's, a function's) of a module's source."""
    found = [
        (tok.start[0], tok.string)
        for tok in tokenize.generate_tokens(io.StringIO(text).readline)
        if tok.type == tokenize.COMMENT
    ]
    nodes = [ast.parse(text)]
    while nodes:  # the statements only: a docstring is never inside an expression
        node = nodes.pop()
        body = node.body
        if (
            isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            found += [
                (body[0].lineno + k, line)
                for k, line in enumerate(body[0].value.value.splitlines())
            ]
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            nodes += [n for n in getattr(node, field, ()) if hasattr(n, "body")]
    return sorted(found)


def pointed_texts() -> list[tuple[str, list[tuple[int, str]]]]:
    """(file, its (line number, line) pairs) of every text the check reads."""
    texts = []
    whole = [
        *REPO.glob("*.md"),
        *(REPO / "docs").glob("*.md"),
        *(REPO / "sweeps").glob("*.toml"),
        REPO / "pyproject.toml",
        REPO / "CITATION.cff",
        REPO / ".ci" / "run",
    ]
    for path in sorted(whole):
        lines = path.read_text(encoding="utf-8").splitlines()
        texts.append((path.relative_to(REPO).as_posix(), list(enumerate(lines, 1))))
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        texts.append((path.relative_to(REPO).as_posix(), comments_and_docstrings(text)))
    return texts


def test_every_pointer_in_the_docs_and_comments_exists():
    """Every pointer in docs/*.md, the top-level *.md files, the comments and docstrings of
    src/mjx_balance and the shipped sweep definitions (sweeps/*.toml), pyproject.toml,
    CITATION.cff and .ci/run leads somewhere: a reader who follows one finds what it names.

    A line's pointers, and when each leads nowhere:

    - a repository path, ``tests/...``, ``docs/...`` (``docs/scripts/...``), ``src/...``,
      ``sweeps/...``, ``notebooks/...``, or ``mjx_balance/...`` (the package's folder): no such
      file or folder;
    - a module by its path below src/mjx_balance, ``rollout/engine.py``: no such module;
    - a test file by its name, ``test_engine.py`` (the names are unique across the floors'
      folders): no such file under tests/;
    - a test, ``tests/rollout/test_engine.py::test_x`` or ``test_engine.py::test_x``, and a
      `` `::test_y` `` later on the same line (a test of the same file): no such function in
      that file;
    - a dotted name ``mjx_balance.runs.grid.parse_grid``: no such module, or no such name at
      the top level of the last module (or, after a package, in its ``__init__.py`` or its lazy
      names); after a function or a constant nothing may follow, after a class anything may;
    - a section, ``docs/model.md, "The push protocol"`` (also ``model.md "Body"``, relative to
      docs/): no heading or bold paragraph lead (``**Longest first.**``) of that file contains
      the quoted text (backticks and case ignored);
    - ``SPEC §``: the SPEC is not in the repository; the docs' sections are the reference.

    Left alone, by narrow rules: a path that is the tail of another (``out/docs/x``,
    ``/tmp/tests/x``, ``DIR/src/x``, ``~/...``), a pattern (followed by ``*``, ``<``, ``{``,
    ``[`` or ``$``: ``tests/test_*.py``, ``cli/<command>.py``), a placeholder in capitals
    (``tests/PATH.py``, ``mjx_balance.cli.MODULE``), a test name cut short (``test_x...``), a
    dotted name that is one of the package's own strings (``mjx_balance.units``, the parquet
    schema's metadata key), and a section quoted across a line break (not read). Code blocks
    are read like prose: a command or an import in an example must work. Only comments and
    docstrings of the package are read (not its other strings); CHANGELOG.md is read whole,
    so its entries name files as they are now."""
    bad = [
        f"{name}:{number}: {pointer}"
        for name, lines in pointed_texts()
        for number, line in lines
        for pointer in stale(line)
    ]
    assert not bad, "pointers that lead nowhere (file:line: pointer):\n" + "\n".join(bad)


@pytest.mark.parametrize(
    "line, pointers",
    [
        ("checked by tests/test_engine.py", ["tests/test_engine.py"]),
        ("see docs/models.md and docs/model.md.", ["docs/models.md"]),
        (
            "`tests/rollout/test_engine.py::test_no_such_test`, `::test_another_missing`",
            [
                "tests/rollout/test_engine.py::test_no_such_test",
                "tests/rollout/test_engine.py::test_another_missing",
            ],
        ),
        (
            "test_engine.py::test_no_such_test and test_nowhere.py",
            ["test_nowhere.py", "test_engine.py::test_no_such_test"],
        ),
        (
            "the old ``mjx_balance.sweep.store`` and mjx_balance.params.Config",
            ["mjx_balance.sweep.store", "mjx_balance.params.Config"],
        ),
        ("(report/run.py, runs/grid.py)", ["report/run.py"]),
        (
            'docs/model.md, "The push protocol"; docs/engine.md, "Per-lane bodies"; '
            'docs/model.md, "Push physics"',
            ['docs/model.md, "Push physics"'],
        ),
        ("the experiments of SPEC §6", ["SPEC §"]),
        # what is not a pointer, or a pointer that leads somewhere
        (
            "tests/test_*.py, tests/<floor>/test_*.py, tests/PATH.py::test_name, out/docs/x.md, "
            "/tmp/tests/a.py, DIR/src/b.py, cli/<command>.py, test_report.py::test_side_by_side...",
            [],
        ),
        (
            "mjx_balance.runs.grid.parse_grid, mjx_balance.cli.MODULE:FUNCTION, "
            "`mjx_balance.units`, mjx_balance.Config.replace, mjx_balance.sweep, "
            "src/mjx_balance/sweeps/default.toml, mjx_balance/report/templates, "
            "`tests/store/test_exports.py::test_point_three_is_point_three`, "
            'model.md "Which strategy", BENCHMARKS.md, "Longest first"',
            [],
        ),
    ],
)
def test_the_pointer_check_finds_each_kind(line, pointers):
    assert stale(line) == pointers
