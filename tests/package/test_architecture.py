"""The package's floors and its import rule (docs/architecture.md), read from the source's AST.

The rules, each a function of a source tree that returns its violations, so that a fixture
package can show every rule failing (``test_each_rule_fails_on_a_broken_fixture``):

- floors: a module imports only from its own floor or from floors below it, in the order of
  :data:`FLOORS` (the package root ``mjx_balance/__init__.py`` and ``__main__`` sit on top);
- no import cycle between modules, counting imports inside functions too;
- no name starting with ``_`` imported from another module of the package;
- no import of a package module inside a function, unless the line (or the one above it) says
  why with a comment containing ``lazy:`` (the imports that keep ``import mjx_balance`` and
  ``mjx-balance --help`` light: JAX and MuJoCo must not load before the XLA flags are set);
  third-party imports inside functions (optional dependencies) are not checked;
- no function longer than 80 lines, none with more than 8 positional parameters.
"""

from __future__ import annotations

import ast
import importlib
import os
import pkgutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import mjx_balance

PACKAGE = Path(mjx_balance.__file__).resolve().parent

# Bottom up: each floor may import from itself and from the floors before it.
FLOORS = (
    "runtime",
    "model",
    "measures",
    "control",
    "reference",
    "rollout",
    "store",
    "runs",
    "figures",
    "studies",
    "report",
    "bench",
    "api",
    "cli",
)
TOP = ("", "__main__")  # the package root and ``python -m mjx_balance``: above every floor
MAX_LINES = 80
MAX_POSITIONAL = 8


@dataclass(frozen=True)
class Import:
    module: str  # the importing module
    target: str  # the imported module (a submodule when ``from pkg import sub``)
    names: tuple  # the names imported from it (empty for ``import x``)
    line: int
    in_function: bool
    lazy: bool  # marked with a ``lazy:`` comment


def _modules(root: Path, package: str) -> dict[str, Path]:
    found = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join([package, *parts])] = path
    return found


def _absolute(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def imports(root: Path, package: str) -> list[Import]:
    """Every import of a package module in the tree under ``root`` (the package's folder)."""
    modules = _modules(root, package)
    found = []
    for module, path in modules.items():
        source = path.read_text()
        lines = source.splitlines()
        is_package = path.name == "__init__.py"

        def lazy(node: ast.stmt) -> bool:
            here = lines[node.lineno - 1 : node.end_lineno]  # noqa: B023 - called in the same iteration
            above = lines[node.lineno - 2] if node.lineno > 1 else ""  # noqa: B023 - called in the same iteration
            return any("lazy:" in text for text in here) or above.strip().startswith("# lazy:")

        def visit(node: ast.AST, in_function: bool) -> None:
            for child in ast.iter_child_nodes(node):
                inner = in_function or isinstance(
                    child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)
                )
                if isinstance(child, ast.ImportFrom):
                    target = _absolute(module, is_package, child)  # noqa: B023 - called in the same iteration
                    if target == package or target.startswith(package + "."):
                        plain = []
                        for alias in child.names:
                            sub = f"{target}.{alias.name}"
                            if sub in modules:
                                found.append(
                                    Import(
                                        module,  # noqa: B023 - called in the same iteration
                                        sub,
                                        (),
                                        child.lineno,
                                        in_function,
                                        lazy(child),
                                    )
                                )
                            else:
                                plain.append(alias.name)
                        if plain:
                            found.append(
                                Import(
                                    module,  # noqa: B023 - called in the same iteration
                                    target,
                                    tuple(plain),
                                    child.lineno,
                                    in_function,
                                    lazy(child),
                                )
                            )
                elif isinstance(child, ast.Import):
                    for alias in child.names:
                        if alias.name == package or alias.name.startswith(package + "."):
                            found.append(
                                Import(
                                    module,  # noqa: B023 - called in the same iteration
                                    alias.name,
                                    (),
                                    child.lineno,
                                    in_function,
                                    lazy(child),
                                )
                            )
                visit(child, inner)

        visit(ast.parse(source), False)
    return found


