"""Sweep engine: grids, chunking, resumable result files, batched bisection, figures, commands.

The bookkeeping is tested with FakeThresholdBatch, an analytic stand-in for the rollout (a push
recovers iff |F| * T < c). It says nothing about balance; it only makes the expected cells,
thresholds and outcomes known exactly. The last test runs the real MJX rollout (the session's
compiled runner, conftest ``batch_runner``) through the command line.

The command-line tests replace the rollout by patching ``mjx_balance.runs.batch.default_batch``,
where LazyBatch looks it up when it first runs a batch.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from margins import within
from support import (
    DEFAULT_BATCH,
    GRID,
    FakeThresholdBatch,
    expected_max_time,
    held_sweep,
    held_table,
    sweep_fake,
    tiny_config,
)

from mjx_balance import runs as sweep
from mjx_balance.measures.outcomes import SUMMARY_COLUMNS
from mjx_balance.model.config_files import load_config
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.runs.definitions import sweeps_dir
from mjx_balance.runs.grid import Grid

# --- grids -----------------------------------------------------------------------------------


def test_parse_grid_ranges_include_stop_and_are_exact():
    np.testing.assert_array_equal(sweep.parse_grid("0:1:0.1"), np.round(np.arange(11) * 0.1, 12))
    assert sweep.parse_grid("0:1:0.1")[3] == 0.3
    assert sweep.parse_grid("0:0.95:0.1")[-1] == 0.9
    durations = sweep.parse_grid("0.05:10:0.05")
    assert durations.size == 200 and durations[-1] == 10.0 and durations[0] == 0.05
    assert sweep.parse_grid("0:150:2").size == 76
    np.testing.assert_array_equal(sweep.parse_grid("-20:20:20"), [-20.0, 0.0, 20.0])
    np.testing.assert_array_equal(sweep.parse_grid("50, -10,0"), [-10.0, 0.0, 50.0])
    np.testing.assert_array_equal(sweep.parse_grid([5, 10]), [5.0, 10.0])
    np.testing.assert_array_equal(sweep.parse_grid(7), [7.0])


@pytest.mark.parametrize(
    "spec, message",
    [
        ("", "empty"),
        ("1:0:0.1", "empty"),
        ("0:1:0", "step"),
        ("0:1:-0.1", "step"),
        ("0:1", "start:stop:step"),
        ("nan,1", "finite"),
        ("0:inf:1", "finite"),
        ("1,2,1", "more than once"),
        ("a,b", "not a number"),
        ([], "empty"),
    ],
)
def test_parse_grid_errors(spec, message):
    with pytest.raises(ParameterError, match=message):
        sweep.parse_grid(spec, "forces")


def test_duration_limits():
    with pytest.raises(ParameterError, match=">= 0"):
        sweep.check_durations(sweep.parse_grid("-0.1,0.1"), 12.0)
    with pytest.raises(ParameterError, match="t_end"):
        sweep.check_durations(sweep.parse_grid("0.1,12.5"), 12.0)
    sweep.check_durations(sweep.parse_grid("0:12:0.1"), 12.0)  # t_end itself is allowed


def test_bad_grid_fails_before_any_work(tmp_path):
    fake = FakeThresholdBatch()
    with pytest.raises(ParameterError, match="t_end"):
        held_sweep(
            tmp_path / "out",
            tiny_config(),
            Grid.of("0:10:5", "0.5,3", tiny_config()),
            run_batch=fake,
            progress=False,
            say=None,
        )
    assert fake.calls == [] and not (tmp_path / "out").exists()


# --- chunking --------------------------------------------------------------------------------


@pytest.mark.parametrize("n, size", [(1, 1), (10, 3), (160, 64), (256, 256), (257, 256)])
def test_chunks_cover_every_cell_once(n, size):
    covered = np.concatenate([np.arange(n)[s] for s in sweep.chunk_slices(n, size)])
    np.testing.assert_array_equal(covered, np.arange(n))


def test_memory_budget_and_chunk_size():
    config = Config()
    assert 10_000 < sweep.scenario_bytes(config) < 10_000_000
    assert 1 <= sweep.default_chunk_size(config, 5000) <= 5000


# --- resumable sweep -------------------------------------------------------------------------


def test_sweep_every_cell_once_with_known_outcomes(tmp_path):
    fake = FakeThresholdBatch()
    result = sweep_fake(tmp_path, fake)
    region = pd.read_parquet(tmp_path / "region.parquet")
    assert list(region.columns[: len(SUMMARY_COLUMNS)]) == SUMMARY_COLUMNS
    assert len(region) == 35 and not region.duplicated(["force", "duration"]).any()
    assert fake.calls == [8] * 5  # every call padded to the chunk size
    expected = np.where(
        fake.recovered(region["force"].to_numpy(), region["duration"].to_numpy()),
        "recovered",
        "fell",
    )
    np.testing.assert_array_equal(region["outcome"].to_numpy(), expected)
    assert set(region["duration"]) == {0.1, 0.5, 1.0, 1.5, 2.0}  # exact values, not float32
    assert (region["convention"] == "paper").all()
    assert result.computed_chunks == 5 and not result.already_complete
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["version"] and manifest["region"]["cells"] == 35
    assert (tmp_path / "config.toml").exists()


def test_interrupted_sweep_resumes_to_the_same_region(tmp_path):
    sweep_fake(tmp_path / "whole", FakeThresholdBatch())
    with pytest.raises(KeyboardInterrupt):
        sweep_fake(tmp_path / "cut", FakeThresholdBatch(fail_on_call=3))
    assert len(list((tmp_path / "cut" / "chunks").glob("chunk-*.parquet"))) == 2
    assert not list((tmp_path / "cut" / "chunks").glob("*.tmp"))
    assert not (tmp_path / "cut" / "region.parquet").exists()
    resumed = FakeThresholdBatch()
    result = sweep_fake(tmp_path / "cut", resumed)
    assert resumed.calls == [8] * 3 and result.reused_chunks == 2
    pd.testing.assert_frame_equal(
        pd.read_parquet(tmp_path / "cut" / "region.parquet"),
        pd.read_parquet(tmp_path / "whole" / "region.parquet"),
    )


def test_finished_sweep_rerun_does_nothing(tmp_path, capsys):
    sweep_fake(tmp_path, FakeThresholdBatch())
    idle = FakeThresholdBatch(fail_on_call=1)
    result = held_sweep(
        tmp_path, tiny_config(), Grid.of(*GRID, tiny_config()), run_batch=idle, progress=False
    )
    assert result.already_complete and idle.calls == []
    assert "nothing to do" in capsys.readouterr().out


@pytest.mark.parametrize("damage", ["garbage", "truncated", "other_cells"])
def test_damaged_chunk_is_recomputed_not_merged(tmp_path, damage):
    sweep_fake(tmp_path, FakeThresholdBatch())
    good = pd.read_parquet(tmp_path / "region.parquet")
    (tmp_path / "region.parquet").unlink()
    chunk = tmp_path / "chunks" / "chunk-00002.parquet"
    if damage == "garbage":
        chunk.write_bytes(b"PAR1 not really parquet")
    elif damage == "truncated":
        pd.read_parquet(chunk).iloc[:5].to_parquet(chunk)
    else:
        frame = pd.read_parquet(chunk)
        frame["duration"] = frame["duration"] + 0.01
        frame.to_parquet(chunk)
    fake = FakeThresholdBatch()
    result = sweep_fake(tmp_path, fake)
    assert fake.calls == [8] and result.recomputed_chunks == 1
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "region.parquet"), good)


def test_damaged_region_file_is_rebuilt_from_chunks(tmp_path):
    sweep_fake(tmp_path, FakeThresholdBatch())
    good = pd.read_parquet(tmp_path / "region.parquet")
    (tmp_path / "region.parquet").write_bytes(b"broken")
    idle = FakeThresholdBatch(fail_on_call=1)
    sweep_fake(tmp_path, idle)
    assert idle.calls == []
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "region.parquet"), good)


def test_a_folder_without_results_is_not_locked_to_its_configuration(tmp_path):
    """A run that failed before its first chunk (a bad value found late) leaves a
    manifest but no results; the corrected configuration takes the folder over. Once the
    folder holds results, another configuration is refused again."""
    from mjx_balance.store.folder import OutputFolder, folder_lock

    bad = tiny_config().replace(controller={"horizon": 10})
    with folder_lock(tmp_path):
        OutputFolder(tmp_path, bad).open()  # what the failed run left
    assert (tmp_path / "manifest.json").exists() and not (tmp_path / "chunks").exists()
    sweep_fake(tmp_path, FakeThresholdBatch())  # the corrected configuration
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["config"]["controller"]["horizon"] == tiny_config().controller.horizon
    with pytest.raises(ParameterError, match="different configuration"):
        sweep_fake(tmp_path, FakeThresholdBatch(), config=bad)


def test_other_configuration_or_grid_is_refused(tmp_path):
    sweep_fake(tmp_path, FakeThresholdBatch())
    other = tiny_config().replace(controller={"horizon": 10})
    with pytest.raises(ParameterError, match="different configuration.*controller.horizon"):
        sweep_fake(tmp_path, FakeThresholdBatch(), config=other)
    with pytest.raises(ParameterError, match="another grid"):
        held_sweep(
            tmp_path,
            tiny_config(),
            Grid.of("0:100:20", GRID[1], tiny_config()),
            run_batch=FakeThresholdBatch(),
            progress=False,
            say=None,
        )


def test_resume_keeps_the_folders_chunk_size(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        sweep_fake(tmp_path, FakeThresholdBatch(fail_on_call=2))
    fake = FakeThresholdBatch()
    sweep_fake(tmp_path, fake, chunk=100)
    assert fake.calls == [8] * 4


# --- max acting time -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "c, limit, note",
    [
        (30.0, 2.4, ""),
        (0.5, 0.0, ""),
        (0.0, 0.0, "the body falls at 0 N"),
        (1e5, 200.0, "holds every force tried"),
    ],
)
def test_sustained_push_limit_finds_the_fake_threshold_to_0_1_n(c, limit, note):
    """Held for the whole 12-s window iff 12 F < c: the largest such multiple of 0.1 N."""
    fake = FakeThresholdBatch(c=c)
    found, said, runs = sweep.acting_time.sustained_push_limit(Config(), fake)
    assert found == limit and note in said
    assert (runs["duration"] == 12.0).all() and len(fake.calls) <= 4


def test_bisection_finds_the_fake_threshold_to_0_01_s():
    config = Config()  # t_end = 12 s
    forces = [1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 120, 4000]
    fake = FakeThresholdBatch(c=30.0)
    result = sweep.max_acting_time(forces, config, run_batch=fake, progress=False, say=None)
    table = result.table.set_index("force")
    for force in forces:
        within(
            table.loc[force, "max_acting_time"],
            expected_max_time(force, 30.0, 12.0),
            atol=1e-9,
            msg=force,
            why="whole steps of 0.01 s, rounded to 12 decimals (np.round) on both sides",
        )
    assert table["monotone"].all()
    # Every call after the coarse scan is one batch of one midpoint per force.
    n_coarse = sweep.coarse_steps(12.0, 0.01).size
    assert fake.calls[0] == len(forces) * n_coarse
    assert all(n == len(forces) for n in fake.calls[1:])
    assert len(fake.calls) - 1 <= math.ceil(math.log2(400)) + 1
    # Recovers up to t_end; fails at the shortest push; an ordinary force.
    assert table.loc[1, "max_acting_time"] == 12.0 and table.loc[1, "ending_outcome"] == ""
    assert "up to t_end" in table.loc[1, "note"]
    assert table.loc[4000, "max_acting_time"] == 0.0 and "shortest push" in table.loc[4000, "note"]
    assert math.isnan(table.loc[4000, "energy_total_max"])
    row = table.loc[20]  # 20 N: 20 T < 30 -> T <= 1.49
    assert row["max_acting_time"] == 1.49 and row["ending_outcome"] == "fell"
    within(
        row["energy_total_01"],
        3 * 20 * 0.1,
        rtol=1e-6,
        why="the stand-in computes 3 |F| T from float32 F and T: three roundings, <= 1.8e-7",
    )
    within(
        row["energy_total_max"],
        3 * 20 * 1.49,
        rtol=1e-6,
        why="the stand-in computes 3 |F| T from float32 F and T: three roundings, <= 1.8e-7",
    )
    assert row["outcome_01"] == "recovered"
    assert list(result.table.columns) == sweep.TABLE_COLUMNS
    assert len(result.runs) == result.table["evaluations"].sum()  # padding dropped


@pytest.mark.parametrize("k", [2, 3, 7])
def test_k_section_finds_the_same_thresholds(k):
    forces = [1, 5, 20, 50, 120, 4000]
    fake = FakeThresholdBatch(c=30.0)
    result = sweep.max_acting_time(
        forces, Config(), run_batch=fake, points_per_round=k, progress=False, say=None
    )
    expected = [expected_max_time(f, 30.0, 12.0) for f in forces]
    np.testing.assert_allclose(result.table["max_acting_time"], expected, atol=1e-9)
    assert all(n == len(forces) * k for n in fake.calls[1:])


@pytest.mark.parametrize("batch", [8, 32, 64])
def test_table_in_batches_of_one_size(batch):
    forces = [1, 5, 20, 50, 120, 4000]
    fake = FakeThresholdBatch(c=30.0)
    result = sweep.max_acting_time(
        forces, Config(), run_batch=fake, batch=batch, progress=False, say=None
    )
    expected = [expected_max_time(f, 30.0, 12.0) for f in forces]
    np.testing.assert_allclose(result.table["max_acting_time"], expected, atol=1e-9)
    assert set(fake.calls) == {batch}


def test_power_of_two_chunks():
    assert sweep.power_of_two_chunk(160, 256) == 64  # 3 x 64: least padding of sizes >= 64
    assert sweep.power_of_two_chunk(312, 128) == 64  # 5 x 64 = 320 rather than 3 x 128 = 384
    assert sweep.power_of_two_chunk(160, 256, minimum=8) == 32
    assert sweep.power_of_two_chunk(256, 256) == 256
    assert sweep.power_of_two_chunk(5000, 256) == 256
    assert sweep.power_of_two_chunk(3, 256) == 8
    assert sweep.power_of_two_chunk(20, 256) == 32
    assert sweep.power_of_two_chunk(15200, 16384) == 16384  # 1 x 16384 <= 1.1 x 15200
    # no size >= 64 within 10 % waste up to 2048 (5 x 2048 = 10240 > 9900): 9 x 1024 = 9216
    assert sweep.power_of_two_chunk(9000, 16384) == 1024


def test_bisection_flags_a_non_monotone_force():
    fake = FakeThresholdBatch(c=30.0, window=(3.5, 4.5))  # fails from 1.5 s, recovers again at 4 s
    result = sweep.max_acting_time([20, 5], Config(), run_batch=fake, progress=False, say=None)
    table = result.table.set_index("force")
    assert not table.loc[20, "monotone"]
    assert table.loc[20, "recovered_beyond_failure"] == 4.0
    assert table.loc[20, "max_acting_time"] == 1.49
    assert "not monotone" in table.loc[20, "note"]
    assert table.loc[5, "monotone"] and math.isnan(table.loc[5, "recovered_beyond_failure"])


def test_negative_forces_in_the_table():
    result = sweep.max_acting_time(
        [-20, 20], Config(), run_batch=FakeThresholdBatch(), progress=False, say=None
    )
    assert list(result.table["max_acting_time"]) == [1.49, 1.49]


def test_run_table_writes_and_skips_when_done(tmp_path, capsys):
    fake = FakeThresholdBatch()
    held_table(tmp_path, Config(), "20,50", run_batch=fake, progress=False)
    table = pd.read_csv(tmp_path / "table.csv")
    assert list(table["max_acting_time"]) == [1.49, 0.59]
    assert list(table["sustained_push_limit"]) == [2.4, 2.4]  # 12 F < 30 N s
    runs = pd.read_parquet(tmp_path / "table_runs.parquet")
    assert (runs["duration"] == 12.0).any()  # the sustained-push scenarios are kept too
    idle = FakeThresholdBatch(fail_on_call=1)
    assert held_table(tmp_path, Config(), "20,50", run_batch=idle, progress=False) is None
    assert "nothing to do" in capsys.readouterr().out


# --- sweep definitions, figures, commands ----------------------------------------------------


def test_sweep_definitions_load_and_default_matches_builtin():
    for path in sorted(sweeps_dir().glob("*.toml")):
        definition = sweep.load_sweep(path, Config())
        if "[sweep]" not in path.read_text(encoding="utf-8"):
            # a shipped configuration (the human bodies): a plain --config loads it too
            assert load_config(path) == definition.config, path
            continue
        assert definition.forces is not None or definition.table_forces is not None, path
        for grid in (definition.forces, definition.table_forces):
            if grid is not None:
                sweep.parse_grid(grid)
        if definition.durations is not None:
            sweep.check_durations(
                sweep.parse_grid(definition.durations), definition.config.scenario.t_end
            )
    default = sweep.load_sweep(sweeps_dir() / "default.toml", Config())
    assert (default.forces, default.durations, default.table_forces, default.chunk) == (
        sweep.DEFAULT_SWEEP["forces"],
        sweep.DEFAULT_SWEEP["durations"],
        sweep.DEFAULT_SWEEP["table_forces"],
        sweep.DEFAULT_SWEEP["chunk"],
    )
    joint = sweep.load_sweep(sweeps_dir() / "study_table_joint.toml", Config())
    assert joint.config.controller.convention == "joint"


def test_sweep_definition_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[sweep]\nforce = "0:10:1"\n')
    with pytest.raises(ParameterError, match="unknown key"):
        sweep.load_sweep(bad, Config())
    bad.write_text("[controller]\nhorizont = 3\n")
    with pytest.raises(ParameterError, match="horizont"):
        sweep.load_sweep(bad, Config())


def test_figures_from_fake_results(tmp_path):
    from mjx_balance.figures import region as region_plots

    held_sweep(
        tmp_path,
        Config(),
        Grid.of("-20:120:10", "0.05:2:0.05", Config()),
        run_batch=FakeThresholdBatch(window=(1.5, 1.6)),
        progress=False,
        say=None,
    )
    region = pd.read_parquet(tmp_path / "region.parquet")
    reference = pd.DataFrame({"force": [20, 50], "duration": [1.4, 0.55]})
    for name, plot, kwargs in (
        ("region.png", region_plots.plot_region, {"reference": reference}),
        ("energy.png", region_plots.plot_energy, {}),
    ):
        plot(region, tmp_path / name, config=Config(), **kwargs)
        assert (tmp_path / name).stat().st_size > 10_000
    boundary = region_plots.recovery_boundary(region).set_index("force")
    assert boundary.loc[30, "boundary"] == 0.95 and not boundary.loc[30, "monotone"]
    assert boundary.loc[10, "boundary"] == 2.0 and boundary.loc[10, "monotone"]
    result = sweep.max_acting_time(
        [1, 5, 20, 50, 120, 4000],
        Config(),
        run_batch=FakeThresholdBatch(),
        progress=False,
        say=None,
    )
    region_plots.plot_table(result.table, tmp_path / "table.png", config=Config())
    assert (tmp_path / "table.png").stat().st_size > 10_000


def test_default_sweep_command_writes_region_and_table(tmp_path, monkeypatch):
    from mjx_balance.cli import main

    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **engine: FakeThresholdBatch())
    out = tmp_path / "default"
    assert main(["sweep", "--out", str(out)]) == 0
    for name in (
        "region.parquet",
        "region.png",
        "energy.png",
        "table.csv",
        "table.png",
        "manifest.json",
        "config.toml",
    ):
        assert (out / name).exists(), name
    region = pd.read_parquet(out / "region.parquet")
    assert len(region) == (
        sweep.parse_grid(sweep.DEFAULT_SWEEP["forces"]).size
        * sweep.parse_grid(sweep.DEFAULT_SWEEP["durations"]).size
    )
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **engine: FakeThresholdBatch(fail_on_call=1))
    assert main(["sweep", "--out", str(out)]) == 0  # finished: nothing to do, no batch called
    assert main(["sweep", "--out", str(out), "--convention", "joint"]) == 2  # other configuration
    assert (
        main(
            ["sweep", "--forces", "0:10:5", "--durations", "0.1,20", "--out", str(tmp_path / "bad")]
        )
        == 2
    )
    assert not (tmp_path / "bad").exists()


def test_cli_overrides_sweep_file(tmp_path, monkeypatch):
    from mjx_balance.cli import main

    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **engine: FakeThresholdBatch())
    definition = tmp_path / "s.toml"
    definition.write_text(
        '[scenario]\nt_end = 3.0\n[controller]\nconvention = "joint"\n'
        '[sweep]\nforces = "0:40:20"\ndurations = [0.5, 1.0]\n'
        "table_forces = [10]\n"
    )
    out = tmp_path / "o"
    assert main(["table", "--sweep", str(definition), "--forces", "20,40", "--out", str(out)]) == 0
    table = pd.read_csv(out / "table.csv")
    assert list(table["force"]) == [20, 40] and (table["convention"] == "joint").all()
    assert json.loads((out / "manifest.json").read_text())["config"]["scenario"]["t_end"] == 3.0
    points = tmp_path / "points.csv"
    points.write_text("force,duration\n20,0.25\n")
    assert (
        main(
            [
                "sweep",
                "--sweep",
                str(definition),
                "--durations",
                "0.25",
                "--out",
                str(tmp_path / "o2"),
                "--convention",
                "paper",
                "--reference",
                str(points),
            ]
        )
        == 0
    )
    region = pd.read_parquet(tmp_path / "o2" / "region.parquet")
    assert list(region["duration"].unique()) == [0.25] and (region["convention"] == "paper").all()
    assert (tmp_path / "o2" / "table.csv").exists()  # the sweep file's table_forces


def test_set_is_checked_on_top_of_the_sweep_file(tmp_path, monkeypatch):
    """--set goes on top of the --sweep file, and is checked there: a value that is only valid
    together with the file's (a delay error of -20 ms needs the file's 100-ms delay) is taken."""
    from mjx_balance.cli import main

    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **engine: FakeThresholdBatch())
    definition = tmp_path / "s.toml"
    definition.write_text(
        "[scenario]\nt_end = 1.0\ncontroller_delay = 0.1\n"
        '[sweep]\nforces = "0,20"\ndurations = [0.5]\n'
    )
    for command in ("sweep", "table"):
        out = tmp_path / command
        assert (
            main(
                [
                    command,
                    "--sweep",
                    str(definition),
                    "--set",
                    "scenario.delay_error=-0.02",
                    "--forces",
                    "0,20",
                    "--out",
                    str(out),
                ]
            )
            == 0
        )
        saved = json.loads((out / "manifest.json").read_text())["config"]["scenario"]
        assert (saved["controller_delay"], saved["delay_error"]) == (0.1, -0.02)


# --- end to end with the real rollout --------------------------------------------------------


def test_cli_end_to_end_with_the_mjx_rollout(tmp_path, monkeypatch, batch_runner, float32):
    """The real BatchRunner through the command line on the session's configuration (defaults,
    t_end = 2 s): a 2 x 2 region and a 2-force table, all in batches of 8 (the compiled size).

    The sweep gets the session's compiled runner (a sweep's own BatchRunner would compile the
    same closed loop again, without trajectories); the stand-in checks that the command asks for
    exactly its configuration."""
    from mjx_balance.cli import main

    t_end = batch_runner.config.scenario.t_end
    asked = []

    def shared_batch(config, **engine):
        asked.append(config)
        assert config == batch_runner.config
        return batch_runner.run_frame

    monkeypatch.setattr(DEFAULT_BATCH, shared_batch)
    definition = tmp_path / "tiny.toml"
    definition.write_text(
        f'[scenario]\nt_end = {t_end}\n[sweep]\nforces = "0,300"\n'
        "durations = [0.1, 0.3]\ntable_forces = [0, 300]\n"
    )
    out = tmp_path / "e2e"
    assert main(["sweep", "--sweep", str(definition), "--out", str(out)]) == 0
    assert len(asked) == 1  # one rollout for the region and the table
    region = pd.read_parquet(out / "region.parquet").set_index(["force", "duration"])
    assert len(region) == 4
    # no push stays upright; 300 N at the upper body's CoM tips the body over within 0.3 s
    # (measured: 0.25 s after a 0.1-s push, 0.19 s into a 0.3-s push)
    assert list(region.loc[0.0, "outcome"]) == ["recovered", "recovered"]
    assert list(region.loc[300.0, "outcome"]) == ["fell", "fell"]
    fall_short, fall_long = region.loc[300.0, "fall_time"]
    assert fall_long < 0.3 and fall_long < fall_short < 0.3
    assert json.loads((out / "manifest.json").read_text())["region"]["chunk_size"] == 8
    table = pd.read_csv(out / "table.csv").set_index("force")
    assert table.loc[0, "max_acting_time"] == t_end  # no force: recovers up to t_end
    assert table.loc[0, "outcome_01"] == "recovered"
    assert table.loc[300, "outcome_01"] == "fell"  # as in the region
    # 300 N: the bisection ends where a direct run of 0.01..0.08-s pushes first fails to recover
    # (measured: 0.01 s recovers, 0.02 s is not settled by 2 s, 0.03 s and longer fall)
    durations = np.round(np.arange(1, 9) * 0.01, 12)
    direct = batch_runner.run_frame(np.full(8, 300.0), durations)
    first_failure = int(np.flatnonzero(direct["outcome"] != "recovered")[0])
    within(
        table.loc[300, "max_acting_time"],
        durations[first_failure - 1] if first_failure else 0.0,
        atol=1e-9,
        why="whole steps of 0.01 s, rounded to 12 decimals (np.round) on both sides",
    )
    assert table.loc[300, "ending_outcome"] == direct["outcome"][first_failure]
    for name in ("region.png", "energy.png", "table.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, name


def test_the_table_bisects_the_one_step_limit_too():
    """max_acting_time_one_step (capturability): the largest T whose pushes up to it all
    recover in place or with one step, by the same bisection; the cells the in-place rounds ran
    are read back, not run again (a fake where one step saves every fall below F T = 60)."""
    forces = [1, 5, 20, 50, 120]
    fake = FakeThresholdBatch(c=30.0, one_step=60.0)
    table = sweep.max_acting_time(forces, Config(), run_batch=fake, progress=False, say=None)
    table = table.table.set_index("force")
    for force in forces:
        assert table.loc[force, "max_acting_time"] == expected_max_time(force, 30.0, 12.0)
        assert table.loc[force, "max_acting_time_one_step"] == expected_max_time(
            force, 60.0, 12.0
        ), force
    # every cell is run once: the one-step rounds read the in-place rounds' cells back
    assert sum(len(c) for c in fake.cells) == len(fake.all_cells())
    plain = FakeThresholdBatch(c=30.0)  # no fall is saved by a step: no call beyond those
    sweep.max_acting_time(forces, Config(), run_batch=plain, progress=False, say=None)
    assert sum(len(c) for c in plain.cells) == len(plain.all_cells())
    assert (table["max_acting_time_one_step"] >= table["max_acting_time"]).all()
