"""Packaging (issue 13, item 4): the wheel ships the sweep definitions and py.typed, and an
installed wheel finds them with importlib.resources (not through the source tree).

The wheel is built from a copy of the sources (so the checkout gets no build/ folder) with
``pip wheel --no-deps --no-build-isolation`` (offline: setuptools and wheel from the
environment, ``pip install -e ".[test]"``), then installed into a folder of its own and
imported from there in a fresh interpreter.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p.name for p in (REPO / "src" / "mjx_balance" / "sweeps").glob("*.toml"))


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    work = tmp_path_factory.mktemp("wheel")
    source = work / "source"
    source.mkdir()
    shutil.copytree(REPO / "src", source / "src",
                    ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", str(source), "--no-deps",
                           "--no-build-isolation", "--no-index", "-q", "-w", str(work / "dist")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    (found,) = (work / "dist").glob("mjx_balance-*.whl")
    return found


def test_the_wheel_holds_the_sweeps_py_typed_and_the_model(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    assert len(SHIPPED) >= 15 and "default.toml" in SHIPPED
    assert {f"mjx_balance/sweeps/{name}" for name in SHIPPED} <= names
    assert "mjx_balance/py.typed" in names
    assert "mjx_balance/data/balance.xml" in names
    assert "mjx_balance/__main__.py" in names and "mjx_balance/api.py" in names
    metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
    requires = zipfile.ZipFile(wheel).read(metadata).decode()
    assert "Requires-Dist: tomli-w" in requires


# In the installed copy: where the package and its sweeps are, and every study's definitions.
INSTALLED = """
import json, sys
import mjx_balance
from mjx_balance import studies
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
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-index",
                           "-q", "--target", str(target), str(wheel)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "MJX_BALANCE_CACHE_DIR": "off"}
    run = subprocess.run([sys.executable, "-c", INSTALLED], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    found = json.loads(run.stdout.strip().splitlines()[-1])
    package = Path(found["package"]).parent
    assert package == target / "mjx_balance"  # the installed copy, not the checkout
    assert Path(found["sweeps"]) == package / "sweeps"
    assert [f"{name}.toml" for name in found["shipped"]] == SHIPPED
    assert found["loaded"] >= 10
    assert all(Path(p).parent == package / "sweeps" and Path(p).is_file()
               for p in found["study_files"])
    assert Path(found["dense"]) == package / "sweeps" / "region_dense_paper.toml"
