"""Durations that are not whole physics steps and enormous work
are refused at once: exit code 2, one line, nothing written; --yes lets big work through."""

import sys
from pathlib import Path

import numpy as np
import pytest

from mjx_balance.cli import main
from mjx_balance.cli import sweep as cli_sweep
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.runs import check_durations, load_sweep, parse_grid
from mjx_balance.runs.definitions import sweeps_dir
from mjx_balance.runs.grid import check_cell_count, check_whole_steps
from mjx_balance.store import folder as store_folder
from mjx_balance.studies.experiments import PLANS

SWEEPS = sorted(sweeps_dir().glob("*.toml"))  # the shipped definitions (package data)


@pytest.fixture(autouse=True)
def ran(monkeypatch):
    """The folders the command would have worked in: no sweep runs here, even if a guard broke."""
    calls = []
    monkeypatch.setattr(cli_sweep, "in_folder", lambda out, work, **_: calls.append(out) or 0)
    return calls


def refused(capsys, argv, out: Path) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()
    return err


def test_durations_between_physics_steps_are_refused_with_the_nearest_valid_values():
    with pytest.raises(ParameterError, match=r"0\.1001.*nearest valid values: 0\.1 or 0\.102 s"):
        check_whole_steps(parse_grid("0.1001,0.101,0.102"), 0.002)
    # float error is not a different duration: snapped, then the same cell twice
    np.testing.assert_array_equal(check_whole_steps([0.10000000001], 0.002), [0.1])
    with pytest.raises(ParameterError, match="appears more than once"):
        check_whole_steps(parse_grid("0.1,0.10000000001"), 0.002)


def test_sweep_refuses_a_duration_between_steps(tmp_path, capsys):
    out = tmp_path / "run"
    err = refused(
        capsys, ["sweep", "--forces", "10", "--durations", "0.1,0.101", "--out", str(out)], out
    )
    assert "0.101" in err and "physics steps" in err


@pytest.mark.parametrize("path", SWEEPS, ids=lambda p: p.name)
def test_every_sweep_file_has_whole_step_durations(path):
    definition = load_sweep(path, Config())
    if definition.durations is not None:
        sc = definition.config.scenario
        check_durations(parse_grid(definition.durations), sc.t_end, physics_dt=sc.physics_dt)


@pytest.mark.parametrize("name", sorted(PLANS))
def test_every_report_plan_has_whole_step_durations(name):
    plan = PLANS[name]
    t_end = plan.t_end if plan.t_end is not None else Config().scenario.t_end
    for durations in (plan.region_durations, plan.study_durations):
        if durations is not None:
            check_durations(parse_grid(durations), t_end, physics_dt=Config().scenario.physics_dt)


def test_a_grid_too_large_to_hold_is_refused_from_its_counts():
    with pytest.raises(ParameterError, match="300,000,200 cells"):
        check_cell_count(1_500_001, 200)


def test_enormous_sweep_is_refused_before_any_array_or_folder(tmp_path, capsys):
    out = tmp_path / "run"
    err = refused(
        capsys,
        ["sweep", "--forces", "0:150:0.0001", "--durations", "0.05:10:0.05", "--out", str(out)],
        out,
    )
    assert "300,000,200 cells" in err
    err = refused(
        capsys,
        [
            "sweep",
            "--forces",
            "0:150:0.01",
            "--durations",
            "0.05:10:0.01",
            "--out",
            str(out),
            "--chunk",
            "128",
        ],
        out,
    )
    assert "14,940,996 cells" in err and "--yes" in err


def test_yes_lets_big_work_through(tmp_path, capsys, ran):
    out = tmp_path / "run"
    argv = [
        "sweep",
        "--forces",
        "0:150:0.01",
        "--durations",
        "0.05:10:0.01",
        "--chunk",
        "128",
        "--out",
        str(out),
    ]
    assert main(argv + ["--yes"]) == 0 and ran == [out]
    printed = capsys.readouterr().out
    assert "planned work: 14,940,996 cells in 116,727 chunks of 128" in printed


