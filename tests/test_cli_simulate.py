"""``mjx-balance simulate`` end to end on short scenarios."""

import pandas as pd
import pytest

from mjx_balance import cli, metrics
from mjx_balance.params import ParameterError, load_config
from mjx_balance.reference import TIMESERIES_COLUMNS, parse_values

FIGURES = ["ankle_angle", "hip_angle", "phase_ankle", "phase_hip", "cop", "com", "ankle_torque",
           "hip_torque", "energy"]


@pytest.fixture
def short_config(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text("[scenario]\nt_end = 0.5\n")
    return path


def test_simulate_writes_every_file(tmp_path, short_config, capsys):
    out = tmp_path / "run"
    code = cli.main(["simulate", "--force", "0,30", "--duration", "0.1", "--convention", "joint",
                     "--config", str(short_config), "--out", str(out)])
    assert code == 0
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary.columns) == metrics.SUMMARY_COLUMNS
    assert list(summary.force) == [0.0, 30.0]
    assert set(summary.convention) == {"joint"}
    assert set(summary.outcome) <= set(metrics.OUTCOMES)
    series = pd.read_parquet(out / "timeseries.parquet")
    assert list(series.columns) == TIMESERIES_COLUMNS
    assert sorted(series.scenario.unique()) == [0, 1]
    assert len(series) == 2 * 250  # 0.5 s at 0.002 s, both scenarios ran to the end
    config = load_config(out / "config.toml")
    assert config.scenario.t_end == 0.5 and config.controller.convention == "joint"
    for name in FIGURES:
        path = out / f"{name}.png"
        assert path.stat().st_size > 10_000
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    printed = capsys.readouterr().out
    assert "outcome" in printed and "recovered" in printed


@pytest.mark.parametrize("option,value,message", [
    ("--force", "10,abc", "not a number"),
    ("--force", "nan", "finite"),
    ("--force", "", "at least one"),
    ("--duration", "-0.1", ">= 0"),
    ("--duration", "inf", "finite"),
    ("--duration", "0.6", "t_end"),  # longer than the configured 0.5-s scenario
])
def test_simulate_rejects_bad_values(tmp_path, short_config, capsys, option, value, message):
    args = ["simulate", "--force", "10", "--duration", "0.1", "--config", str(short_config),
            "--out", str(tmp_path / "bad")]
    args[args.index(option) + 1] = value
    assert cli.main(args) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_parse_values():
    assert parse_values("0, 20,50", "force") == [0.0, 20.0, 50.0]
    assert parse_values("-40", "force") == [-40.0]
    with pytest.raises(ParameterError, match="duration"):
        parse_values("-1", "duration", nonnegative=True)
