"""``mjx-balance simulate`` end to end on short scenarios."""

import numpy as np
import pandas as pd
import pytest
from margins import within
from PIL import Image

from mjx_balance import cli
from mjx_balance.cli.simulate import PRINTED_COLUMNS, parse_values
from mjx_balance.measures.outcomes import SUMMARY_COLUMNS
from mjx_balance.measures.strategy import STRATEGY_COLUMNS
from mjx_balance.model.params import ParameterError
from mjx_balance.model.config_files import load_config
from mjx_balance.reference.loop import TIMESERIES_COLUMNS

FIGURES = [
    "ankle_angle",
    "hip_angle",
    "phase_ankle",
    "phase_hip",
    "cop",
    "com",
    "ankle_torque",
    "hip_torque",
    "states",
    "inputs",
    "energy",
    "balance",
]


@pytest.fixture
def short_config(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text("[scenario]\nt_end = 0.5\n")
    return path


# Every (duration, force) pair, durations outermost; the joint convention over 0.5 s: no push
# stays upright, 30 N for 0.1 s never leaves the settle band, 30 N for 0.2 s still sways at 0.5 s.
EXPECTED_ROWS = [
    (0.0, 0.1, "recovered"),
    (30.0, 0.1, "recovered"),
    (0.0, 0.2, "recovered"),
    (30.0, 0.2, "not_settled"),
]


def test_simulate_writes_every_file(tmp_path, short_config, capsys):
    out = tmp_path / "run"
    code = cli.main(
        [
            "simulate",
            "--forces",
            "0,30",
            "--durations",
            "0.1,0.2",
            "--convention",
            "joint",
            "--config",
            str(short_config),
            "--out",
            str(out),
        ]
    )
    assert code == 0
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary.columns) == SUMMARY_COLUMNS + STRATEGY_COLUMNS
    assert list(zip(summary.force, summary.duration, summary.outcome)) == EXPECTED_ROWS
    assert set(summary.convention) == {"joint"}
    assert (summary.settle_time[summary.outcome == "recovered"] >= 0).all()
    assert summary.settle_time[summary.outcome == "not_settled"].isna().all()

    series = pd.read_parquet(out / "timeseries.parquet")
    assert list(series.columns) == TIMESERIES_COLUMNS
    assert sorted(series.scenario.unique()) == [0, 1, 2, 3]
    for i, row in summary.iterrows():  # each scenario ran to the end: 0.5 s at 0.002 s
        run = series[series.scenario == i]
        assert len(run) == 250
        np.testing.assert_allclose(run.time.to_numpy(), 0.002 * np.arange(1, 251))
        assert (run.force == row.force).all() and (run.duration == row.duration).all()
        within(
            run.energy_total.iloc[-1],
            row.energy_total,
            rtol=1e-9,
            atol=1e-12,
            why="the same float64 number, once through summary.csv (pandas reads a "
            "written float back to within an ulp, 1.1e-16)",
        )

    config = load_config(out / "config.toml")
    assert config.scenario.t_end == 0.5 and config.controller.convention == "joint"
    for name in FIGURES:
        path = out / f"{name}.png"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
        with Image.open(path) as image:
            assert image.format == "PNG" and min(image.size) > 100
            image.verify()  # a complete, uncorrupted file

    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("planned work: 4 pushes, 2 s of scenario windows")
    assert lines[1].split() == PRINTED_COLUMNS
    printed = [line.split() for line in lines[2:-1]]
    assert [(float(r[0]), float(r[1]), r[3]) for r in printed] == EXPECTED_ROWS
    assert all(r[2] == "joint" and len(r) == len(PRINTED_COLUMNS) for r in printed)
    assert lines[-1].startswith(f"wrote {out / 'summary.csv'}")
    assert f"{len(FIGURES)} figures" in lines[-1]


