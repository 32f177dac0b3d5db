"""What a result depends on, printed and pinned: ``mjx-balance --version --verbose`` and
``mb.environment()`` name the versions, the XLA flags, the CPU's vector ISA and the devices;
requirements-lock.txt pins every dependency, at the releases pyproject.toml pins."""

from __future__ import annotations

import re
import tomllib
from importlib.metadata import version

import pytest
from support import REPO

import mjx_balance as mb
from mjx_balance.cli import main


def name_of(requirement: str) -> str:
    """A requirement's distribution name, normalised (PEP 503)."""
    return re.sub(r"[-_.]+", "-", re.split(r"[<>=!~;\[ ]", requirement, maxsplit=1)[0]).lower()


@pytest.mark.parametrize("words", [["--version", "--verbose"], ["-v", "--version"]])
def test_version_verbose_prints_what_a_result_depends_on(capsys, words):
    assert main(words) == 0
    lines = dict(line.split(":", 1) for line in capsys.readouterr().out.strip().splitlines())
    printed = {name: value.strip() for name, value in lines.items()}
    assert printed["jax"] == version("jax") and printed["mujoco"] == version("mujoco")
    assert printed["numpy"] == version("numpy") and printed["osqp"] == version("osqp")
    assert "--xla_cpu_max_isa=AVX" in printed["xla_flags"].split()  # the package's own flags
    assert printed["cpu_isa"] == "AVX" and printed["device"].startswith("platform cpu")
    assert {"x64", "matmul_precision", "result_xla_flags", "os", "git"} <= set(printed)


def test_the_api_returns_the_same_record():
    env = mb.environment()
    assert env["package"] == mb.__version__ and env["jaxlib"] == version("jaxlib")
    assert env["device"]["count"] >= 1 and isinstance(env["xla_flags"], list)


def test_the_lock_file_pins_every_dependency_at_the_pinned_releases():
    """Fails when a dependency is added, or a pin of pyproject.toml moved, without running
    docs/scripts/lock.sh again."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    lock = [
        line
        for line in (REPO / "requirements-lock.txt").read_text().splitlines()
        if line and not line.startswith("#")
    ]
    assert all(re.fullmatch(r"[A-Za-z0-9_.\-]+==[A-Za-z0-9_.+\-]+", line) for line in lock), lock
    locked = {name_of(line): line.split("==")[1] for line in lock}
    for requirement in project["dependencies"]:
        if "python_version <" in requirement:
            continue  # a backport for older Pythons than the lock's
        assert name_of(requirement) in locked, requirement
        pinned = re.search(r"==\s*([\w.]+)", requirement)
        if pinned:
            assert locked[name_of(requirement)] == pinned.group(1), requirement