def test_table_is_guarded_too(tmp_path, capsys, ran):
    out = tmp_path / "table"
    refused(capsys, ["table", "--forces", "0:150:0.001", "--out", str(out)], out)
    assert ran == []
    assert main(["table", "--forces", "0:150:0.001", "--out", str(out), "--yes"]) == 0
    assert ran == [out]


# Every command that runs work plans it first: absurd work refused, --yes lets it through.
HUGE = {
    "simulate": ["simulate", "--forces", "0:200:0.01", "--durations", "0.1:1:0.1"],
    "basin": [
        "basin",
        "--x-com",
        "0:0.05:0.00001",
        "--v-com",
        "-0.3:0.3:0.0005",
        "--push-forces",
        "none",
    ],
}


class Reached(Exception):
    """The command went past its checks to the work in its folder."""


@pytest.mark.parametrize("command", sorted(HUGE))
def test_every_command_refuses_absurd_work_unless_yes(tmp_path, capsys, monkeypatch, command):
    from importlib import import_module

    def reached(out, **_):
        raise Reached(out)

    # the work starts where the folder's lock is taken: by the command (simulate) or by the
    # API function it stands on (basin), wherever a module imported the lock
    import_module(f"mjx_balance.cli.{command}")
    import_module("mjx_balance.api")
    lock = store_folder.folder_lock
    for name, module in list(sys.modules.items()):
        if name.startswith("mjx_balance") and getattr(module, "folder_lock", None) is lock:
            monkeypatch.setattr(module, "folder_lock", reached)
    out = tmp_path / "run"
    assert main([*HUGE[command], "--out", str(out)]) == 2
    said = capsys.readouterr()
    assert said.out.startswith("planned work: ")  # said first, then refused in one line
    assert len(said.err.strip().splitlines()) == 1 and "Traceback" not in said.err
    assert "beyond the limit" in said.err and "--yes" in said.err
    assert not out.exists()
    with pytest.raises(Reached):
        main([*HUGE[command], "--yes", "--out", str(out)])


def test_a_short_window_is_planned_as_the_rates_window():
    """The engine's rate was measured on 12-s windows decided early, so a 2-s window is planned
    as one (1,001,000 cells of 2 s: 2.1 to 3.2 h, as such a sweep's progress bar showed, not
    the 21 to 32 min a window-proportional plan said); the scalar reference runs every window
    whole, so its plan stays proportional."""
    from mjx_balance.runs import chunks

    assert "about 2.1 to 3.2 h" in chunks.planned_work(1_001_000, 2.0, None)
    assert "about 21 to 32 min" in chunks.planned_work(1_001_000, 2.0, None, window_floor=0)
    twelve = chunks.planned_work(1000, 12.0, None)
    assert (
        twelve.split(" at ")[0].split(", ")[-1]
        == chunks.planned_work(1000, 1.0, None).split(" at ")[0].split(", ")[-1]
    )


@pytest.mark.parametrize(
    "argv, startup",
    [
        (["table", "--forces", "50", "--set", "scenario.t_end=2"], "ENGINE_STARTUP"),
        (["simulate", "--forces", "50", "--durations", "0.1"], "REFERENCE_STARTUP"),
    ],
)
def test_the_plan_counts_the_start_up(tmp_path, capsys, monkeypatch, argv, startup):
    """A tiny run's plan said "under 1 s" and took 21 s (a table of one force): the plan line
    now says the start-up beside the work (runs.chunks: measured tiny runs, cold and warm), and
    the limit counts it."""
    from mjx_balance.runs import chunks

    low, high, what = getattr(chunks, startup)
    assert 1 <= low < high
    limits = []

    def limit(*_args, setup_s=0.0, **_kwargs):  # the guard's check: the seconds it counted
        limits.append(setup_s)
        raise Reached

    monkeypatch.setattr(chunks, "check_planned_work", limit)
    with pytest.raises(Reached):
        main([*argv, "--out", str(tmp_path / "out")])
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("planned work"))
    assert f"plus {chunks.wall_span(low, high)} of start-up ({what})" in line, line
    assert limits == [high]
