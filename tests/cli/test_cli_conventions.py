"""Command-line conventions: ``python -m mjx_balance``,
``--version``, ``-q`` / ``-v`` through logging, defaults in ``--help``, exit codes, ``--set``
overrides validated as a TOML file is, the manifest's provenance, ``model`` and ``view``."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from datetime import datetime
from importlib.metadata import version

import mujoco
import pytest
from support import DEFAULT_BATCH, REPO, FakeThresholdBatch

from mjx_balance.cli.common import load_run_config
from mjx_balance.cli.main import build_parser, main
from mjx_balance.model.params import Config
from mjx_balance.store import provenance

GRID = ["--forces", "0:20:10", "--durations", "0.5,1", "--set", "scenario.t_end=2"]


@pytest.fixture
def fake(monkeypatch):
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_: FakeThresholdBatch())


def test_python_m_prints_the_versions():
    done = subprocess.run(
        [sys.executable, "-m", "mjx_balance", "--version"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    line = done.stdout.strip()
    for name in ("jax", "jaxlib", "mujoco"):
        assert f"{name} {version(name)}" in line
    assert line.startswith(f"mjx-balance {version('mjx_balance')} (")
    usage = subprocess.run(
        [sys.executable, "-m", "mjx_balance", "sweep", "--no-such-option"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert usage.returncode == 2 and "usage: mjx-balance sweep" in usage.stderr


def test_help_shows_defaults_and_exit_codes():
    parser = build_parser()
    text = parser.format_help()
    assert "exit codes: 0 success; 1 failure" in text and "2 bad usage" in text
    commands = parser._subparsers._group_actions[0].choices
    assert {"simulate", "sweep", "table", "bench", "animate", "report", "model", "view"} <= set(
        commands
    )

    def words(name: str) -> str:  # the help text without its line breaks
        return " ".join(commands[name].format_help().split())

    simulate = words("simulate")
    assert "(default: 0,20,50,80,100,120)" in simulate and "exit codes" in simulate
    assert "frames per second, at most 100 (default: 25.0)" in words("animate")
    sweep = words("sweep")
    assert "(default: None)" not in sweep and "(default: False)" not in sweep
    assert "--set SECTION.KEY=VALUE" in sweep and "--no-cache" in sweep


@pytest.mark.parametrize(
    "name", ["simulate", "bench", "sweep", "table", "animate", "report", "model", "view"]
)
def test_every_command_with_config_takes_set(name):
    extra = {
        "animate": ["--force", "1", "--out", "a.gif"],
        "view": ["--force", "1"],
        "model": ["--out", "m.xml"],
    }.get(name, ["--out", "x"])
    args = build_parser().parse_args(
        [name, "--set", "controller.horizon=30", "--set", "scenario.t_end=6", *extra]
    )
    config = load_run_config(args)
    assert config.controller.horizon == 30 and config.scenario.t_end == 6.0
    assert config.replace(controller={"horizon": 20}, scenario={"t_end": 12.0}) == Config()


def test_set_is_checked_as_a_toml_file_is(tmp_path, capsys):
    """The same rule and message for a value from --set as from the file (exit 2, one line)."""
    for section, key, toml, option in [
        ("controller", "horizon", '"abc"', "abc"),
        ("scenario", "t_end", "-1.0", "-1"),
        ("body", "upper_mass", "1e9", "1e9"),
        ("body", "no_such_key", "1", "1"),
    ]:
        path = tmp_path / f"{key}.toml"
        path.write_text(f"[{section}]\n{key} = {toml}\n")
        assert main(["model", "--config", str(path), "--out", str(tmp_path / "a.xml")]) == 2
        from_file = capsys.readouterr().err.strip()
        assert (
            main(["model", "--set", f"{section}.{key}={option}", "--out", str(tmp_path / "b.xml")])
            == 2
        )
        from_set = capsys.readouterr().err.strip()
        assert len(from_set.splitlines()) == 1
        rule = from_file.removeprefix(f"mjx-balance: error: {path}: ")
        assert rule != from_file and f"{section}" in rule
        assert from_set == f"mjx-balance: error: --set: {rule}"
    # a malformed --set is a usage error of the option itself
    with pytest.raises(SystemExit) as exc:
        main(["model", "--set", "horizon=30", "--out", str(tmp_path / "c.xml")])
    assert exc.value.code == 2
    assert "argument --set: expected SECTION.KEY=VALUE" in capsys.readouterr().err
    assert not list(tmp_path.glob("*.xml"))
    # --set wins over the file; a bare word is a string
    path = tmp_path / "joint.toml"
    path.write_text('[controller]\nconvention = "joint"\nhorizon = 10\n')
    args = build_parser().parse_args(
        ["sweep", "--config", str(path), "--set", "controller.convention=paper", "--out", "x"]
    )
    assert load_run_config(args).controller.convention == "paper"
    assert load_run_config(args).controller.horizon == 10


def test_model_writes_the_configured_body(tmp_path, capsys):
    out = tmp_path / "body.xml"
    assert (
        main(
            [
                "model",
                "--set",
                "body.upper_mass=40",
                "--set",
                "body.lower_length=0.9",
                "--set",
                "body.foot_length=0.26",
                "--set",
                "scenario.physics_dt=0.001",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert f"wrote {out}" in capsys.readouterr().out
    model = mujoco.MjModel.from_xml_path(str(out))
    body = Config().body
    assert model.body("upper").mass[0] == pytest.approx(40.0)
    assert model.body("lower").mass[0] == pytest.approx(body.lower_mass)
    assert model.body("foot").mass[0] == pytest.approx(body.foot_mass)
    assert model.opt.timestep == pytest.approx(0.001)
    # lengths: the lower rod spans the ankle to the hip, the sole its half length each way
    assert model.body("upper").pos[2] == pytest.approx(0.9)
    assert model.geom("sole").size[0] == pytest.approx(0.26 / 2)
    assert model.body("upper").ipos[2] == pytest.approx(body.upper_com)
    # the defaults: the shipped model's masses
    assert main(["-q", "model", "--out", str(tmp_path / "default.xml")]) == 0
    assert capsys.readouterr().out == ""  # -q: no message
    default = mujoco.MjModel.from_xml_path(str(tmp_path / "default.xml"))
    assert default.body_mass.sum() == pytest.approx(body.total_mass)


def test_view_without_a_display_is_one_line_and_exit_1(monkeypatch, capsys):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", "--force", "50"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "needs a display" in err and "DISPLAY" in err


def test_quiet_and_verbose(tmp_path, capsys, fake):
    out = tmp_path / "loud"
    assert main(["sweep", *GRID, "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "sweep: 3 forces x 2 durations" in captured.out and f"wrote {out}" in captured.out
    assert "scenarios" in captured.err  # the progress bar
    assert main(["-q", "sweep", *GRID, "--out", str(tmp_path / "quiet")]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    assert main(["sweep", "-v", *GRID, "--out", str(out)]) == 0  # after the command too
    assert "nothing to do" in capsys.readouterr().out


def test_manifest_records_provenance_and_a_resume_is_not_refused_for_it(tmp_path, fake):
    out = tmp_path / "sweep"
    before = datetime.now().astimezone()
    assert main(["-q", "sweep", *GRID, "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    (run,) = manifest["runs"]
    assert run["command"] == "mjx-balance -q sweep " + " ".join(GRID) + f" --out {out}"
    assert run["status"] == "completed" and run["physics"] == "mjx"
    started, ended = (datetime.fromisoformat(run[k]) for k in ("started", "ended"))
    assert started <= ended and ended >= before.replace(microsecond=0)
    for name, dist in [
        ("package", "mjx_balance"),
        ("jax", "jax"),
        ("jaxlib", "jaxlib"),
        ("mujoco", "mujoco"),
    ]:
        assert run[name] == version(dist)
    assert set(run["device"]) == {"platform", "kind", "count"}
    git = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True)
    if git.returncode == 0:
        assert run["git_commit"] == git.stdout.strip()
    # A second process: its own record, appended; the resume compares only the configuration.
    done = subprocess.run(
        [sys.executable, "-m", "mjx_balance", "-q", "sweep", *GRID, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr  # complete: nothing to run, no rollout built
    runs = json.loads((out / "manifest.json").read_text())["runs"]
    assert len(runs) == 2 and runs[0] == run and runs[1]["run_id"] != run["run_id"]
    assert runs[1]["status"] == "completed"
    # every key of a record is documented (docs/outputs.md)
    documented = set(re.findall(r"`([^`\n]+)`", (REPO / "docs" / "outputs.md").read_text()))
    assert set(run) | set(run["device"]) | {"runs", "kind", "simulate"} <= documented


def test_provenance_without_git(monkeypatch):
    monkeypatch.setattr(provenance, "_GIT", {})
    monkeypatch.setenv("PATH", "/nonexistent")  # no git executable
    record = provenance.provenance()
    assert "git_commit" not in record and record["jax"] == version("jax")


def test_simulate_folder_has_a_manifest_and_can_be_run_again(tmp_path, monkeypatch):
    out = tmp_path / "sim"
    argv = [
        "-q",
        "simulate",
        "--forces",
        "10",
        "--durations",
        "0.1",
        "--set",
        "scenario.t_end=0.1",
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["kind"] == "simulate" and manifest["simulate"]["forces"] == [10.0]
    assert manifest["runs"][0]["physics"] == "mujoco"
    assert main(argv) == 0  # its own folder: not mistaken for a sweep's
