"""mujoco and mujoco-mjx must be the same release (pyproject.toml pins both to 3.17.0; MuJoCo
4.0.0 is a meta-package over mujoco-core and mujoco-studio, and mujoco-mjx stops at 3.17.0).
A mismatched pair is refused at the first physics call, in one line that says what to install;
``import mjx_balance`` and ``mjx-balance --version`` stay light and work. The installed versions
are faked by replacing the lookup (``runtime.version.mujoco_versions``).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import tomllib
from support import REPO

from mjx_balance import cli
from mjx_balance.model.mjcf import build_model
from mjx_balance.runtime import version
from mjx_balance.runtime.version import INSTALL, MUJOCO, InstallError, check_mujoco

PIN = 'pip install "mujoco==3.17.0" "mujoco-mjx==3.17.0"'


def installed_as(monkeypatch, mujoco, mujoco_mjx):
    monkeypatch.setattr(version, "mujoco_versions", lambda: (mujoco, mujoco_mjx))


def test_the_pin_is_pyprojects():
    dependencies = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    assert f"mujoco=={MUJOCO}" in dependencies and f"mujoco-mjx=={MUJOCO}" in dependencies
    assert INSTALL == PIN


def test_a_matching_pair_passes(monkeypatch):
    installed_as(monkeypatch, "3.17.0", "3.17.0")
    check_mujoco()
    check_mujoco(mjx=True)
    installed_as(monkeypatch, "3.18.0", "3.18.0")  # a pair of another release still matches
    check_mujoco(mjx=True)


@pytest.mark.parametrize("mjx", [False, True])
def test_a_mismatched_pair_is_refused_in_one_line(monkeypatch, mjx):
    installed_as(monkeypatch, "4.0.0", "3.17.0")
    with pytest.raises(InstallError) as refused:
        check_mujoco(mjx=mjx)
    text = str(refused.value)
    assert "\n" not in text
    assert "mujoco 4.0.0" in text and "mujoco-mjx 3.17.0" in text and text.endswith(PIN)


def test_without_mujoco_mjx_only_the_batched_physics_is_refused(monkeypatch):
    installed_as(monkeypatch, "3.17.0", None)
    check_mujoco()  # MuJoCo C alone: the scalar reference runs
    with pytest.raises(InstallError, match="mujoco-mjx not installed"):
        check_mujoco(mjx=True)


def test_the_lookup_reads_the_distributions(monkeypatch):
    # MuJoCo 4's import package comes from mujoco-core: its version counts without `mujoco`.
    found = {"mujoco-core": "4.0.1", "mujoco-mjx": "3.17.0"}

    def fake(name):
        if name not in found:
            raise version.PackageNotFoundError(name)
        return found[name]

    version.mujoco_versions.cache_clear()
    monkeypatch.setattr(version, "version", fake)
    try:
        assert version.mujoco_versions() == ("4.0.1", "3.17.0")
        with pytest.raises(InstallError, match="mujoco 4.0.1, mujoco-mjx 3.17.0"):
            check_mujoco()
    finally:
        version.mujoco_versions.cache_clear()
    monkeypatch.undo()
    assert version.mujoco_versions() == (
        version.installed("mujoco"),
        version.installed("mujoco-mjx"),
    )


def test_the_physics_refuses_at_its_first_call(monkeypatch):
    from mjx_balance.model.params import Config
    from mjx_balance.rollout import physics  # lazy: JAX, only for this test

    installed_as(monkeypatch, "4.0.0", "3.17.0")
    with pytest.raises(InstallError, match="same release"):
        build_model()  # the C model: the reference's first call
    with pytest.raises(InstallError, match="same release"):
        physics.mj_model(Config())  # the batched paths' first call
    installed_as(monkeypatch, "3.17.0", None)
    build_model()  # the reference still runs without mujoco-mjx
    with pytest.raises(InstallError, match="needs mujoco-mjx"):
        physics.mj_model(Config())


def test_the_command_line_says_it_in_one_line_and_exits_1(monkeypatch, capsys, tmp_path):
    # `view` reaches the physics with the lightest imports (no JAX); every command reports the
    # refusal through the same handler (cli.main._run). A display is faked: the check comes
    # before any window opens.
    import mujoco.viewer

    def no_window(*args, **kwargs):  # were the refusal missing, no window opens here either
        raise RuntimeError("no window in the tests")

    monkeypatch.setattr(mujoco.viewer, "launch_passive", no_window)
    installed_as(monkeypatch, "4.0.0", "3.17.0")
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setenv("XLA_FLAGS", "")  # main() may add a host device count to XLA_FLAGS
    capsys.readouterr()
    assert cli.main(["view", "--force", "10", "--duration", "0.1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("mjx-balance: error: mujoco and mujoco-mjx must be the same release")
    assert err[0].endswith(PIN)


# In a fresh interpreter that sees MuJoCo 4.0.0 beside mujoco-mjx 3.17.0 (importlib.metadata
# patched before the package is imported): the import and --version work and load neither JAX nor
# MuJoCo; the first model build is refused.
MISMATCHED = """
import importlib.metadata, json, sys
real = importlib.metadata.version
importlib.metadata.version = lambda name: "4.0.0" if name == "mujoco" else real(name)
import mjx_balance
from mjx_balance.cli import main
try:
    main(["--version"])
except SystemExit as exc:
    code = exc.code
light = not {"jax", "mujoco"} & set(sys.modules)
from mjx_balance.model.mjcf import build_model
from mjx_balance.runtime.version import InstallError
try:
    build_model()
    refused = None
except InstallError as exc:
    refused = str(exc)
print(json.dumps({"code": code, "light": light, "refused": refused}))
"""


def test_import_and_version_work_under_a_mismatched_pair(tmp_path):
    done = subprocess.run(
        [sys.executable, "-c", MISMATCHED],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
        env={"PATH": "/usr/bin:/bin", "MJX_BALANCE_CACHE_DIR": "off"},
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.strip().splitlines()
    assert lines[0].startswith("mjx-balance ") and "mujoco 4.0.0" in lines[0]
    found = json.loads(lines[-1])
    assert found["code"] == 0 and found["light"]
    assert found["refused"] and found["refused"].endswith(PIN)