def floor(module: str, package: str) -> int:
    """The floor's index in :data:`FLOORS` (the root and ``__main__``: above all)."""
    rest = module[len(package) + 1 :] if module != package else ""
    head = rest.split(".")[0]
    if head in TOP:
        return len(FLOORS)
    return FLOORS.index(head)


def upward_imports(found: list[Import], package: str) -> list[str]:
    def name(index: int) -> str:
        return FLOORS[index] if index < len(FLOORS) else "top"

    return [
        f"{i.module}:{i.line} imports {i.target} (floor {name(floor(i.target, package))}"
        f" is above its own)"
        for i in found
        if floor(i.target, package) > floor(i.module, package)
    ]


def cycles(found: list[Import], package: str) -> list[str]:
    """Import cycles between modules (a package's ``__init__`` counts as a module; importing
    a submodule also runs its package's ``__init__``, which is not counted: only the edges
    written in the source are)."""
    graph: dict[str, set[str]] = {}
    for i in found:
        if i.target != i.module:
            graph.setdefault(i.module, set()).add(i.target)
    # Tarjan's strongly connected components.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    result: list[str] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                result.append(" <-> ".join(sorted(component)))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in sorted(graph):
        if v not in index:
            connect(v)
    return result


def private_imports(found: list[Import]) -> list[str]:
    return [
        f"{i.module}:{i.line} imports {name} from {i.target}"
        for i in found
        for name in i.names
        if name.startswith("_") and not name.startswith("__") and i.target != i.module
    ]


def unmarked_function_imports(found: list[Import]) -> list[str]:
    return [
        f"{i.module}:{i.line} imports {i.target} inside a function without a 'lazy:' comment"
        for i in found
        if i.in_function and not i.lazy
    ]


def _docstring_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """The lines of a function's docstring: the limit is on its code (the public API's
    docstrings carry Args, Returns and Raises sections: tests/package/test_api_docs.py)."""
    first = node.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
        if isinstance(first.value.value, str):
            return first.end_lineno - first.lineno + 1
    return 0


def long_functions(root: Path, package: str) -> list[str]:
    bad = []
    for module, path in _modules(root, package).items():
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            length = node.end_lineno - node.lineno + 1 - _docstring_lines(node)
            if length > MAX_LINES:
                bad.append(f"{module}:{node.lineno} {node.name} has {length} lines")
            args = node.args.posonlyargs + node.args.args
            positional = len(args) - (1 if args and args[0].arg in ("self", "cls") else 0)
            if positional > MAX_POSITIONAL:
                bad.append(
                    f"{module}:{node.lineno} {node.name} has {positional} positional parameters"
                )
    return bad


def violations(root: Path, package: str) -> dict[str, list[str]]:
    found = imports(root, package)
    return {
        "upward": upward_imports(found, package),
        "cycles": cycles(found, package),
        "private": private_imports(found),
        "function-level": unmarked_function_imports(found),
        "size": long_functions(root, package),
    }


# -- the package ------------------------------------------------------------------------------


def test_every_module_is_on_a_floor():
    for module in _modules(PACKAGE, "mjx_balance"):
        floor(module, "mjx_balance")  # raises ValueError for a module outside the floors


def test_the_package_keeps_the_import_rule():
    assert violations(PACKAGE, "mjx_balance") == {
        "upward": [],
        "cycles": [],
        "private": [],
        "function-level": [],
        "size": [],
    }


# -- the rules can fail -------------------------------------------------------------------------

