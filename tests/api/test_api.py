"""The public Python API: ``mjx_balance.simulate``, ``sweep``, ``table``,
``load_config``, ``Config``, and the command line as a thin layer over it.

The API's frames are compared with the files the command line writes for the same request.
``simulate`` runs the real scalar reference (0.3-s scenarios); ``sweep`` and ``table`` run the
bookkeeping with the sweep tests' stand-in batch function (the rollout itself is tested in
test_engine.py; the slow test below compares the real rollout too).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from support import DEFAULT_BATCH, FakeThresholdBatch

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.model.params import ParameterError


@pytest.fixture
def fake(monkeypatch):
    """The rollout replaced by the stand-in (recovered iff F * T < 30 N s); the list of the
    stand-ins built."""
    built = []

    def make(config, **_engine):
        built.append(FakeThresholdBatch())
        return built[-1]

    monkeypatch.setattr(DEFAULT_BATCH, make)
    return built


def test_the_package_exports_the_api_and_stays_light():
    assert set(mb.__all__) >= {"simulate", "sweep", "table", "load_config", "Config"}
    for name in mb.__all__:
        assert getattr(mb, name) is not None
    code = (
        "import os, sys, json\n"
        "import mjx_balance as mb\n"
        "print(json.dumps({'heavy': sorted(m for m in ('jax', 'mujoco', 'pandas', 'numpy')"
        " if m in sys.modules), 'flags': os.environ.get('XLA_FLAGS', ''),"
        " 'callable': [callable(getattr(mb, n)) for n in ('simulate', 'sweep', 'table')]}))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PATH": "/usr/bin:/bin"},
    )
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    assert found["heavy"] == []  # import mjx_balance imports neither JAX nor MuJoCo
    assert "--xla_cpu_strict_dot_conv_math=true" in found["flags"]  # set before JAX starts
    assert found["callable"] == [True, True, True]


def test_sweep_is_the_function():
    # mjx_balance.sweep is api.sweep itself (help() shows its docstring); the machinery is
    # mjx_balance.runs (docs/architecture.md)
    import inspect

    from mjx_balance import api, runs

    assert mb.sweep is api.sweep and mb.sweep is not runs and callable(mb.sweep)
    assert list(inspect.signature(mb.sweep).parameters)[:4] == [
        "forces",
        "durations",
        "config",
        "out",
    ]


def test_simulate_returns_the_frames_the_cli_writes(tmp_path):
    config = mb.Config().replace(scenario={"t_end": 0.3})
    summary, series = mb.simulate([30, 0], "0.1", config)
    assert list(summary["force"]) == [0.0, 30.0] and set(summary["duration"]) == {0.1}
    assert series["scenario"].nunique() == 2 and series["time"].max() == pytest.approx(0.3)

    out = tmp_path / "cli"
    assert (
        main(
            [
                "-q",
                "simulate",
                "--forces",
                "0,30",
                "--durations",
                "0.1",
                "--set",
                "scenario.t_end=0.3",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    pd.testing.assert_frame_equal(series, pd.read_parquet(out / "timeseries.parquet"))
    # summary.csv: the numbers as written (CSV reads an empty string back as a missing value)
    written = pd.read_csv(out / "summary.csv")
    assert list(written.columns) == list(summary.columns)
    for column in summary.columns:
        if pd.api.types.is_numeric_dtype(summary[column]):
            np.testing.assert_allclose(written[column], summary[column], rtol=1e-12, atol=0)
        else:
            back = written[column].astype(object).where(written[column].notna(), "")
            assert list(back) == list(summary[column]), column
    assert mb.load_config(out / "config.toml") == config


def test_config_may_be_a_config_a_path_a_dict_or_none(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("[scenario]\nt_end = 0.3\n[body]\nupper_mass = 40.0\n")
    expected = mb.load_config(path)
    assert expected.body.upper_mass == 40.0
    from mjx_balance.api import as_config

    assert as_config(str(path)) == as_config(path) == expected
    assert as_config({"scenario": {"t_end": 0.3}, "body": {"upper_mass": 40}}) == expected
    assert as_config(None) == mb.Config()
    with pytest.raises(ParameterError, match="must be a number"):
        as_config({"controller": {"horizon": "abc"}})
    with pytest.raises(ParameterError, match="config must be"):
        as_config(3)
    with pytest.raises(ParameterError, match="t_end"):  # before any work
        mb.simulate([10], [0.5], expected)
    with pytest.raises(ParameterError, match="forces"):
        mb.simulate("a,b", [0.1], expected)


def test_sweep_and_table_return_the_frames_the_cli_writes(tmp_path, fake):
    cli_out = tmp_path / "cli"
    assert (
        main(
            [
                "-q",
                "sweep",
                "--forces",
                "0:40:10",
                "--durations",
                "0.5,1,1.5",
                "--set",
                "scenario.t_end=2",
                "--out",
                str(cli_out),
            ]
        )
        == 0
    )
    config = mb.Config().replace(scenario={"t_end": 2.0})
    region = mb.sweep("0:40:10", [0.5, 1.0, 1.5], config)  # in memory: nothing kept
    pd.testing.assert_frame_equal(region, pd.read_parquet(cli_out / "region.parquet"))
    assert len(region) == 15 and (region["outcome"] == "fell").any()
    assert not list(tmp_path.glob("mjx_balance-*"))

    api_out = tmp_path / "api"  # on disk: the same store, resumable
    first = mb.sweep([0, 10, 20, 30, 40], "0.5,1,1.5", config, out=api_out)
    pd.testing.assert_frame_equal(first, region)
    calls = len(fake)
    again = mb.sweep([0, 10, 20, 30, 40], "0.5,1,1.5", config, out=api_out)
    pd.testing.assert_frame_equal(again, region)
    assert sum(len(f.calls) for f in fake[calls:]) == 0  # finished: nothing run again
    manifest = json.loads((api_out / "manifest.json").read_text())
    assert manifest["runs"][0]["command"] == "python: mjx_balance.sweep"
    with pytest.raises(ParameterError, match="different configuration"):
        mb.sweep("0:40:10", "0.5,1,1.5", config.replace(body={"upper_mass": 40.0}), out=api_out)

    assert (
        main(
            ["-q", "table", "--forces", "10,20", "--set", "scenario.t_end=2", "--out", str(cli_out)]
        )
        == 0
    )
    table = mb.table([10, 20], config)
    pd.testing.assert_frame_equal(table, pd.read_csv(cli_out / "table.csv"))
    assert list(table["force"]) == [10.0, 20.0]
    # the stand-in recovers iff F T < 30: the max acting time is below 30 / F
    assert np.all(table["max_acting_time"].to_numpy() < 30.0 / table["force"].to_numpy())


@pytest.mark.slow
def test_the_real_rollout_through_the_api_equals_the_cli_file(tmp_path):
    out = tmp_path / "cli"
    assert (
        main(
            [
                "-q",
                "sweep",
                "--forces",
                "20,150",
                "--durations",
                "0.1,0.2",
                "--set",
                "scenario.t_end=1",
                "--slots",
                "4",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    region = mb.sweep([20, 150], [0.1, 0.2], {"scenario": {"t_end": 1.0}}, slots=4)
    pd.testing.assert_frame_equal(region, pd.read_parquet(out / "region.parquet"))


# -- bad arguments: a ValueError naming the argument, nothing written ------------


@pytest.mark.parametrize("forces", [True, [True, 20.0], ["abc"], None, {"a": 1}])
def test_forces_that_are_not_numbers_are_refused(forces, tmp_path):
    with pytest.raises(ValueError, match="forces: expected a number, a sequence of numbers"):
        mb.sweep(forces, [0.1], out=tmp_path / "out")
    # simulate: None is no forces at all (give them, or pairs)
    with pytest.raises(ValueError, match="forces: (expected|give the pushes' forces)"):
        mb.simulate(forces, [0.1])
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "name, value",
    [("chunk", 2.5), ("chunk", 0), ("chunk", "4"), ("slots", 0), ("slots", True), ("slots", -3)],
)
def test_sizes_that_are_not_whole_positive_numbers_are_refused(name, value, tmp_path):
    with pytest.raises(ValueError, match=f"{name} = .*must be a whole number >= 1"):
        mb.sweep([10.0], [0.1], out=tmp_path / "out", **{name: value})
    assert not (tmp_path / "out").exists()


def test_numpy_numbers_are_accepted(fake, tmp_path):
    config = mb.Config().replace(
        body={"upper_mass": np.int64(40)},
        controller={"horizon": np.int64(20)},
        scenario={"t_end": np.float32(2.0)},
    )
    assert config.body.upper_mass == 40.0 and type(config.controller.horizon) is int
    region = mb.sweep(
        np.array([10.0, 60.0]), [np.float64(0.1)], config, chunk=np.int64(2), slots=np.int32(4)
    )
    assert len(region) == 2