@pytest.mark.parametrize(
    "option,value,message",
    [
        ("--forces", "10,abc", "not a number"),
        ("--forces", "nan", "finite"),
        ("--forces", "", "empty grid"),
        ("--durations", "-0.1", ">= 0"),
        ("--durations", "inf", "finite"),
        ("--durations", "0.6", "t_end"),  # longer than the configured 0.5-s scenario
    ],
)
def test_simulate_rejects_bad_values(tmp_path, short_config, capsys, option, value, message):
    args = [
        "simulate",
        "--forces",
        "10",
        "--durations",
        "0.1",
        "--config",
        str(short_config),
        "--out",
        str(tmp_path / "bad"),
    ]
    args[args.index(option) + 1] = value
    assert cli.main(args) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_parse_values():
    assert parse_values("0, 20,50", "force") == [0.0, 20.0, 50.0]
    assert parse_values("-40", "force") == [-40.0]
    with pytest.raises(ParameterError, match="duration"):
        parse_values("-1", "duration", nonnegative=True)


def test_full_window_reaches_the_figures(tmp_path, short_config, monkeypatch):
    """--full-window asks the figures for time axes up to t_end; they get the run's
    configuration and summary (bounds and outcomes) either way."""
    seen = []
    monkeypatch.setattr(
        "mjx_balance.figures.timeseries.timeseries_figures",
        lambda series, out, **kw: seen.append(kw) or [],
    )
    for flag in ([], ["--full-window"]):
        code = cli.main(
            [
                "simulate",
                "--forces",
                "30",
                "--durations",
                "0.1",
                "--config",
                str(short_config),
                "--out",
                str(tmp_path / f"run{len(flag)}"),
                *flag,
            ]
        )
        assert code == 0
    assert [kw["full_window"] for kw in seen] == [False, True]
    assert all(kw["config"].scenario.t_end == 0.5 and len(kw["summary"]) == 1 for kw in seen)


@pytest.mark.parametrize(
    "pairs, expected",
    [
        ("20:0.1,50:0.1", [(20.0, 0.1), (50.0, 0.1)]),  # several forces at one duration
        ("-20:0.1", [(-20.0, 0.1)]),  # a value that starts with a minus is not an option
        ("-20:0.1,-40:0.2,-20:0.1", [(-20.0, 0.1), (-40.0, 0.2), (-20.0, 0.1)]),
    ],
)
def test_pairs_may_share_a_duration_and_start_with_a_minus(pairs, expected):
    from mjx_balance.cli.main import build_parser
    from mjx_balance.model.params import Config
    from mjx_balance.runs.folders import check_pushes

    args = build_parser().parse_args(["simulate", "--pairs", pairs, "--out", "unused"])
    forces, durations, given, _ = check_pushes(
        Config(), args.forces, args.durations, args.pairs, flag="--"
    )
    assert given == expected and list(zip(forces, durations)) == expected


def test_pairs_from_a_data_frame_and_a_file_alike(tmp_path):
    from mjx_balance.runs.grid import parse_pairs

    frame = pd.DataFrame({"Force": [20.0, 50.0], "duration": [0.1, 0.1]})
    (tmp_path / "pairs.csv").write_text("force,duration\n20,0.1\n50,0.1\n")
    for spec in (frame, tmp_path / "pairs.csv"):
        forces, durations = parse_pairs(spec)
        assert forces.tolist() == [20.0, 50.0] and durations.tolist() == [0.1, 0.1]
    with pytest.raises(
        ParameterError, match="pairs: needs columns force and duration.*got columns f, d"
    ):
        parse_pairs(pd.DataFrame({"f": [1.0], "d": [0.1]}))


def test_a_diverging_push_writes_nothing_outside_out(tmp_path, short_config, monkeypatch, capfd):
    """MuJoCo C logs each warning to MUJOCO_LOG.TXT in the working folder and prints it on
    stdout unless told not to (runtime.version.quiet_mujoco_log); a 1e12-N push makes it warn.
    Everything the command writes is under --out, and stdout holds only the command's lines."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    code = cli.main(
        ["simulate", "--forces", "1e12", "--durations", "0.1", "--config", str(short_config)]
        + ["--out", "run"]
    )
    out, _ = capfd.readouterr()
    assert code == 0
    assert pd.read_csv(work / "run" / "summary.csv")["outcome"].tolist() == ["diverged"]
    assert sorted(p.name for p in work.iterdir()) == ["run"]
    assert "QACC" not in out and "WARNING" not in out
