"""Packaging: the sweep definitions live once, in the repository's top-level ``sweeps/`` (the
package's ``mjx_balance/sweeps`` is a symbolic link to it), and every install finds them: the
editable install of the README (``pip install -e .``), ``pip install .`` and a wheel. The wheel
also ships py.typed, the default model and the LICENSE.

The source is copied with its symbolic link (as a clone has it, without the checkout's build
products) and built with ``pip wheel`` / ``pip install --target`` ``--no-deps
--no-build-isolation`` (offline: setuptools and wheel from the environment, ``pip install -e
".[test]"``); an installed copy is imported from its own folder in a fresh interpreter.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from support import REPO

SHIPPED = sorted(p.name for p in (REPO / "sweeps").glob("*.toml"))
PIP = [sys.executable, "-m", "pip"]
OFFLINE = ["--no-deps", "--no-build-isolation", "--no-index", "-q"]


@pytest.fixture(scope="module")
def source(tmp_path_factory) -> Path:
    """A copy of the repository as a clone has it: src/ (the package's sweeps a link), sweeps/,
    pyproject.toml, README.md and LICENSE."""
    work = tmp_path_factory.mktemp("source")
    shutil.copytree(
        REPO / "src",
        work / "src",
        symlinks=True,
        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"),
    )
    shutil.copytree(REPO / "sweeps", work / "sweeps")
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(REPO / name, work / name)
    assert (work / "src" / "mjx_balance" / "sweeps").is_symlink()
    return work


@pytest.fixture(scope="module")
def wheel(source, tmp_path_factory) -> Path:
    dist = tmp_path_factory.mktemp("dist")
    done = subprocess.run(
        [*PIP, "wheel", str(source), *OFFLINE, "-w", str(dist)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    (found,) = dist.glob("mjx_balance-*.whl")
    return found


def test_one_source_of_truth_for_the_sweep_definitions():
    link = REPO / "src" / "mjx_balance" / "sweeps"
    assert link.is_symlink() and link.resolve() == (REPO / "sweeps").resolve()
    assert len(SHIPPED) >= 15 and "default.toml" in SHIPPED


def test_the_wheel_holds_the_sweeps_py_typed_and_the_model(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {f"mjx_balance/sweeps/{name}" for name in SHIPPED} <= names
    for name in SHIPPED:  # the files themselves, not the link
        shipped = zipfile.ZipFile(wheel).read(f"mjx_balance/sweeps/{name}")
        assert shipped == (REPO / "sweeps" / name).read_bytes()
    assert "mjx_balance/py.typed" in names
    assert "mjx_balance/data/balance.xml" in names
    assert "mjx_balance/__main__.py" in names and "mjx_balance/api.py" in names
    metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
    requires = zipfile.ZipFile(wheel).read(metadata).decode()
    assert "Requires-Dist: tomli-w" in requires
    # the license travels with the wheel (pyproject's license-files) and its metadata names it
    license_file = next(n for n in names if n.endswith(".dist-info/licenses/LICENSE"))
    assert zipfile.ZipFile(wheel).read(license_file) == (REPO / "LICENSE").read_bytes()
    assert "License-Expression: Apache-2.0" in requires


def test_pip_install_dot_copies_the_sweeps(source, tmp_path):
    target = tmp_path / "site"
    done = subprocess.run(
        [*PIP, "install", *OFFLINE, "--target", str(target), str(source)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    installed = target / "mjx_balance" / "sweeps"
    assert not installed.is_symlink()
    assert sorted(p.name for p in installed.glob("*.toml")) == SHIPPED
    shipped = (REPO / "sweeps" / "default.toml").read_bytes()
    assert (installed / "default.toml").read_bytes() == shipped


def test_the_editable_install_reads_the_repository_sweeps():
    # The README's install (pip install -e .): the package is the checkout's, and its sweeps are
    # the top-level sweeps/ through the link, so an edited definition is seen at once.
    import mjx_balance
    from mjx_balance.runs.definitions import shipped_sweeps, sweeps_dir

    if Path(mjx_balance.__file__).resolve().parent != (REPO / "src" / "mjx_balance").resolve():
        pytest.skip("mjx_balance is not installed from this checkout (pip install -e .)")
    assert Path(os.path.realpath(sweeps_dir())) == (REPO / "sweeps").resolve()
    assert [f"{name}.toml" for name in shipped_sweeps()] == SHIPPED


# In the installed copy: where the package and its sweeps are, and every study's definitions.
INSTALLED = """
import json, sys
import mjx_balance
from mjx_balance.studies import catalog as studies
from mjx_balance.model.params import Config
from mjx_balance.runs.definitions import find_sweep, shipped_sweeps, sweeps_dir
loaded = 0
for st in studies.STUDIES:
    for variant in st.variants:
        studies.variant_definition(st, variant, Config())
        loaded += 1
print(json.dumps({"package": mjx_balance.__file__, "sweeps": str(sweeps_dir()),
                  "shipped": shipped_sweeps(), "loaded": loaded,
                  "study_files": [str(p) for p in studies.study_files()],
                  "dense": str(find_sweep("region_dense_paper"))}))
"""


def test_an_installed_wheel_finds_its_sweeps_without_the_source_tree(wheel, tmp_path):
    target = tmp_path / "site"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "--no-index",
            "-q",
            "--target",
            str(target),
            str(wheel),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "MJX_BALANCE_CACHE_DIR": "off"}
    run = subprocess.run(
        [sys.executable, "-c", INSTALLED],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout.strip().splitlines()[-1])
    package = Path(found["package"]).parent
    assert package == target / "mjx_balance"  # the installed copy, not the checkout
    assert Path(found["sweeps"]) == package / "sweeps"
    assert [f"{name}.toml" for name in found["shipped"]] == SHIPPED
    assert found["loaded"] >= 10
    assert all(
        Path(p).parent == package / "sweeps" and Path(p).is_file() for p in found["study_files"]
    )
    assert Path(found["dense"]) == package / "sweeps" / "region_dense_paper.toml"
