"""Cohorts' bad inputs (``mjx-balance cohort``, ``mb.cohort``) and ``compare --subject``: each
refused in one line naming the argument or file and the value (exit code 2 on the command
line, a ValueError or TypeError in Python) before anything is written (no folder, no
manifest.json, no .lock); a cohort folder that holds no result is taken over by a corrected
configuration. No test here runs the engine: refusals come before any work, and the runs use
the stand-in batch (``support.FakeThresholdBatch``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from support import REPO, FakeThresholdBatch, assert_refused, run_cli

import mjx_balance as mb
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.model.subject import Subject
from mjx_balance.studies import cohort
from mjx_balance.studies import members as cohort_members

BASE = Config().replace(scenario={"t_end": 2.0})
FORCES, DURATIONS = "0:40:20", "0.5,1"
LONG_ID = "P" * 300  # passed the id check, then failed "File name too long" (exit 1)


def stand_ins(config: Config) -> FakeThresholdBatch:
    return FakeThresholdBatch(c=float(config.controller.input1_bounds[1]))


def nothing_written(out) -> bool:
    """No folder at all: not even the lock file or the manifest."""
    return not out.exists()


# --- the command line: every refusal before the folder ---------------------------------------


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--heights", "1.7", "--masses", "70", "--forces", "1e39"], ["forces", "1e+39"]),
        (
            ["--heights", "1.7", "--masses", "70", "--table-forces", "1e39"],
            ["table forces", "1e+39"],
        ),
        (
            ["--heights", "1.7", "--masses", "70", "--set", "controller.horizon=200"],
            ["controller.horizon = 200"],
        ),
        (["--heights", "1.7", "--masses", "70", "--durations", "5"], ["t_end = 2", "5"]),
        (["--heights", "1.7", "--masses", "70", "--forces", "abc"], ["forces", "'abc'"]),
        (["--heights", "1.7", "--masses", "1.5"], ["subject.mass = 1.5"]),
        (["--heights", "1.0", "--masses", "6"], ["body mass index"]),
        (
            ["--population", "3", "--seed", "1", "--set", "controller.horizon=200"],
            ["controller.horizon = 200"],
        ),
    ],
)
def test_a_refused_cohort_writes_nothing(tmp_path, capsys, argv, words):
    """The grid, the configuration and each subject's configuration are checked before the
    folder is made: `--forces 1e39` and `--set controller.horizon=200` left manifest.json (the
    corrected command was then refused), every grid error left DIR/.lock."""
    out = tmp_path / "out"
    code, err = run_cli(
        ["cohort", *argv, "--set", "scenario.t_end=2", "-q", "--out", str(out)], capsys
    )
    assert_refused(code, err, *words)
    assert nothing_written(out)


@pytest.mark.parametrize(
    "rows, words",
    [
        (f"id,height,mass\n{LONG_ID},1.6,55\n", ["line 2: id = ", "300 characters", "at most 64"]),
        ("id,height,mass\nP1,1,6,55\n", ["line 2: 4 values", "decimal comma"]),
        ("id,height,mass,ankle_strenght\nP1,1.6,55,0.5\n", ["unknown column(s) 'ankle_strenght'"]),
        ("# pilot\nheight,mass\n", ["holds a header and no subject"]),
    ],
)
def test_a_bad_subjects_file_writes_nothing(tmp_path, capsys, rows, words):
    """A 300-character id was accepted, then failed at its folder (exit 1, the manifest
    marked failed): ids are bounded as the file is read, as every other row problem is."""
    people = tmp_path / "people.csv"
    people.write_text(rows)
    out = tmp_path / "out"
    code, err = run_cli(
        [
            "cohort",
            "--subjects",
            str(people),
            "--forces",
            FORCES,
            "--durations",
            DURATIONS,
            "--out",
            str(out),
        ],
        capsys,
    )
    assert_refused(code, err, str(people), *words)
    assert nothing_written(out)


def test_a_subjects_file_with_headers_in_any_case_and_a_bom_keeps_its_ids(tmp_path):
    """`ID` or a BOM before `id` lost the ids (s01, s02 instead), `Sex` the sex."""
    people = tmp_path / "people.csv"
    people.write_text(
        "ID,Height,Mass,Sex\nann,1.62,58,female\nbob,1.85,90,male\n", encoding="utf-8-sig"
    )
    members = cohort_members.read_subjects(people)
    assert [m.id for m in members] == ["ann", "bob"]
    assert members[0].subject == Subject(1.62, 58, "female")


def test_every_id_is_bounded_however_the_subjects_come():
    for subjects in (
        {LONG_ID: Subject(1.7, 70)},
        [cohort_members.Member(LONG_ID, Subject(1.7, 70))],
    ):
        with pytest.raises(ParameterError, match="300 characters long; an id has at most 64"):
            cohort_members.as_members(subjects)
    assert cohort_members.as_members({"P" * 64: Subject(1.7, 70)})[0].id == "P" * 64


# --- a folder without results is taken over --------------------------------------------------


def _leftover(out, base: Config) -> None:
    """The manifest a cohort run left when it was refused or stopped before its first result
    (as the refusals above did before they moved ahead of the folder)."""
    record = cohort._record(
        cohort_members.subject_grid([1.7], [70]),
        base,
        np.array([0.0, 20, 40]),
        np.array([0.5, 1.0]),
        None,
    )
    out.mkdir(parents=True)
    (out / "manifest.json").write_text(
        json.dumps({**record, "runs": [{"command": "mjx-balance cohort ...", "status": "failed"}]})
    )


def test_a_folder_without_results_is_taken_over_by_a_corrected_cohort(tmp_path):
    """`--set controller.horizon=200` refused after the manifest was written left a folder
    that refused the corrected command ("holds a cohort with other configuration"): a cohort
    folder none of whose subjects holds a result is started anew, its runs' records kept."""
    out = tmp_path / "out"
    _leftover(out, BASE.replace(controller={"horizon": 200}))
    members = cohort_members.subject_grid([1.7], [70])
    said: list[str] = []
    frame = cohort.run_cohort(
        out, members, BASE, FORCES, DURATIONS, run_batches=stand_ins, say=said.append
    )
    assert list(frame["id"]) == ["s01"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["controller"]["horizon"] == BASE.controller.horizon
    assert [r["status"] for r in manifest["runs"]][:1] == ["failed"]  # the old run's record
    assert any("holds no results" in line for line in said)
    # once it holds results, another configuration is refused as before
    with pytest.raises(ParameterError, match="holds a cohort with other configuration"):
        cohort.run_cohort(
            out,
            members,
            BASE.replace(controller={"horizon": 15}),
            FORCES,
            DURATIONS,
            run_batches=stand_ins,
            say=None,
        )


def test_the_corrected_command_takes_over_a_refused_runs_folder(tmp_path, capsys, fake_rollout):
    """A refused run, then its corrected command, on the command line: the manifest a refused
    `--set controller.horizon=200` left, then the command without it: exit 0, the cohort
    written."""
    out = tmp_path / "out"
    _leftover(out, BASE.replace(controller={"horizon": 200}))
    code, err = run_cli(
        [
            "cohort",
            "--heights",
            "1.7",
            "--masses",
            "70",
            "--forces",
            FORCES,
            "--durations",
            DURATIONS,
            "--set",
            "scenario.t_end=2",
            "-q",
            "--queue",
            "each",
            "--out",
            str(out),
        ],
        capsys,
    )  # each: the fake rollout
    assert code == 0, err
    assert (out / "cohort.csv").exists()


def test_a_folder_with_one_subjects_chunk_is_not_taken_over(tmp_path):
    """A subject's partial map (a chunk, no region.parquet) is a result: kept, and another
    cohort refused."""
    out = tmp_path / "out"
    members = cohort_members.subject_grid([1.7], [70])
    cohort.run_cohort(out, members, BASE, FORCES, DURATIONS, run_batches=stand_ins, say=None)
    (out / "cohort.csv").unlink()
    (out / "subjects" / "s01" / "region.parquet").unlink()
    assert list((out / "subjects" / "s01" / "chunks").glob("*.parquet"))
    with pytest.raises(ParameterError, match="other subjects or grids"):
        cohort.run_cohort(
            out,
            cohort_members.subject_grid([1.8], [70]),
            BASE,
            FORCES,
            DURATIONS,
            run_batches=stand_ins,
            say=None,
        )


# --- mb.cohort -------------------------------------------------------------------------------


def test_the_api_takes_one_subject(tmp_path, fake_rollout):
    """`mb.cohort(mb.Subject(1.7, 70), out=DIR)` failed "'Subject' object is not iterable"."""
    fake_rollout(FakeThresholdBatch(c=20.0))
    frame = mb.cohort(
        mb.Subject(1.7, 70),
        out=tmp_path / "out",
        forces=FORCES,
        durations=DURATIONS,
        config=BASE,
        progress=False,
        queue="each",
    )  # each: the fake rollout
    assert list(frame["id"]) == ["s01"] and frame.loc[0, "height"] == 1.7


@pytest.mark.parametrize(
    "kwargs, error, words",
    [
        ({"physics": "gpu"}, ValueError, ["physics = 'gpu'", "'auto', 'mjx', 'c'"]),
        ({"physics": None}, ValueError, ["physics = None"]),
        ({"slots": 0}, ValueError, ["slots = 0"]),
        ({"full_length": "yes"}, TypeError, ["full_length = 'yes'"]),  # a type: api.checked
        ({"progress": "yes"}, TypeError, ["progress = 'yes'"]),
        ({"wait": None}, TypeError, ["wait = None"]),
        ({"format": "xls"}, ValueError, ["format = 'xls'"]),
        ({"figure_format": "bmp"}, ValueError, ["bmp"]),
        ({"forces": "abc"}, ValueError, ["forces", "'abc'"]),
        ({"durations": [5.0]}, ValueError, ["t_end = 2", "5"]),
        ({"table_forces": [1e39]}, ValueError, ["table forces", "1e+39"]),
        (
            {"config": BASE.replace(controller={"horizon": 200})},
            ValueError,
            ["controller.horizon = 200"],
        ),
        ({"subjects": 42}, ValueError, ["subjects", "int"]),
        ({"subjects": [Subject(1.7, 70), "tall"]}, ValueError, ["subjects", "'tall'"]),
        ({"subjects": {LONG_ID: Subject(1.7, 70)}}, ValueError, ["at most 64"]),
    ],
)
def test_the_api_refuses_a_bad_argument_before_writing(tmp_path, kwargs, error, words):
    """`physics="gpu"` raised a raw ValueError after writing a failed manifest: every argument
    is checked first, the error naming it and what it accepts."""
    out = tmp_path / "out"
    args = {
        "subjects": [Subject(1.7, 70)],
        "forces": FORCES,
        "durations": DURATIONS,
        "config": BASE,
        "progress": False,
        **kwargs,
    }
    with pytest.raises(error) as err:
        mb.cohort(out=out, **args)
    message = str(err.value)
    assert "\n" not in message
    for word in words:
        assert word in message
    assert nothing_written(out)


# --- compare --subject -----------------------------------------------------------------------


def test_compare_with_a_subject_on_a_sweep_definition_base(tmp_path, capsys, monkeypatch):
    """`compare --config of.toml --subject ... t2.toml of.toml` (of.toml a sweep definition)
    failed "unknown section(s) sweep" where the same command without --subject worked: the
    subject's path read the base as a plain configuration file. The base is now read as each
    compared file is, with the subject's body under its values."""
    from mjx_balance.studies import compare

    sweep_file = REPO / "src" / "mjx_balance" / "sweeps" / "study_offset_free.toml"
    of = tmp_path / "of.toml"
    of.write_text(sweep_file.read_text())
    t2 = tmp_path / "t2.toml"
    t2.write_text("[scenario]\nt_end = 2.0\n")
    seen = {}
    monkeypatch.setattr(
        "mjx_balance.api.run_compare",  # what mb.compare (and the CLI) call
        lambda out, configs, *args, **kwargs: seen.update(configs),
    )
    subject = Subject(1.6, 55)
    for extra in ([], ["--subject", "height=1.6,mass=55"]):
        seen.clear()
        code, err = run_cli(
            [
                "compare",
                "--config",
                str(of),
                *extra,
                str(t2),
                str(of),
                "--out",
                str(tmp_path / "cmp"),
            ],
            capsys,
        )
        assert code == 0, err
        assert set(seen) == {"t2", "of"}
        for config in seen.values():  # the base's offset-free controller under every variant
            assert config.controller.offset_free
        assert seen["t2"].scenario.t_end == 2.0
        body = subject.config().body if extra else Config().body
        assert seen["t2"].body == body and seen["of"].body == body
    # a plain configuration file as the base, with a subject, as before
    assert compare.load_base(t2, subject) == subject.config(
        Config().replace(scenario={"t_end": 2.0})
    )
    assert compare.load_base(None, subject) == subject.config()
    assert compare.load_base(None) is None