BAD = {
    "__init__.py": "",
    "model/__init__.py": "",
    # upward: the model floor imports the control floor
    "model/params.py": "from ..control.qp import build\n\n\ndef make():\n    return build\n",
    "control/__init__.py": "",
    # private: a private name of another module; cycle: qp <-> admm (one inside a function,
    # marked lazy, still a cycle)
    "control/qp.py": "from .admm import _step\n\n\ndef build():\n    return _step\n",
    "control/admm.py": (
        "def _step():\n    # lazy: for the test\n    from .qp import build\n"
        "    return build\n\n\ndef solve():\n    from . import qp\n"
        "    return qp\n"
    ),
    # size: 81 lines; positional: 9 parameters
    "runs/__init__.py": "",
    "runs/grid.py": (
        "def long():\n" + "    x = 1\n" * 79 + "    return x\n\n\n"
        "def many(a, b, c, d, e, f, g, h, i):\n    return a\n\n\n"
        "def fine(a, b, c, d, e, f, g, h, *, i=1):\n    return a\n"
    ),
}


def test_each_rule_fails_on_a_broken_fixture(tmp_path):
    root = tmp_path / "fake"
    for name, text in BAD.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    found = violations(root, "fake")
    assert found["upward"] == [
        "fake.model.params:1 imports fake.control.qp (floor control is above its own)"
    ]
    assert found["cycles"] == ["fake.control.admm <-> fake.control.qp"]
    assert found["private"] == ["fake.control.qp:1 imports _step from fake.control.admm"]
    assert found["function-level"] == [
        "fake.control.admm:8 imports fake.control.qp inside a function without a 'lazy:' comment"
    ]
    assert found["size"] == [
        "fake.runs.grid:1 long has 81 lines",
        "fake.runs.grid:84 many has 9 positional parameters",
    ]


# -- the library never imports the command line; import mjx_balance stays light -----------------


def _library_modules() -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(mjx_balance.__path__, "mjx_balance.")]
    return [n for n in names if n != "mjx_balance.cli" and not n.startswith("mjx_balance.cli.")]


def test_library_modules_exist():
    names = _library_modules()
    for expected in (
        "mjx_balance.measures.outcomes",
        "mjx_balance.rollout.kernel",
        "mjx_balance.store.folder",
        "mjx_balance.report.html",
        "mjx_balance.bench.pipeline",
        "mjx_balance.runtime.compiled",
    ):
        assert expected in names


def test_no_library_module_imports_the_command_line():
    # A fresh interpreter: this test session may have imported the cli already.
    code = (
        "import importlib, sys\n"
        f"for name in {_library_modules()!r}:\n"
        "    importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.startswith('mjx_balance.cli')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout


def test_import_and_help_stay_light():
    # Neither JAX nor MuJoCo loads for ``import mjx_balance`` or for building the parser.
    code = (
        "import sys, mjx_balance\nfrom mjx_balance.cli.main import build_parser\n"
        "build_parser()\n"
        "print(sorted(m for m in ('jax', 'mujoco', 'pandas') if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout


def test_help_of_the_sweep_function():
    import pydoc

    from mjx_balance import api

    assert mjx_balance.sweep is api.sweep
    text = pydoc.render_doc(mjx_balance.sweep, renderer=pydoc.plaintext)
    assert api.sweep.__doc__.strip().splitlines()[0] in text
    # the package holds no module called ``sweep`` that could shadow the function
    assert not (PACKAGE / "sweep").exists() and not (PACKAGE / "sweep.py").exists()


def test_old_module_names_are_gone():
    # The flat layout's names (``mjx_balance.params``, ``mjx_balance.sweep.*``) were never
    # released: nothing answers to them (CHANGELOG.md, "Removed").
    for old in ("mjx_balance.params", "mjx_balance.sweep.definitions", "mjx_balance.region_plots"):
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(old)


def test_no_library_module_switches_the_matplotlib_backend():
    # A notebook's inline backend stays (the command line picks Agg for itself): importing
    # every module leaves the backend the user chose.
    code = (
        "import importlib, matplotlib\n"
        f"for name in {_library_modules()!r}:\n"
        "    importlib.import_module(name)\n"
        "print(matplotlib.get_backend())\n"
    )
    env = {**os.environ, "MPLBACKEND": "svg"}
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
        env=env,
    )
    assert out.stdout.strip().splitlines()[-1] == "svg", out.stdout
