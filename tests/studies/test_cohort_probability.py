"""A cohort's probability map (``studies.probability``, cohort_probability.csv,
cohort_probability_boundaries.csv, cohort_probability.png): Wilson's interval against published
values, the worst-case width rule, P per cell as the count over the subjects' maps, the
boundaries on hand-made maps, and the files a cohort and the command write.

No test here runs the engine: the maps are written by hand or by the stand-in batch
(``support.FakeThresholdBatch``: recovered iff |F| T < c, with c the configuration's ankle
torque bound, so heavier subjects recover more cells)."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pandas as pd
import pytest
from support import DEFAULT_BATCH, FakeThresholdBatch

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.figures.region import recovery_boundary
from mjx_balance.measures import units
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.store.files import readable_png
from mjx_balance.studies import cohort, probability
from mjx_balance.studies import members as cohort_members

FORCES, DURATIONS = "0:40:10", "0.5,1,2"
BASE = Config().replace(scenario={"t_end": 2.0})
TABLE_DIGITS = 0.5e-4  # published limits are rounded to 4 decimals: within half a unit of it


def threshold(config: Config) -> float:
    return float(config.controller.input1_bounds[1])


def stand_ins(config: Config) -> FakeThresholdBatch:
    return FakeThresholdBatch(c=threshold(config))


def region(forces, durations, recovered) -> pd.DataFrame:
    """A hand-made region map: ``recovered[i][j]`` for force i and duration j (else fell)."""
    f, d = np.meshgrid(forces, durations, indexing="ij")
    ok = np.asarray(recovered, dtype=bool)
    return pd.DataFrame(
        {
            "force": f.ravel().astype(float),
            "duration": d.ravel().astype(float),
            "outcome": np.where(ok.ravel(), "recovered", "fell"),
        }
    )


# --- the interval ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "k, n, low, high",
    [
        # Newcombe (1998), Statistics in Medicine 17:857-872, Table II, method 3 (score, no
        # continuity correction)
        (81, 263, 0.2553, 0.3662),
        (15, 148, 0.0624, 0.1605),
        (0, 20, 0.0, 0.1611),
        (1, 29, 0.0061, 0.1718),
        # the closed forms at 0/n, n/n and n/2 (z = 1.959964): z^2 / (n + z^2) = 0.2775 for n = 10,
        # and 1/2 -+ z / (2 sqrt(n + z^2)) = 0.5 -+ 0.2634
        (0, 10, 0.0, 0.2775),
        (10, 10, 0.7225, 1.0),
        (5, 10, 0.2366, 0.7634),
    ],
)
def test_the_wilson_interval_gives_the_published_limits(k, n, low, high):
    lo, hi = probability.wilson(k, n)
    assert float(lo) == pytest.approx(low, abs=TABLE_DIGITS)
    assert float(hi) == pytest.approx(high, abs=TABLE_DIGITS)


def test_the_wilson_interval_is_elementwise_and_refuses_impossible_counts():
    lo, hi = probability.wilson(np.array([0, 3, 7]), np.array([7, 7, 7]))
    assert lo[0] == 0.0 and hi[2] == 1.0  # exactly, not 1e-17 off
    assert np.all(lo <= np.array([0, 3, 7]) / 7) and np.all(np.array([0, 3, 7]) / 7 <= hi)
    for k, n in [(3, 2), (-1, 5), (0, 0)]:
        with pytest.raises(ValueError, match="0 <= recovered <= n"):
            probability.wilson(k, n)


def test_the_worst_half_width_and_the_subjects_a_width_needs():
    # the closed form is the interval's own half-width at k = n / 2
    for n in (2, 10, 380, 382):
        lo, hi = probability.wilson(n // 2, n)
        assert probability.half_width(n) == pytest.approx((hi - lo) / 2, rel=1e-12)
    # and no count gives a wider interval
    for n in (7, 10, 51):
        lo, hi = probability.wilson(np.arange(n + 1), n)
        assert ((hi - lo) / 2).max() <= probability.half_width(n) * (1 + 1e-12)
    # the smallest n whose half-width at P = 1/2 is within the width, found by scanning the
    # interval itself (k = n / 2 as a real count, so odd n are scanned too)
    for width, expected in [(0.10, 93), (0.05, 381)]:
        scanned = next(
            n
            for n in range(1, 2000)
            if np.subtract(*probability.wilson(n / 2, n)[::-1]) / 2 <= width
        )
        assert probability.subjects_for(width) == scanned == expected
    assert "±22.0 %" in probability.interval_text(16)  # 1.96 / (2 sqrt(16 + 1.96^2)) = 0.2200
    assert "±10 % needs 93, ±5 % needs 381" in probability.interval_text(16)
    with pytest.raises(ValueError, match="width = 0.5"):
        probability.subjects_for(0.5)
    with pytest.raises(ValueError, match="n = 0"):
        probability.half_width(0)


# --- P per cell and the boundaries -----------------------------------------------------------


def test_p_per_cell_is_the_count_over_the_subjects_maps():
    forces, durations = [0, 10, 20], [0.1, 0.2]
    maps = {
        "a": region(forces, durations, [[1, 1], [1, 0], [0, 0]]),
        "b": region(forces, durations, [[1, 1], [1, 1], [1, 0]]),
        "c": region(forces, durations, [[1, 0], [0, 0], [0, 0]]),
    }
    maps["c"].loc[1, "outcome"] = "not_settled"  # counts as not recovered, as on a map
    maps["b"] = maps["b"].iloc[::-1]  # the rows' order does not matter
    cells = probability.cells(maps)
    assert list(cells.columns) == probability.CELL_COLUMNS
    assert cells[["force", "duration"]].to_numpy().tolist() == [
        [f, d] for f in forces for d in durations
    ]
    expected = [3, 2, 2, 1, 1, 0]  # counted by hand from the three maps above
    assert cells["recovered_subjects"].tolist() == expected
    assert cells["subjects"].tolist() == [3] * 6
    assert cells["p_recover"].tolist() == [k / 3 for k in expected]
    lo, hi = probability.wilson(np.array(expected), 3)
    assert cells["p_low"].tolist() == lo.tolist() and cells["p_high"].tolist() == hi.tolist()
    # a cell one map lacks is counted over the maps that hold it
    partial = probability.cells({**maps, "c": maps["c"].iloc[1:]})
    first = partial.iloc[0]
    assert (first["subjects"], first["recovered_subjects"]) == (2, 2)


def test_p_with_one_step_counts_the_falls_one_step_saves():
    """With every map's steps_needed, the one-step columns count the subjects that recover in
    place or need at most one step (counted by hand); a map without the column leaves them
    out. Added one map at a time (Tally, what a cohort does) or all at once, the same frame."""
    forces, durations = [0, 10], [0.1, 0.2]
    a = region(forces, durations, [[1, 1], [0, 0]])
    b = region(forces, durations, [[1, 0], [0, 0]])
    a["steps_needed"] = [0.0, 0.0, 1.0, 2.0]  # its falls: one step saves the first
    b["steps_needed"] = [0.0, 1.0, np.inf, 1.0]  # (inf: no step count saves it)
    cells = probability.cells({"a": a, "b": b})
    assert list(cells.columns) == probability.CELL_COLUMNS + probability.STEP_CELL_COLUMNS
    assert cells["recovered_subjects"].tolist() == [2, 1, 0, 0]
    assert cells["one_step_subjects"].tolist() == [2, 2, 1, 1]  # by hand from the above
    assert cells["one_step_subjects"].dtype == cells["subjects"].dtype == np.int64
    lo, hi = probability.wilson(np.array([2, 2, 1, 1]), 2)
    assert cells["p_one_step_low"].tolist() == lo.tolist()
    assert cells["p_one_step_high"].tolist() == hi.tolist()
    tally = probability.Tally()
    for one in (b, a):
        tally.add(one)
    pd.testing.assert_frame_equal(tally.cells(), cells, check_exact=True)
    without = probability.cells({"a": a, "b": b.drop(columns="steps_needed")})
    assert list(without.columns) == probability.CELL_COLUMNS
    pd.testing.assert_frame_equal(without, cells[probability.CELL_COLUMNS], check_exact=True)
    with pytest.raises(ParameterError, match="at least one"):
        probability.Tally().cells()


def cells_of(counts: dict[tuple[float, float], int], n: int) -> pd.DataFrame:
    """A probability map from recovered counts per (force, duration) over n subjects."""
    frame = pd.DataFrame(
        [
            {"force": f, "duration": d, "subjects": n, "recovered_subjects": k}
            for (f, d), k in counts.items()
        ]
    )
    frame["p_recover"] = frame["recovered_subjects"] / n
    return frame


def test_the_boundaries_of_a_hand_made_map():
    durations = [0.1, 0.2, 0.3, 0.5]
    counts = {  # recovered subjects of 20, per force over the durations
        0.0: [20, 20, 20, 20],  # every level: the longest duration
        10.0: [20, 19, 12, 1],  # 19/20 is exactly 0.95: at the 95 % level
        20.0: [18, 10, 0, 0],  # 18/20 = 0.9: not 95 %; 10/20 is 50 %
        30.0: [1, 0, 20, 20],  # recovers again beyond a gap: the boundary stops at the gap
        40.0: [0, 0, 0, 0],  # no level: 0
    }
    cells = cells_of({(f, d): k for f, row in counts.items() for d, k in zip(durations, row)}, 20)
    base = region(
        list(counts),
        durations,
        [[1, 1, 1, 1], [1, 1, 0, 0], [1, 0, 0, 0], [0, 1, 1, 1], [0, 0, 0, 0]],
    )
    found = probability.boundaries(cells, base).set_index("force")
    assert list(found.columns) == ["boundary_p95", "boundary_p50", "boundary_p5", "boundary_base"]
    expected = {
        0.0: [0.5, 0.5, 0.5, 0.5],
        10.0: [0.2, 0.3, 0.5, 0.2],
        20.0: [0.0, 0.2, 0.2, 0.1],
        30.0: [0.0, 0.0, 0.1, 0.0],
        40.0: [0.0, 0.0, 0.0, 0.0],
    }
    for force, row in expected.items():
        assert found.loc[force].tolist() == row, force
    assert probability.boundaries(cells).columns.tolist()[-1] == "boundary_p5"  # no base


def test_one_subjects_boundaries_are_its_own():
    """With one subject P is 0 or 1: every level's boundary is the subject's own recovery
    boundary on the grid (the one its region figure draws)."""
    one = region([0, 10, 20, 30], [0.1, 0.2, 0.4], [[1, 1, 1], [1, 1, 0], [1, 0, 1], [0, 0, 0]])
    found = probability.boundaries(probability.cells({"s01": one}))
    own = recovery_boundary(one)["boundary"].tolist()
    for percent in probability.LEVELS:
        assert found[f"boundary_p{percent}"].tolist() == own


# --- the cohort's files ----------------------------------------------------------------------


def test_the_cohort_writes_the_probability_map_and_its_figure(tmp_path):
    out = tmp_path / "out"
    members = cohort_members.subject_grid([1.6, 1.8], [50, 70, 95])
    said: list[str] = []
    frame = cohort.run_cohort(
        out, members, BASE, FORCES, DURATIONS, run_batches=stand_ins, say=said.append
    )
    written = pd.read_csv(out / "cohort_probability.csv")
    maps = {m.id: pd.read_parquet(out / "subjects" / m.id / "region.parquet") for m in members}
    for cell in written.itertuples():  # each cell counted again from the subjects' folders
        outcomes = [
            m.loc[(m["force"] == cell.force) & (m["duration"] == cell.duration), "outcome"].item()
            for m in maps.values()
        ]
        assert cell.subjects == len(members)
        assert cell.recovered_subjects == outcomes.count("recovered")
        assert cell.p_recover == cell.recovered_subjects / len(members)
    assert 0 < written["p_recover"].mean() < 1 and written["p_recover"].nunique() > 2
    pd.testing.assert_frame_equal(written, frame.attrs["probability"], check_dtype=False)
    # the base map is the base configuration's own, and its boundary is in the boundaries
    base = pd.read_parquet(out / "base" / "region.parquet")
    ok = base["force"] * base["duration"] < threshold(BASE)
    assert (base["outcome"] == "recovered").tolist() == ok.tolist()
    lines = pd.read_csv(out / "cohort_probability_boundaries.csv")
    pd.testing.assert_frame_equal(lines, frame.attrs["probability_boundaries"], check_dtype=False)
    assert lines["boundary_base"].tolist() == recovery_boundary(base)["boundary"].tolist()
    assert (lines["boundary_p95"] <= lines["boundary_p50"]).all()
    assert (lines["boundary_p50"] <= lines["boundary_p5"]).all()
    assert (lines["boundary_p95"] < lines["boundary_p5"]).any()  # the subjects differ
    assert frame.attrs["half_width"] == probability.half_width(6)
    assert any(probability.interval_text(6) in line for line in said)
    for name in ("cohort_probability.csv", "cohort_probability_boundaries.csv"):
        columns = pd.read_csv(out / name).columns
        assert units.unknown(columns) == []
        sidecar = pd.read_csv(out / name.replace(".csv", ".units.csv"), keep_default_na=False)
        assert list(sidecar["column"]) == list(columns)
    assert units.unit("p_recover") == "1" and units.unit("boundary_p50") == "s"
    assert readable_png(out / "cohort_probability.png")


def test_the_command_writes_the_probability_map_and_plans_its_width(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_engine: stand_ins(config))
    out = tmp_path / "out"
    assert (
        main(
            [
                "cohort",
                "--population",
                "2",
                "--seed",
                "2",
                "--forces",
                FORCES,
                "--durations",
                DURATIONS,
                "--set",
                "scenario.t_end=2",
                "--format",
                "parquet",
                "--queue",
                "each",
                "--out",
                str(out),
            ]
        )
        == 0
    )  # each: the fake rollout
    printed = capsys.readouterr().out
    planned = next(line for line in printed.splitlines() if line.startswith("planned work"))
    assert planned.startswith("planned work: 45 cells")  # 2 subjects and the base, 15 each
    assert probability.interval_text(2) in planned and "±" in planned
    cells = pd.read_csv(out / "cohort_probability.csv")
    assert len(cells) == 15 and set(cells["subjects"]) == {2}
    assert (out / "cohort_probability.parquet").exists()  # --format: as every table
    assert (out / "cohort_probability_boundaries.parquet").exists()
    assert readable_png(out / "cohort_probability.png")
    # mb.cohort on the same folder: resumed, the probability map in the result's attrs
    again = mb.cohort(
        cohort_members.population(2, 2),
        out=out,
        forces=FORCES,
        durations=DURATIONS,
        config=BASE,
        progress=False,
        queue="each",
    )
    pd.testing.assert_frame_equal(again.attrs["probability"], cells, check_dtype=False)
    assert math.isclose(again.attrs["half_width"], probability.half_width(2))


def test_the_base_map_is_a_result_that_keeps_the_folder(tmp_path):
    """A cohort folder whose only result is its base map is not taken over by another cohort
    (a subject's map would not be either): the base map was run with this cohort's base."""
    out = tmp_path / "out"
    cohort.run_cohort(
        out,
        cohort_members.subject_grid([1.7], [70]),
        BASE,
        FORCES,
        DURATIONS,
        run_batches=stand_ins,
        say=None,
    )
    (out / "cohort.csv").unlink()
    shutil.rmtree(out / "subjects")
    assert (out / "base" / "region.parquet").exists()
    with pytest.raises(ParameterError, match="holds a cohort with other configuration"):
        cohort.run_cohort(
            out,
            cohort_members.subject_grid([1.7], [70]),
            BASE.replace(controller={"horizon": 15}),
            FORCES,
            DURATIONS,
            run_batches=stand_ins,
            say=None,
        )


def test_the_plan_counts_the_subjects_set_up_before_and_during_the_run(capsys, monkeypatch):
    """A 30,000-subject cohort checks its representatives and sets up its first queue's maps
    before its first scenario, then every other subject's when its queue starts (the
    plan once said "about 4 min" and then checked every subject for 25 min first); the plan
    line says both, and the limit counts them. The subjects are not checked here: the plan is
    said before, so the check is stopped at its start."""
    from mjx_balance.model.params import ParameterError
    from mjx_balance.runs.chunks import SUBJECT_CHECK_SECONDS, SUBJECT_SETUP_SECONDS, wall_span
    from mjx_balance.runs.population import FIRST_QUEUE

    def stopped(*_args, **_kwargs):
        raise ParameterError("stopped at the subjects' checks")

    monkeypatch.setattr("mjx_balance.studies.cohort.plan_cohort", stopped)
    words = ["cohort", "--population", "30000", "--seed", "1", "--forces", "0,50"]
    words += ["--durations", "0.1", "--set", "scenario.t_end=2", "--out", "unused"]
    assert main(words) == 2
    printed = capsys.readouterr().out
    planned = next(line for line in printed.splitlines() if line.startswith("planned work"))
    checked = cohort.checked_first(30000)
    assert 0 < checked <= 24  # each sex's extremes of six values
    before = checked * SUBJECT_CHECK_SECONDS + FIRST_QUEUE * SUBJECT_SETUP_SECONDS
    during = (30001 - FIRST_QUEUE) * SUBJECT_SETUP_SECONDS
    assert (
        f"after {wall_span(before, before)} of checking {checked} subjects' configurations and "
        f"setting up {FIRST_QUEUE} maps before the first scenario" in planned
    ), planned
    assert f"plus {wall_span(during, during)} of setting up 29,985 more maps" in planned
