"""``mjx-balance bench engine`` (bench/engine.py): the engine's time per control period split
into its parts. The command runs (a tiny grid, in a fresh process with the command line's two
host devices), its parts are non-negative and they add up, with the remainder, to the
end-to-end time it measured; the stage-by-stage replay gives the engine's own bits; the
instrumented run returns the engine's results."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import jax
import numpy as np
import pytest

from mjx_balance.bench import engine as bench_engine
from mjx_balance.cli.bench import engine_table
from mjx_balance.cli.main import build_parser

TINY = [
    "--forces",
    "20,120",
    "--durations",
    "0.1,0.5",
    "--t-end",
    "0.3",
    "--slots",
    "4",
    "--runs",
    "2",
    "--repeats",
    "1",
    "--sampled",
    "100",
    "--json",
]


def run_command(*argv: str) -> tuple[str, dict]:
    """``mjx-balance bench engine ARGV`` in a fresh process: (its output, its JSON line). The
    process shares the session's compile cache (conftest), so a second run loads its programs;
    no check reads the compile seconds."""
    env = dict(os.environ)
    env.pop("XLA_FLAGS", None)  # the command line's own two host devices
    proc = subprocess.run(
        [sys.executable, "-m", "mjx_balance", "bench", "engine", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout, json.loads(proc.stdout.strip().splitlines()[-1])


def check_split(fig: dict) -> None:
    """Every part >= 0; the parts plus the remainder are the end-to-end time, which is the
    mean of the timed runs (measured apart from the parts); the units agree."""
    parts, rem, total = fig["parts"], fig["remainder"], fig["total"]
    assert parts and all(p["seconds"] >= 0 for p in parts.values()), parts
    assert all(p["how"] in ("isolated", "in run") for p in parts.values())
    assert rem["how"] == "remainder" and total["how"] == "measured"
    assert total["seconds"] == pytest.approx(np.mean(fig["runs"]), abs=2e-4)
    assert fig["seconds"] == total["seconds"] > 0
    rounding = 1e-4 * (len(parts) + 2)  # every figure is rounded to 0.1 ms
    assert sum(p["seconds"] for p in parts.values()) + rem["seconds"] == pytest.approx(
        total["seconds"], abs=rounding
    )
    assert rem["device_s"] + rem["host_s"] == pytest.approx(rem["seconds"], abs=3e-4)
    assert sum(p["share"] for p in parts.values()) + rem["share"] == pytest.approx(1, abs=1e-3)
    slot_periods = fig["periods"] * fig["lanes"]
    for r in (*parts.values(), rem, total):  # (seconds are rounded to 0.1 ms, these are not)
        assert r["ms_per_period"] == pytest.approx(
            1e3 * r["seconds"] / fig["periods"], abs=0.1 / fig["periods"] + 1e-4
        )
        assert r["us_per_slot_period"] == pytest.approx(
            1e6 * r["seconds"] / slot_periods, abs=100 / slot_periods + 1e-4
        )
    assert fig["scen_per_s"] == pytest.approx(fig["scenarios"] / fig["seconds"], rel=1e-3)
    assert 0 < fig["occupancy"] <= 1
    it = fig["admm_iterations"]
    assert 0 < it["per_busy_slot"] <= it["per_block"]


def made_up(path: str) -> tuple[list, dict]:
    """Two runs and a replay with round numbers (no compile)."""
    parts = {"transfers": 0.5, "python": 0.25, "device_call": 6.0}
    if path == "c":
        parts.update(physics=2.0, samples_host=0.5)
    drives = [
        bench_engine.Drive({}, 10.0 + d, {k: v + d / 10 for k, v in parts.items()}, 100, 100, [])
        for d in (0.0, 1.0)
    ]
    stages = {
        "physics": 3.0,
        "prepare": 0.25,
        "conclude": 0.25,
        "solve": 2.0,
        "certify": 0.5,
        "refill": 0.25,
        "harvest": 0.25,
        "fold": 1.0,
        "bare_physics": 2.5,
        "qp_vectors": 0.1,
        "call": 0.125,
    }
    return drives, {"seconds": stages}


@pytest.mark.parametrize("path", ["mjx", "c"])
def test_the_split_adds_up(path):
    drives, replay = made_up(path)
    fig = bench_engine.split(path, drives, replay, lanes=8)
    fig.update(
        runs=[d.seconds for d in drives],
        periods=100,
        lanes=8,
        scenarios=21,
        scen_per_s=21 / 10.5,
        occupancy=0.5,
        admm_iterations={
            "per_busy_slot": 10.0,
            "per_block": 20.0,
            "cap": 100,
            "busy_slots_at_cap": 0.0,
            "blocks_at_cap": 0.0,
        },
    )
    check_split(fig)
    isolated = sum(bench_engine.ISOLATED[path].values(), ())
    in_run = bench_engine.IN_RUN[path]
    expected = sum(replay["seconds"][n] for n in isolated) + sum(
        np.mean([d.parts[k] for d in drives]) for k in in_run
    )
    assert fig["remainder"]["seconds"] == pytest.approx(10.5 - expected)
    assert fig["remainder"]["device_s"] == pytest.approx(
        6.05 - sum(replay["seconds"][n] for n in isolated)
    )
    assert set(fig["info"]) >= {"device_call", "qp_vectors"}
    # a stage below its no-op correction counts as 0, and is listed
    replay["seconds"]["certify"] = -0.1
    fig = bench_engine.split(path, drives, replay, lanes=8)
    assert fig["parts"]["certificate"]["seconds"] == 0
    assert fig["below_resolution"] == ["certificate"]


def test_cli_dispatch():
    args = build_parser().parse_args(["bench", "engine", "--physics", "c", "--runs", "1"])
    assert args.target == "mjx_balance.cli.bench:engine_command"
    assert args.physics == ("c",) and args.runs == 1 and args.sampled == 10
    with pytest.raises(SystemExit):
        build_parser().parse_args(["bench", "engine", "--physics", "gpu"])


@pytest.mark.slow  # a whole bench run; the C path's agreement is tests/rollout/test_cpath.py's
def test_bench_engine_c_path():
    """The command on the MuJoCo C path: a tiny grid, every call replayed (and checked)."""
    out, figures = run_command("--physics", "c", *TINY)
    fig = figures["paths"]["c"]
    check_split(fig)
    assert fig["scenarios"] == 4 and fig["calls"] == fig["periods"]
    assert fig["replay"]["identical"] is True and fig["replay"]["differ"] == 0
    assert fig["replay"]["checked"] == fig["periods"]  # every call (--sampled 100)
    for line in engine_table(fig):
        assert line.split()[0] in out
    for part in fig["parts"].values():
        assert part["label"][:40] in out
    assert "REMAINDER" in out and "load average" in out


@pytest.mark.slow  # the MJX engine compiles for about a minute on 2 cores, its stages again
def test_bench_engine_mjx_path():
    """The command on the MJX path; whole blocks replayed stage by stage end in the engine's
    own state, bit for bit."""
    argv = dict(zip(TINY[:-1:2], TINY[1::2]), **{"--slots": "2", "--forces": "20,60,100,140"})
    out, figures = run_command("--physics", "mjx", *sum(argv.items(), ()), "--json")
    fig = figures["paths"]["mjx"]
    check_split(fig)
    assert fig["calls"] >= 2 and fig["periods"] == fig["calls"] * fig["block"]
    assert fig["replay"]["checked"] == fig["calls"] and fig["replay"]["identical"] is True
    assert set(fig["info"]) == {"device_call", "qp_vectors", "bare_physics"}


@pytest.mark.slow  # compiles both engines
@pytest.mark.parametrize("physics", ["c", "mjx"])
def test_the_instrumented_run_is_the_engine(physics):
    """The probed run (its recording on) gives exactly what Engine.run gives on the same
    cells: the probe changes nothing the engine computes."""
    from mjx_balance.model.params import Config
    from mjx_balance.rollout import BatchRunner
    from mjx_balance.rollout.runner import push_steps

    with jax.enable_x64(False):
        runner = BatchRunner(
            Config().replace(scenario={"t_end": 0.3}),
            physics=physics,
            slots=2,
            devices=jax.local_devices()[:1],
        )
        forces = np.array([10.0, 60.0, 120.0, 150.0, 30.0])
        n_push = push_steps(np.array([0.1, 0.3, 0.05, 0.2, 0.3]), 0.002)
        expected = runner.engine.run(forces, n_push)
        got = bench_engine.drive(runner.engine, forces, n_push, record=True).raw
    assert set(got) == set(expected)
    for name in expected:
        assert np.asarray(got[name]).tobytes() == np.asarray(expected[name]).tobytes(), name


def test_agreement_counts_differing_bits():
    a = {"x": np.array([1.0, 2.0, np.nan], np.float32), "k": np.array([3, 4], np.int32)}
    same = bench_engine.Agreement()
    same.add(a, {k: v.copy() for k, v in a.items()})
    assert same.figures(1) == {
        "checked": 1,
        "values": 5,
        "differ": 0,
        "max_rel_diff": 0.0,
        "identical": True,
    }
    b = {k: v.copy() for k, v in a.items()}
    b["x"][1] = np.nextafter(np.float32(2), np.float32(3))  # one ulp
    other = bench_engine.Agreement()
    other.add(a, b)
    fig = other.figures(1)
    assert fig["differ"] == 1 and fig["identical"] is False
    assert 0 < fig["max_rel_diff"] < 1e-6
    assert bench_engine.Agreement().figures(0)["identical"] is None
