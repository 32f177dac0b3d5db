"""The layering rule: the library never imports the command line (only ``cli`` imports ``cli``)."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import mjx_balance


def _library_modules() -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(mjx_balance.__path__, "mjx_balance.")]
    return [n for n in names if n != "mjx_balance.cli" and not n.startswith("mjx_balance.cli.")]


def test_library_modules_exist():
    names = _library_modules()
    for expected in ("mjx_balance.outcomes", "mjx_balance.rollout.kernel",
                     "mjx_balance.sweep.store", "mjx_balance.report.html",
                     "mjx_balance.bench.pipeline"):
        assert expected in names


def test_no_library_module_imports_the_command_line():
    # A fresh interpreter: this test session may have imported the cli already.
    code = (
        "import importlib, sys\n"
        f"for name in {_library_modules()!r}:\n"
        "    importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.startswith('mjx_balance.cli')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300)
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout
