"""``mjx-balance landscape`` / ``landscape.run_landscape``: the weight landscape.

Most tests use a stand-in batch function whose outcome depends on the weights and the delay in
closed form (recovered iff |F| T < c(config), the stand-in of tests/support.py), so every
number of landscape.csv is known and nothing compiles. One test runs the real rollout (the
session's compiled closed loop, shared because weights are data) and checks the landscape's
numbers against a direct ``compare`` of the same configuration, written independently."""

import math
import shutil

import numpy as np
import pandas as pd
import pytest
from PIL import Image
from support import FakeThresholdBatch, expected_area, expected_max_time

from mjx_balance.cli import main
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.studies import landscape
from mjx_balance.studies.compare import run_compare

FORCES, DURATIONS, TABLE_FORCES = "0:40:10", "0.5,1,2", "10"
QS, RS = "1,10", "0.1,1"


def weights(config: Config) -> tuple[float, float]:
    """The (Q, R) scales of a configuration relative to the defaults."""
    base = Config().controller
    return (
        config.controller.q_diag[0] / base.q_diag[0],
        config.controller.r_diag[1] / base.r_diag[1],
    )


def threshold(config: Config) -> float:
    """The stand-in's c: grows with Q/R, halved by a delay, partly restored by compensation."""
    q, r = weights(config)
    c = 20.0 * (q / r) ** 0.25
    if config.scenario.controller_delay > 0:
        c *= 0.8 if config.controller.delay_compensation else 0.5
    return c


def energy_factor(config: Config) -> float:
    q, r = weights(config)
    return 1.0 + q + 1.0 / r  # 2 + 1/r at Q x 1 ... (the base weights: 3)


class WeightedFake(FakeThresholdBatch):
    """FAKE batch function: the stand-in with its energies scaled per configuration."""

    def __init__(self, config):
        super().__init__(c=threshold(config))
        self.config = config
        self.factor = energy_factor(config)

    def __call__(self, forces, durations):
        out = super().__call__(forces, durations)
        out["energy_total"] = out["energy_total"] * self.factor
        return out


def stand_in_fake(config):
    """The stand-in of a configuration (conftest's ``stand_in`` makes one per configuration)."""
    return WeightedFake(config)


def calls(made) -> int:
    return sum(len(f.calls) for f in made)


def cli(out, *extra):
    return main(
        [
            "landscape",
            "--q-scales",
            QS,
            "--r-scales",
            RS,
            "--delays",
            "0,100c",
            "--forces",
            FORCES,
            "--durations",
            DURATIONS,
            "--table-forces",
            TABLE_FORCES,
            "--out",
            str(out),
            *extra,
        ]
    )


def test_landscape_writes_its_numbers_figure_and_reading(tmp_path, stand_in):
    out = tmp_path / "land"
    assert cli(out) == 0
    frame = pd.read_csv(out / "landscape.csv")
    assert len(frame) == 8 and list(frame.columns[:5]) == landscape.KEY_COLUMNS
    assert list(frame["delay"].unique()) == ["0", "100c"]
    for _, row in frame.iterrows():
        config = landscape.setting_config(
            Config(),
            landscape.Delay(row["delay_ms"], row["compensated"]),
            row["q_scale"],
            row["r_scale"],
        )
        assert weights(config) == pytest.approx((row["q_scale"], row["r_scale"]))
        c = threshold(config)
        assert row["area"] == pytest.approx(expected_area(c))
        assert row["sustained_push_limit"] == pytest.approx(np.floor(c / 12 * 10 - 1e-9) / 10)
        assert row["max_acting_time_10N"] == expected_max_time(10, c, 12.0)
        assert row["study"] == (row["q_scale"] == 1 and row["r_scale"] == 1)
        assert row["nonconverged_solves"] == 0
        # the same pushes recovered x the energy factor: exactly the factors' ratio when this
        # setting recovers at least the base's cells
        base = landscape.setting_config(
            Config(), landscape.Delay(row["delay_ms"], row["compensated"]), 1, 1
        )
        assert row["energy_vs_study"] == pytest.approx(energy_factor(config) / energy_factor(base))
    base = frame[(frame["delay"] == "0") & frame["study"]].iloc[0]
    assert base["area"] == pytest.approx(expected_area(20.0))
    with Image.open(out / "landscape.png") as image:
        assert image.size[0] > 1000 and image.size[1] > 600  # 2 rows x 4 panels
    text = (out / "landscape.txt").read_text()
    best = frame[frame["delay"] == "0"].sort_values("area").iloc[-1]  # Q x 10, R x 0.1
    assert (best["q_scale"], best["r_scale"]) == (10, 0.1)
    assert f"Largest area {best['area']:.4g} N s at (Q x 10, R x 0.1)" in text
    assert "no delay (4 settings)" in text and "100 ms, compensated (4 settings)" in text
    assert (out / "delay_100ms_comp" / "q10_r0.1" / "region.parquet").exists()


def test_a_rerun_computes_nothing_and_resumes_a_partial_landscape(tmp_path, stand_in):
    out = tmp_path / "land"
    assert cli(out) == 0
    first = (out / "landscape.csv").read_bytes()
    done = calls(stand_in)
    (out / "landscape.csv").unlink()
    (out / "landscape.png").unlink()
    built = len(stand_in)
    assert cli(out) == 0
    assert (len(stand_in), calls(stand_in)) == (built, done)  # nothing built, nothing ran
    assert (out / "landscape.csv").read_bytes() == first and (out / "landscape.png").exists()
    # one setting lost: only its scenarios run again
    shutil.rmtree(out / "delay_000ms" / "q10_r1")
    fresh = len(stand_in)
    assert cli(out) == 0
    assert len(stand_in) == fresh + 1 and calls(stand_in[fresh:]) > 0
    assert stand_in[-1].config == landscape.setting_config(Config(), landscape.Delay(0), 10, 1)
    assert (out / "landscape.csv").read_bytes() == first


def test_bad_input_is_refused_before_any_work_and_nothing_is_lost(tmp_path, stand_in, capsys):
    out = tmp_path / "land"
    for flag, value, message in (
        ("--q-scales", "0,1", "must be > 0"),
        ("--r-scales", "1,x", "not a number"),
        ("--delays", "0,5x", "not a delay setting"),
        ("--delays", "0c", "needs a delay > 0"),
        ("--delays", "10,10", "given twice"),
        ("--delays", "0.3", "whole multiple of physics_dt"),
        ("--durations", "0.5,13", "t_end"),
    ):
        args = {
            "--q-scales": QS,
            "--r-scales": RS,
            "--delays": "0",
            "--forces": FORCES,
            "--durations": DURATIONS,
            flag: value,
        }
        code = main(["landscape", *[w for k, v in args.items() for w in (k, v)], "--out", str(out)])
        assert code == 2, flag
        err = capsys.readouterr().err
        assert message in err, (flag, value, err)
    assert not out.exists() and not stand_in  # nothing ran, nothing was written
    assert cli(out) == 0
    kept = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file() and p.name != ".lock"}
    done = calls(stand_in)
    # another grid, or another base configuration, over a finished landscape: refused,
    # naming the setting, before any scenario runs or any file changes
    assert (
        main(
            [
                "landscape",
                "--q-scales",
                QS,
                "--r-scales",
                RS,
                "--delays",
                "0,100c",
                "--forces",
                "0:40:20",
                "--durations",
                DURATIONS,
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "delay_000ms/q1_r0.1" in capsys.readouterr().err
    assert cli(out, "--set", "controller.horizon=10") == 2
    assert "different configuration" in capsys.readouterr().err
    assert calls(stand_in) == done
    assert {p: p.read_bytes() for p in kept} == kept


def test_delay_settings_and_names():
    delays = landscape.parse_delays("0, 10,100c,12.5ms c")
    assert [d.key for d in delays] == [
        "delay_000ms",
        "delay_010ms",
        "delay_100ms_comp",
        "delay_012.5ms_comp",
    ]
    assert [d.label for d in delays[:3]] == ["no delay", "10 ms, plain", "100 ms, compensated"]
    config = landscape.setting_config(Config(), delays[2], 0.1, 1000)
    assert config.scenario.controller_delay == 0.1 and config.controller.delay_compensation
    assert config.controller.q_diag == pytest.approx((100.0,) * 4)
    assert config.controller.r_diag == pytest.approx((100.0, 0.1))
    assert landscape.setting_name(0.001, 1000) == "q0.001_r1000"
    with pytest.raises(ParameterError, match="too close"):
        landscape.parse_scales("1,1.0000001", "Q scales")
    with pytest.raises(ParameterError, match="at least one"):
        landscape.parse_delays(" , ")


def test_paired_energy_compares_the_same_pushes():
    keys = {"force": [10.0, 20.0, 30.0], "duration": [0.1, 0.1, 0.1]}
    base = pd.DataFrame(
        {**keys, "outcome": ["recovered", "recovered", "fell"], "energy_total": [1.0, 3.0, np.nan]}
    )
    other = pd.DataFrame(
        {**keys, "outcome": ["recovered", "fell", "recovered"], "energy_total": [0.5, np.nan, 50.0]}
    )
    assert landscape.paired_energy(other, base) == (1, pytest.approx(0.5))  # the 10-N push
    none = other.assign(outcome="fell")
    n, value = landscape.paired_energy(none, base)
    assert n == 0 and math.isnan(value)


# the real rollout for every setting; the stand-in landscape tests stay in the default run
@pytest.mark.slow
def test_landscape_numbers_equal_a_direct_compare_with_the_real_rollout(
    tmp_path, batch_runner, float32
):
    """The real closed loop (the session's compiled function: a BatchRunner of scaled weights
    shares it), t_end = 2 s, 2 pushes and one table force: each setting's landscape row equals
    compare.csv's row of the same configuration written out by hand, and the two R scales give
    different numbers (the scales reach the controller)."""
    import jax

    from mjx_balance import rollout

    def make(config, **_engine):
        runner = rollout.BatchRunner(config, trajectories=True, devices=jax.local_devices()[:1])
        assert runner._shape_key(8) == batch_runner._shape_key(8)  # no compile
        return runner.run_frame

    base = batch_runner.config
    grid = {"forces": "0,60", "durations": "0.1"}
    frame = landscape.run_landscape(
        tmp_path / "land",
        base,
        **grid,
        q_scales="1",
        r_scales="0.1,1",
        delays="0",
        table_forces="60",
        make_batch=make,
        say=None,
    )
    by_hand = {"r01": base.replace(controller={"r_diag": (0.01, 1e-5)}), "r1": base}
    batches = {name: make(c) for name, c in by_hand.items()}
    direct = run_compare(
        tmp_path / "cmp",
        by_hand,
        grid["forces"],
        grid["durations"],
        "60",
        run_batches=batches,
        say=None,
    ).set_index("name")
    numbers = [
        "area",
        "recovered_cells",
        "f_max_ref",
        "mean_recovery_energy",
        "sustained_push_limit",
        "max_acting_time_60N",
    ]
    for name, r in (("r01", 0.1), ("r1", 1.0)):
        row = frame[frame["r_scale"] == r].iloc[0]
        for column in numbers:
            assert row[column] == pytest.approx(direct.loc[name, column], nan_ok=True), column
    assert frame["recovered_cells"].min() >= 1  # the unpushed body recovers
    a, b = (frame[frame["r_scale"] == r].iloc[0] for r in (0.1, 1.0))
    assert (a["sustained_push_limit"], a["mean_recovery_energy"]) != (
        b["sustained_push_limit"],
        b["mean_recovery_energy"],
    )


def test_the_report_section_is_read_from_the_folder(tmp_path, stand_in):
    from mjx_balance.report.landscape import landscape_section

    assert landscape_section(tmp_path) is None  # no landscape there
    out = tmp_path / "land"
    assert cli(out) == 0
    section = landscape_section(out)
    kinds = [b["kind"] for b in section["blocks"]]
    assert section["id"] == "landscape" and kinds[:3] == ["paragraph", "figure", "table"]
    figure = section["blocks"][1]
    assert figure["path"] == str(out / "landscape.png")  # embedded when the page is rendered
    table = section["blocks"][2]
    rows = [dict(zip(table["header"], r)) for r in table["rows"]]
    assert [r["which"] for r in rows] == [
        "base weights (1, 1)",
        "largest area",
        "largest sustained limit",
    ] * 2
    frame = pd.read_csv(out / "landscape.csv", dtype={"delay": str})
    base = frame[(frame["delay"] == "100c") & frame["study"]].iloc[0]
    assert rows[3]["delay"] == "100 ms, compensated"
    assert rows[3]["area [N s]"] == f"{base['area']:.4g}"
    assert rows[1]["Q scale"] == "10" and rows[1]["R scale"] == "0.1"  # the largest area
    text = " ".join(b["text"] for b in section["blocks"] if b["kind"] == "paragraph")
    assert (out / "landscape.txt").read_text().strip().splitlines()[0] in text
