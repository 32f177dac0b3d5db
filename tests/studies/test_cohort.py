"""Cohorts (``mjx-balance cohort``, ``mb.cohort``, ``studies.cohort``): the subjects' sources
(grid, CSV, seeded population), the cohort's files and units, resume, the command line's
errors; and one real-engine test: a cohort of one subject is the plain sweep of that body, bit
for bit, at the same slot count.

The bookkeeping tests use a stand-in batch function (``test_sweep.FakeThresholdBatch``:
recovered iff |F| T < c), with c the subject's ankle torque bound (it grows with the mass and
the ankle strength), so the subjects' areas differ as the real ones would."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from support import DEFAULT_BATCH, FakeThresholdBatch

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.measures import units
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.model.subject import HEIGHT_RANGE, Subject
from mjx_balance.studies import cohort
from mjx_balance.studies import members as cohort_members

FORCES, DURATIONS = "0:40:10", "0.5,1,2"
BASE = Config().replace(scenario={"t_end": 2.0})


def threshold(config: Config) -> float:
    return float(config.controller.input1_bounds[1])


def stand_ins(made: list | None = None):
    def make(config):
        batch = FakeThresholdBatch(c=threshold(config))
        if made is not None:
            made.append(batch)
        return batch

    return make


def run(out, members, made=None, **kwargs):
    return cohort.run_cohort(
        out, members, BASE, FORCES, DURATIONS, run_batches=stand_ins(made), say=None, **kwargs
    )


# --- subjects --------------------------------------------------------------------------------


def test_a_grid_of_subjects_is_the_product_of_the_lists():
    members = cohort_members.subject_grid([1.6, 1.8], [60, 80], ["male", "female"], [0.5, 1.0])
    assert len(members) == 16
    assert [m.id for m in members[:3]] == ["s01", "s02", "s03"]
    first, last = members[0].subject, members[-1].subject
    assert (first.height, first.mass, first.sex, first.ankle_strength) == (1.6, 60, "male", 0.5)
    assert (last.height, last.mass, last.sex, last.ankle_strength) == (1.8, 80, "female", 1.0)
    with pytest.raises(ParameterError, match="height"):
        cohort_members.subject_grid([9.0], [60])


def test_a_population_is_seeded_and_truncated():
    a = cohort_members.population(30, seed=7)
    assert a == cohort_members.population(30, seed=7)  # the same seed, the same subjects
    assert a != cohort_members.population(30, seed=8)
    sexes = {m.subject.sex for m in a}
    assert sexes == {"male", "female"}
    males = cohort_members.population(20, 1, female_fraction=0.0)
    assert {m.subject.sex for m in males} == {"male"}
    # a mean near the top of the range: every draw redrawn into it (a truncated normal)
    tall = cohort_members.population(50, seed=3, height_mean=2.45, height_sd=0.2)
    heights = np.array([m.subject.height for m in tall])
    assert heights.max() <= HEIGHT_RANGE[1] and heights.min() >= HEIGHT_RANGE[0]
    assert (heights > 2.3).mean() > 0.3  # still drawn around the mean, not clipped to a value
    with pytest.raises(ParameterError, match="female_fraction"):
        cohort_members.population(5, 1, female_fraction=1.5)
    with pytest.raises(ParameterError, match="seed = -1"):
        cohort_members.population(5, -1)
    with pytest.raises(ParameterError, match="height"):
        cohort_members.population(5, 1, height_mean=40.0, height_sd=0.01)


def test_a_csv_of_participants_keeps_its_ids_and_refuses_bad_rows(tmp_path):
    good = tmp_path / "people.csv"
    good.write_text(
        "id,height,mass,sex,ankle_strength,hip_strength,note\n"
        "P-07,1.62,58,female,0.8,,left-handed\n"
        ",1.80,82,male,,,\n"
    )
    members = cohort_members.read_subjects(good)
    assert [m.id for m in members] == ["P-07", "s02"]
    assert members[0].subject == Subject(1.62, 58, "female", 0.8)
    cases = {
        "1.7,abc,male": "line 3: mass = 'abc'",
        "1.7,70,other": "line 3.*sex.*'other'",
        "7.5,70,male": "line 3.*height.*7.5",
    }
    for row, message in cases.items():
        bad = tmp_path / "bad.csv"
        bad.write_text(f"height,mass,sex\n1.6,60,male\n{row}\n")
        with pytest.raises(ParameterError, match=message):
            cohort_members.read_subjects(bad)
    twice = tmp_path / "twice.csv"
    twice.write_text("id,height,mass\na,1.6,60\nA,1.7,70\n")
    with pytest.raises(ParameterError, match="'A' is given twice"):
        cohort_members.read_subjects(twice)
    slash = tmp_path / "slash.csv"
    slash.write_text("id,height,mass\na/b,1.6,60\n")
    with pytest.raises(ParameterError, match="line 2: id = 'a/b'"):
        cohort_members.read_subjects(slash)


# --- the cohort's files ----------------------------------------------------------------------


def test_the_cohort_writes_its_table_summary_manifest_and_figures(tmp_path):
    members = cohort_members.subject_grid([1.6, 1.8], [55, 85])
    frame = run(tmp_path / "out", members)
    out = tmp_path / "out"
    written = pd.read_csv(out / "cohort.csv")
    assert list(written["id"]) == [m.id for m in members]
    assert list(written.columns[:6]) == cohort.SUBJECT_COLUMNS
    for name in ("area", "mean_recovery_energy", "sustained_push_limit"):
        assert name in written
    # each subject's area is its own region's, from its own folder's map
    for member, row in zip(members, written.itertuples()):
        region = pd.read_parquet(out / "subjects" / member.id / "region.parquet")
        assert row.area == pytest.approx(mb.region_numbers(region)["area"])
        c = threshold(member.subject.config(BASE))
        ok = region["force"] * region["duration"] < c
        assert (region["outcome"] == "recovered").tolist() == ok.tolist()
    assert written["area"].nunique() > 1  # heavier subjects hold more (a larger torque bound)
    pd.testing.assert_frame_equal(written, frame, check_dtype=False)
    summary = pd.read_csv(out / "cohort_summary.csv").set_index("statistic")
    assert list(summary.index) == list(cohort.STATISTICS)
    assert summary.loc["mean", "area"] == pytest.approx(written["area"].mean())
    assert summary.loc["sd", "mass"] == pytest.approx(written["mass"].std(ddof=1))
    assert summary.loc["p50", "height"] == pytest.approx(1.7)
    assert "id" not in summary and "sex" not in summary
    for name in ("cohort.csv", "cohort_summary.csv"):  # every column has a unit, sidecar too
        columns = pd.read_csv(out / name).columns
        assert units.unknown(columns) == []
        sidecar = pd.read_csv(out / name.replace(".csv", ".units.csv"), keep_default_na=False)
        assert list(sidecar["column"]) == list(columns)
    assert units.unit("mass") == "kg" and units.unit("area") == "N s"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["kind"] == "cohort"
    assert [s["id"] for s in manifest["cohort"]["subjects"]] == [m.id for m in members]
    assert manifest["cohort"]["forces"] == [0, 10, 20, 30, 40]
    assert manifest["runs"][0]["command"]
    for figure in ("cohort_area.png", "cohort_boundaries.png", "cohort_regions.png"):
        assert (out / figure).stat().st_size > 1000


def test_the_table_forces_give_the_limit_and_acting_times(tmp_path):
    members = cohort_members.subject_grid([1.7], [60, 90])
    frame = run(tmp_path / "out", members, table_forces="20,40")
    assert {"max_acting_time_20N", "max_acting_time_40N"} <= set(frame.columns)
    assert frame["sustained_push_limit"].notna().all()
    assert (frame["max_acting_time_20N"].diff().dropna() >= 0).all()  # heavier: longer


def test_the_chosen_subjects_span_the_area():
    frame = pd.DataFrame({"id": [f"s{i:02d}" for i in range(20)], "area": np.arange(20.0)[::-1]})
    picks = cohort.chosen(frame, 5)
    assert picks[0] == "s19" and picks[-1] == "s00"  # the smallest and the largest area
    assert len(picks) == 5 and "s10" in picks or "s09" in picks  # the median among them
    assert cohort.chosen(frame.head(3)) == ["s02", "s01", "s00"]


def test_a_cohort_resumes_subject_by_subject(tmp_path):
    out = tmp_path / "out"
    members = cohort_members.subject_grid([1.6, 1.8], [60])
    run(out, members)
    first = pd.read_csv(out / "cohort.csv")
    made: list = []
    run(out, members, made)  # nothing to do: no scenario runs
    assert sum(len(b.calls) for b in made) == 0
    # a partial subject: its merged map and one chunk gone; only that subject runs again
    partial = out / "subjects" / members[1].id
    (partial / "region.parquet").unlink()
    chunks = sorted((partial / "chunks").glob("chunk-*.parquet"))
    chunks[0].unlink()
    made.clear()
    run(out, members, made)
    # the subjects' batches in order, then the base map's (finished: nothing runs)
    assert [len(b.calls) > 0 for b in made] == [False, True, False]
    pd.testing.assert_frame_equal(pd.read_csv(out / "cohort.csv"), first)
    with pytest.raises(ParameterError, match="other subjects or grids"):
        run(out, cohort_members.subject_grid([1.6], [60]))


# --- the command line and mb.cohort ----------------------------------------------------------


@pytest.mark.parametrize(
    "argv, message",
    [
        ([], "give one source of subjects"),
        (
            ["--heights", "1.6", "--masses", "60", "--population", "3", "--seed", "1"],
            "got grid, population",
        ),
        (["--heights", "1.6"], "--heights and --masses go together"),
        (["--population", "3"], "--population needs --seed"),
        (["--population", "3", "--seed", "1", "--sexes", "female"], "--sexes goes with"),
        (["--population", "3", "--seed", "1", "--ages", "30"], "--ages goes with"),
        (["--heights", "1.6", "--masses", "60", "--age-mean", "70"], "--age-mean goes with"),
        (["--population", "3", "--seed", "1", "--age-sd", "5"], "--age-sd goes with --age-mean"),
        (["--heights", "1.6", "--masses", "60", "--ages", "12"], "subject.age = 12"),
        (["--population", "3", "--seed", "1", "--age-mean", "15"], "age_mean"),
        (
            ["--heights", "1.6", "--masses", "60", "--subject", "height=1.7,mass=70"],
            "--subject is one person",
        ),
        (["--heights", "1.6:1.2:0.1", "--masses", "60"], "--heights"),
    ],
)
def test_the_command_refuses_an_unclear_source(tmp_path, capsys, argv, message):
    assert main(["cohort", *argv, "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out" / "cohort.csv").exists()


def test_the_command_parses_its_lists(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:  # argparse's own error: exit code 2
        main(
            [
                "cohort",
                "--heights",
                "1.6",
                "--masses",
                "60",
                "--sexes",
                "males",
                "--out",
                str(tmp_path / "o"),
            ]
        )
    assert exc.value.code == 2
    assert "male, female or male,female" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("id,height,mass\nx,1.6,-3\n")
    assert main(["cohort", "--subjects", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "line 2" in capsys.readouterr().err


def test_the_command_runs_a_cohort_from_a_csv(tmp_path, monkeypatch):
    made = []

    def make(config, **_engine):
        made.append(FakeThresholdBatch(c=threshold(config)))
        return made[-1]

    monkeypatch.setattr(DEFAULT_BATCH, make)
    people = tmp_path / "people.csv"
    people.write_text("id,height,mass,sex\nann,1.62,58,female\nbob,1.85,90,male\n")
    out = tmp_path / "out"
    assert (
        main(
            [
                "cohort",
                "--subjects",
                str(people),
                "--forces",
                FORCES,
                "--durations",
                DURATIONS,
                "--set",
                "scenario.t_end=2",
                "--format",
                "parquet",
                "-q",
                "--queue",
                "each",
                "--out",
                str(out),
            ]
        )
        == 0
    )  # each: the fake rollout
    frame = pd.read_csv(out / "cohort.csv")
    assert list(frame["id"]) == ["ann", "bob"] and list(frame["sex"]) == ["female", "male"]
    assert frame.loc[0, "area"] < frame.loc[1, "area"]
    assert (out / "cohort.parquet").exists()  # --format: the tables also as parquet
    # mb.cohort on the same folder and subjects: resumed, the same table
    again = mb.cohort(
        {"ann": Subject(1.62, 58, "female"), "bob": Subject(1.85, 90)},
        out=out,
        forces=FORCES,
        durations=DURATIONS,
        config=BASE,
        queue="each",
    )
    pd.testing.assert_frame_equal(again, frame, check_dtype=False)


# --- the real engine -------------------------------------------------------------------------


@pytest.mark.slow
def test_a_cohort_of_one_is_the_plain_sweep_of_that_body(tmp_path):
    """Bit for bit (region.parquet's every column) at the same slot count: the cohort's subject
    folder (``--queue each``) is the plain sweep's folder of that --subject. One compile (the
    two runs share the compiled program: the same body), about 90 s on a 2-core CPU."""
    person = "height=1.58,mass=52,sex=female,ankle_strength=0.7"
    grid = ["--forces", "30,90", "--durations", "0.1,0.3", "--slots", "8", "-q"]
    assert main(["sweep", "--subject", person, *grid, "--out", str(tmp_path / "plain")]) == 0
    people = tmp_path / "one.csv"
    people.write_text("id,height,mass,sex,ankle_strength\nmona,1.58,52,female,0.7\n")
    assert (
        main(
            [
                "cohort",
                "--subjects",
                str(people),
                *grid,
                "--queue",
                "each",
                "--out",
                str(tmp_path / "cohort"),
            ]
        )
        == 0
    )
    plain = pd.read_parquet(tmp_path / "plain" / "region.parquet")
    one = pd.read_parquet(tmp_path / "cohort" / "subjects" / "mona" / "region.parquet")
    pd.testing.assert_frame_equal(one, plain, check_exact=True)
    assert plain["outcome"].nunique() > 1  # the grid crosses the boundary: not a trivial map
    row = pd.read_csv(tmp_path / "cohort" / "cohort.csv").iloc[0]
    assert row["area"] == pytest.approx(mb.region_numbers(plain)["area"])


def test_the_queue_by_default_is_one_on_mjx_each_elsewhere_and_a_resumed_folders_own(tmp_path):
    """``--queue auto``: one engine queue on the MJX path without a cluster, every subject its
    own run on the C path or a cluster, and a folder whose maps started keeps their queue
    (resuming under the other is refused: the results differ by float rounding)."""
    out = tmp_path / "c"
    assert cohort.resolved_queue(out, "auto", "auto", None) == "one"
    assert cohort.resolved_queue(out, "auto", "mjx", None) == "one"
    assert cohort.resolved_queue(out, "auto", "c", None) == "each"
    assert cohort.resolved_queue(out, "auto", "auto", "local:2") == "each"
    assert cohort.resolved_queue(out, "each", "auto", None) == "each"  # asked: kept
    started = out / "subjects" / "s02"
    started.mkdir(parents=True)
    (out / "subjects" / "s01").mkdir()  # a folder with no manifest yet: nothing to resume
    (started / "manifest.json").write_text(
        json.dumps({"region": {"engine": {"slots": 32, "early_stop": True, "physics": "mjx"}}})
    )
    assert cohort.resolved_queue(out, "auto", "auto", None) == "each"  # before queues: each
    (started / "manifest.json").write_text(
        json.dumps({"region": {"engine": {"slots": 32, "physics": "mjx", "queue": "one"}}})
    )
    assert cohort.resolved_queue(out, "auto", "c", None) == "one"
    plan = cohort.plan_cohort(
        tmp_path / "new",
        cohort_members.numbered([Subject(1.7, 70)]),
        Config(),
        "0,50",
        "0.1",
        physics="c",
    )
    assert plan.engine["queue"] == "each"


def test_subjects_share_one_compiled_program():
    """Everything a compiled program is keyed on (``BatchRunner._shape_key``: tree structure,
    shapes, static settings) is the same for bodies of other sizes and strengths: the body,
    the QP and the torque bounds are traced arguments, so a cohort compiles once (measured:
    docs/cohorts.md, "Cohorts"). Builds the runners only; nothing is compiled."""
    from mjx_balance.rollout.runner import BatchRunner

    small = BatchRunner(Subject(1.52, 48, "female", ankle_strength=0.6).config())
    large = BatchRunner(Subject(1.93, 105, "male", hip_strength=1.4).config())
    assert small.static.limits == large.static.limits  # the bounds are not in it
    assert not np.array_equal(small.arrays.bounds, large.arrays.bounds)  # but they differ
    assert small._shape_key(32) == large._shape_key(32)
