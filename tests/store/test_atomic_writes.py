"""Every file the package writes is written atomically (docs/reliability.md, "Every write site
faulted"): read from the source's AST, each call that writes a file (``Path.write_text`` and
``write_bytes``, pandas' ``to_csv`` and ``to_parquet``, ``savefig``, Arrow's writers, PIL's
``save``, ``json.dump``, ``shutil``'s copies and moves, ``open`` and ``os.open`` for writing)
writes the temporary file of ``store.files.write_atomic`` (its argument or receiver is named
``tmp``), or is one of the few listed below with its reason. A write that fails half-way then
leaves the old file or none, never half a table read back as a result; the write-fault harness
(docs/scripts/write_faults.py) proves it by faulting every site a run has, this test keeps a
new site from bypassing it."""

from __future__ import annotations

import ast
from pathlib import Path

import mjx_balance

PACKAGE = Path(mjx_balance.__file__).resolve().parent
WRITERS = {
    "write_text", "write_bytes", "to_csv", "to_parquet", "to_json", "savefig", "save", "savez",
    "savez_compressed", "write_table", "ParquetWriter", "dump",
}  # fmt: skip
SHUTIL = {"copy", "copy2", "copyfile", "copytree", "copyfileobj", "move"}
NOT_FILES = {"style", "figure_style", "buffer"}  # figures.style.save is atomic; a buffer is no file
ALLOWED = {
    # the temporary file write_atomic handed to anim.save (figures/animation.py)
    ("figures/animation.py", "finish"),
    # the temporary file region.py's write_atomic hands merge_chunks
    ("store/folder.py", "merge_chunks"),
    ("store/folder.py", "flush"),
    # the lock: a record of who holds the folder, never read back as a result
    ("store/folder.py", "folder_lock"),
}


def _names(node: ast.AST) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}


def _kind(call: ast.Call) -> str | None:
    """The kind of file write ``call`` makes, or None."""
    f = call.func
    if isinstance(f, ast.Attribute):
        receiver = f.value.id if isinstance(f.value, ast.Name) else None
        if f.attr in WRITERS and receiver not in NOT_FILES:
            first = call.args[0] if call.args else None
            if not (isinstance(first, ast.Name) and first.id in NOT_FILES):
                return f.attr
        if f.attr in SHUTIL and receiver == "shutil":
            return f"shutil.{f.attr}"
        if f.attr == "open" and receiver == "os":
            return "os.open"
    elif isinstance(f, ast.Name) and f.id == "open":
        mode = call.args[1] if len(call.args) > 1 else None
        mode = next((k.value for k in call.keywords if k.arg == "mode"), mode)
        if isinstance(mode, ast.Constant) and any(c in str(mode.value) for c in "wax+"):
            return "open"
    return None


def raw_writes(package: Path) -> list[str]:
    """Each write call under ``package`` that is neither to a ``tmp`` nor allowed, as
    ``module:line: kind in function``."""
    found = []
    for path in sorted(package.rglob("*.py")):
        module = path.relative_to(package).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        functions = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)]
        inner = {id(c): fn.name for fn in functions for c in ast.walk(fn)}  # innermost last
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call) or (kind := _kind(node)) is None:
                continue
            target = _names(node.func) | {n for a in node.args for n in _names(a)}
            function = inner.get(id(node), "<module>")
            if "tmp" in target or (module, function) in ALLOWED:
                continue
            found.append(f"{module}:{node.lineno}: {kind} in {function}")
    return found


def test_every_file_the_package_writes_is_written_atomically():
    assert raw_writes(PACKAGE) == []


def test_the_scan_finds_a_raw_write(tmp_path):
    """The rule can fail: each kind of raw write in a fixture package is found, and the same
    writes through ``tmp`` are not."""
    (tmp_path / "raw.py").write_text(
        "import json, os, shutil\n"
        "def f(path, frame, fig, out):\n"
        "    path.write_text('x')\n"
        "    frame.to_csv(path)\n"
        "    fig.savefig(path)\n"
        "    shutil.copyfile(out, path)\n"
        "    json.dump({}, open(path, 'w'))\n"
        "    os.open(path, os.O_WRONLY)\n"
        "def g(tmp, frame):\n"
        "    tmp.write_text('x')\n"
        "    frame.to_csv(tmp)\n"
    )
    found = raw_writes(tmp_path)
    kinds = [line.split(": ")[1].split(" in ")[0] for line in found]
    assert sorted(kinds) == sorted(
        ["write_text", "to_csv", "savefig", "shutil.copyfile", "dump", "open", "os.open"]
    )
    assert all(line.endswith(" in f") for line in found)
