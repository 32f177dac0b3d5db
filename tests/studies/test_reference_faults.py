"""Reference files' and the scorecard's bad inputs: each refused in one line naming the file
(its line and column) or the argument and the value (exit code 2 on the command line, a
ValueError / TypeError in Python) before anything is written; several files of one name kept
and scored apart; one force tolerance for adding a reference's forces and matching them; a
large file read and scored in seconds; the scorecard's figure, message and report table saying
what they should. No test here runs the engine: the scorecard is scored against made-up tables,
and the command line's runs use the stand-in batch (``support.FakeThresholdBatch``)."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest
from support import assert_refused, run_cli

import mjx_balance as mb
from mjx_balance.model.params import ParameterError
from mjx_balance.studies import reference_files as rf
from mjx_balance.studies import scorecard as sc

# Our side, made up (as tests/studies/test_scorecard.py): three forces, 100 N's 0.1-s push fell.
OURS = pd.DataFrame(
    {
        "force": [20.0, 50.0, 100.0],
        "max_acting_time": [0.58, 0.18, 0.08],
        "energy_total_01": [0.054, 0.357, np.nan],
        "energy_total_max": [5.5, 3.8, 2.2],
        "study_energy_total_01": [0.039, 0.247, np.nan],
        "monotone": [True, True, False],
    }
)
RUNS = pd.DataFrame(
    {
        "force": [20.0, 20.0, 20.0, 50.0, 50.0],
        "duration": [0.5, 0.57, 0.58, 0.17, 0.18],
        "outcome": ["recovered"] * 5,
        "energy_total": [3.0, 5.3, 5.5, 3.6, 3.8],
    }
)


def _write(folder, name, text):
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _refused(path, *words):
    """read_reference refuses ``path`` in one line naming the file and ``words``."""
    with pytest.raises(ParameterError) as info:
        rf.read_reference(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message, message
    for word in words:
        assert word in message, message
    return message


# --- a file's rows and values ------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, words",
    [
        # a trailing comma on the data rows: pandas took the first column as the index, the force
        # became 0.35 and the scorecard was empty
        (
            "force,max_acting_time\n20,0.35,\n50,0.18,\n",
            ["line 2", "3 fields where the header has 2", "trailing comma"],
        ),
        (
            "# a comment\nforce,max_acting_time\n20,0.35\n\n50,0.18,0.1\n",
            ["line 5", "3 fields where the header has 2"],
        ),
        ("force,duration,recovered\n20,0.3,1\n20,0.4,0,\n", ["line 3", "4 fields"]),
    ],
)
def test_a_row_with_more_fields_than_the_header_is_refused(tmp_path, text, words):
    _refused(_write(tmp_path, "ref.csv", text), *words)


def test_a_trailing_comma_on_every_line_is_an_empty_column(tmp_path):
    """A comma ending the header and every row too is an unnamed, empty column: read as if it
    were not there; an unnamed column that holds values is refused."""
    ref = rf.read_reference(_write(tmp_path, "ok.csv", "force,max_acting_time,\n20,0.6,\n"))
    assert ref.frame["force"].tolist() == [20.0] and ref.measures == ["max_acting_time"]
    _refused(
        _write(tmp_path, "bad.csv", "force,,max_acting_time\n20,x,0.6\n"),
        "column 2 has no name",
        "'x'",
        "line 2",
    )


@pytest.mark.parametrize(
    "column",
    [
        "force",
        "duration",
        "max_acting_time",
        "study_energy_total_max",
        "energy_hip_01",
        "resolution",
        "tolerance",
    ],
)
@pytest.mark.parametrize("value", ["inf", "-inf", "1e309", "nan", "abc"])
def test_every_numeric_column_refuses_a_value_that_is_not_a_finite_number(tmp_path, column, value):
    """inf and 1e309 in a measure dropped the row silently (nan was refused); inf as a force
    was refused later without naming the file. Now every numeric column the same way: file,
    line, column and the value."""
    columns = list(dict.fromkeys(["force", "max_acting_time", column]))
    good = ",".join("30" if c == "force" else "0.5" for c in columns)
    bad = ",".join(value if c == column else "20" if c == "force" else "0.5" for c in columns)
    path = _write(tmp_path, "ref.csv", f"{','.join(columns)}\n{good}\n{bad}\n")
    _refused(path, "line 3", f"{column} must be a finite number", repr(value))


def test_a_negative_value_names_its_line(tmp_path):
    _refused(
        _write(tmp_path, "ref.csv", "force,max_acting_time\n20,0.6\n50,-0.1\n"),
        "line 3",
        "max_acting_time must not be negative",
        "'-0.1'",
    )


def test_a_file_where_every_value_was_dropped_is_refused_not_scored_empty(tmp_path):
    """Every row's measure inf: the scorecard was header-only; now the first is refused."""
    path = _write(tmp_path, "ref.csv", "force,max_acting_time\n20,inf\n50,1e309\n")
    _refused(path, "line 2", "'inf'")


@pytest.mark.parametrize(
    "text, words",
    [
        (
            "force,max_acting_time\n20,0.35\n50,0.2\n20.0,0.36\n",
            ["lines 2 and 4", "two different max_acting_time", "force 20 N", "0.35 and 0.36"],
        ),
        (
            "force,energy_total_01,energy_total_max\n20,0.05,5.5\n20,0.05,6.0\n",
            ["lines 2 and 3", "two different energy_total_max", "5.5 and 6"],
        ),
        (
            "force,duration,recovered\n20,0.3,yes\n20,0.30,no\n",
            ["lines 2 and 3", "two different recovered", "push 20 N x 0.3 s"],
        ),
    ],
)
def test_contradictory_duplicate_rows_are_refused_naming_both_lines(tmp_path, text, words):
    _refused(_write(tmp_path, "ref.csv", text), *words)


def test_an_identical_repeated_row_is_scored_once(tmp_path):
    ref = rf.read_reference(
        _write(
            tmp_path,
            "ref.csv",
            ("force,max_acting_time,duration,recovered\n20,0.6,0.3,1\n20,0.60,0.3,yes\n"),
        )
    )
    card = sc.score(ref, OURS)
    assert card["measure"].tolist() == ["max_acting_time", "recovered"]


@pytest.mark.parametrize(
    "text, words",
    [
        (
            "force;max_acting_time\n20;0.35\n",
            ["'force;max_acting_time'", "the separator must be a comma"],
        ),
        ("force;max_acting_time\n20;0,35\n", ["the separator must be a comma"]),  # decimal comma
        ("force\tmax_acting_time\n20\t0.35\n", ["the separator must be a comma"]),
        (
            "Kraft,max_acting_time\n20,0.35\n",
            ["needs a column force", "found column(s) 'kraft', 'max_acting_time'"],
        ),
        ("force,force\n20,30\n", ["force given more than once"]),
        ("", ["empty"]),
    ],
)
def test_a_header_without_force_says_what_it_found(tmp_path, text, words):
    """A semicolon-separated file said "needs a column force" with no hint."""
    _refused(_write(tmp_path, "ref.csv", text), *words)


def test_a_byte_order_mark_and_blank_or_indented_comment_lines_are_read(tmp_path):
    path = _write(tmp_path, "ref.csv", "\ufeffforce,max_acting_time\n  # a note\n20,0.6\n,\n")
    assert rf.read_reference(path).frame["force"].tolist() == [20.0]


def test_an_absurd_file_is_refused_before_it_is_read(tmp_path, monkeypatch):
    monkeypatch.setattr(rf.references, "MAX_BYTES", 100)
    path = _write(tmp_path, "ref.csv", "force,max_acting_time\n" + "20,0.6\n" * 20)
    _refused(path, "a reference file holds at most")
    monkeypatch.setattr(rf.references, "MAX_BYTES", 10**9)
    monkeypatch.setattr(rf, "MAX_ROWS", 5)
    path = _write(
        tmp_path,
        "rows.csv",
        "force,duration,recovered\n" + "".join(f"20,{d / 10:.1f},1\n" for d in range(1, 7)),
    )
    _refused(path, "6 rows", "at most 5")


def test_a_large_file_is_read_and_scored_in_seconds(tmp_path):
    """The scorecard was built row by row (1.9 ms a row: 25 min for 796k rows); read and
    scored by columns now. 20,000 rows of a lab's trials and 20,000 of seven measures (160,000
    scorecard rows): 27 s row by row, 0.4 s by columns (2 shared cores); 5 s leaves room for a
    busy machine and still fails the row-by-row code."""
    n = 20_000
    forces = np.repeat(OURS["force"].to_numpy(), n // 3 + 1)[:n]
    durations = np.tile(np.arange(n // 3 + 1), 3)[:n] * 1e-4
    trials = pd.DataFrame(
        {
            "force": forces,
            "duration": durations.round(4),
            "recovered": (durations < 0.3).astype(int),
        }
    )
    trials.to_csv(tmp_path / "trials.csv", index=False)
    table = pd.DataFrame(
        {
            "force": np.linspace(1, 200, n).round(4),
            "max_acting_time": 0.45,
            "energy_total_01": 0.12,
            "energy_total_max": 3.5,
            "study_energy_total_01": 0.1,
            "study_energy_u1_01": 0.07,
            "study_energy_u2_01": 0.03,
            "study_energy_total_max": 2.0,
        }
    )
    table.to_csv(tmp_path / "table.csv", index=False)
    start = time.perf_counter()
    refs = rf.read_references([tmp_path / "trials.csv", tmp_path / "table.csv"])
    card = sc.scorecard(OURS, refs, runs=RUNS)
    seconds = time.perf_counter() - start
    assert len(card) == n + 7 * n
    assert seconds < 5, f"{seconds:.1f} s"


# --- one force tolerance -------------------------------------------------------------------------


@pytest.mark.parametrize("given, added", [(20.0001, False), (19.9999, False), (20.01, True)])
def test_one_force_tolerance_adds_and_matches_a_reference_force(tmp_path, given, added):
    """20.0001 N was neither added to the table run (numpy.isclose's tolerance) nor matched in
    it (1e-9 N): "force not in our table". Every step that adds reference forces (sweep and
    table, report, the API) and the matching now use the scorecard's one tolerance."""
    from mjx_balance import api
    from mjx_balance.cli.sweep import with_reference_forces

    refs = rf.read_references(_write(tmp_path, "ref.csv", f"force,max_acting_time\n{given},0.6\n"))
    table_forces = np.array([20.0, 50.0, 100.0])
    run = with_reference_forces(table_forces, refs, "table")
    assert (given in run) == added and len(run) == 3 + added
    # what the run's table then holds is what the reference's row is scored against
    ours = OURS.set_index("force").reindex(run).ffill().reset_index()
    row = sc.score(refs[0], ours).iloc[0]
    assert not row["status"].startswith("not computed"), row["status"]
    assert len(api._with_forces(table_forces, refs)) == 3 + added
    assert rf.reference_forces(refs, table_forces) == ([given] if added else [])
    assert rf.reference_forces(refs, tuple(table_forces)) == ([given] if added else [])


def test_a_reference_forces_within_the_tolerance_are_run_once(tmp_path):
    a = _write(tmp_path, "a.csv", "force,max_acting_time\n30,0.6\n")
    b = _write(tmp_path, "b.csv", "force,max_acting_time\n30.00001,0.6\n70,0.1\n")
    assert rf.reference_forces(rf.read_references([a, b])) == [30.0, 70.0]


def test_the_scorecard_applies_the_one_row_rules_to_whole_columns(tmp_path):
    """score() (by columns) gives what our_value / our_recovered give row by row."""
    ref = rf.read_reference(
        _write(
            tmp_path,
            "ref.csv",
            (
                "force,duration,recovered,max_acting_time,energy_total_01,energy_total_max,"
                "study_energy_total_01\n"
                "20.00001,0.3,1,0.6,0.05,5.5,0.04\n50,0.185,0,0.2,0.4,3.7,\n100,0.05,1,0.1,0.9,2.2,\n"
                "80,0.1,1,0.1,,,\n20,0.7,0,,,,\n"
            ),
        )
    )
    region = pd.DataFrame(
        {"force": [50.0, 100.0], "duration": [0.185, 0.05], "outcome": ["fell", "recovered"]}
    )
    card = sc.score(ref, OURS, runs=RUNS, region=region)
    for row in card.itertuples():
        if row.measure == "recovered":
            ours, how, status = sc.our_recovered(row.force, row.duration, OURS, region)
            assert row.tolerance_basis == (f"exact: {how}" if how else "")
        else:
            ours, unc, basis, status = sc.our_value(row.measure, row.force, OURS, RUNS)
            assert row.our_uncertainty == pytest.approx(unc, nan_ok=True)
            assert basis in row.tolerance_basis
        assert row.ours == pytest.approx(ours, nan_ok=True)
        assert row.status == (status or ("agrees" if row.within else "differs"))
    assert len(card) == 5 + 4 + 4 + 2 + 1  # each row's measures and recovered, in file order
    assert card["force"].tolist()[:5] == [20.00001] * 5


# --- several references of one name ----------------------------------------------------------


def _report_folder(out, convention="paper"):
    """A report folder's table of one convention, made up (no run)."""
    (out / convention / "table").mkdir(parents=True)
    OURS.to_csv(out / convention / "table" / "table.csv", index=False)


def test_several_files_of_one_name_are_each_kept_and_scored(tmp_path):
    """report --reference a/study.csv --reference b/study.csv --reference lab.txt exited 0
    but scored only b/study.csv (both copied to references/study.csv) and never lab.txt."""
    from mjx_balance.report.reproduction import (
        reference_files,
        report_scorecard,
        store_references,
    )

    out = tmp_path / "report"
    _report_folder(out)
    a = _write(tmp_path, "a/study.csv", "force,max_acting_time,source\n20,0.6,Paper A\n")
    b = _write(tmp_path, "b/study.csv", "force,max_acting_time,source\n20,0.9,Paper B\n")
    lab = _write(tmp_path, "lab.txt", "force,duration,recovered\n20,0.3,1\n")
    stored = store_references(out, [str(a), str(b), str(lab)])
    assert [p.name for p in stored] == ["study.csv", "study_2.csv", "lab.csv"]
    assert [p.read_text() for p in stored] == [p.read_text() for p in (a, b, lab)]
    assert sorted(reference_files(out)) == sorted(stored)
    card = report_scorecard(out, ["paper"])
    scored = card.groupby("source")["reference"].first().to_dict()
    assert scored == {"study": 0.6, "study_2": 0.9, "lab": 1.0}
    assert set(card.loc[card["source"] == "study_2", "citation"]) == {"Paper B"}
    # the labels are those the command line read the files with (before they were stored)
    assert [r.label for r in rf.read_references([a, b, lab])] == ["study", "study_2", "lab"]


def test_reference_files_keep_the_order_they_were_given_in(tmp_path):
    from mjx_balance.report.reproduction import reference_files, store_references

    paths = [
        _write(tmp_path, f"{i}/r.csv", f"force,max_acting_time\n20,0.{i}\n") for i in range(1, 12)
    ]
    stored = store_references(tmp_path / "out", paths)
    assert reference_files(tmp_path / "out") == stored


def test_labels_stay_unique_when_a_file_is_labelled_like_a_suffix(tmp_path):
    a = _write(tmp_path, "a.csv", "force,max_acting_time,label\n20,0.6,lab\n")
    b = _write(tmp_path, "b.csv", "force,max_acting_time,label\n20,0.6,lab_2\n")
    c = _write(tmp_path, "c.csv", "force,max_acting_time,label\n20,0.6,lab\n")
    assert [r.label for r in rf.read_references([a, b, c])] == ["lab", "lab_2", "lab_3"]


# --- the API -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "ours, words",
    [
        (pd.DataFrame(), ["ours", "needs the column force", "its columns: none"]),
        (pd.DataFrame({"F": [20.0], "max_acting_time": [0.5]}), ["ours", "force", "F"]),
        (
            pd.DataFrame({"force": ["twenty"], "max_acting_time": [0.5]}),
            ["ours", "force must hold numbers"],
        ),
    ],
)
def test_the_api_refuses_a_table_without_a_force_column(tmp_path, ours, words):
    """mb.scorecard(pd.DataFrame(), f) raised KeyError 'force' from inside."""
    ref = _write(tmp_path, "ref.csv", "force,max_acting_time\n20,0.6\n")
    with pytest.raises(ValueError) as info:
        mb.scorecard(ours, ref)
    for word in words:
        assert word in str(info.value)


def test_a_table_without_max_acting_time_scores_what_it_has(tmp_path):
    ref = _write(tmp_path, "ref.csv", "force,duration,recovered,energy_total_01\n20,0.3,1,0.05\n")
    card = mb.scorecard(OURS[["force", "energy_total_01"]], ref)
    assert card["status"].tolist() == ["agrees", "not computed: our table has no max_acting_time"]


@pytest.mark.parametrize(
    "reference, words",
    [
        (123, ["reference", "int 123", "a CSV path"]),
        ([None], ["reference", "NoneType"]),
        (b"ref.csv", ["reference", "bytes"]),
        ({"a": 1}, ["reference", "dict"]),
    ],
)
def test_the_api_refuses_a_reference_of_another_type(tmp_path, reference, words):
    """mb.scorecard(folder, 123) raised a TypeError from inside pathlib."""
    OURS.to_csv(tmp_path / "table.csv", index=False)
    with pytest.raises(TypeError) as info:
        mb.scorecard(tmp_path, reference)
    for word in words:
        assert word in str(info.value)


@pytest.mark.parametrize("ours", [123, None, [OURS]])
def test_the_api_refuses_ours_of_another_type(tmp_path, ours):
    ref = _write(tmp_path, "ref.csv", "force,max_acting_time\n20,0.6\n")
    with pytest.raises(TypeError, match="ours: expected a sweep or table folder"):
        mb.scorecard(ours, ref)


def test_a_folder_whose_table_lost_its_force_column_is_named(tmp_path):
    OURS.drop(columns="force").to_csv(tmp_path / "table.csv", index=False)
    ref = _write(tmp_path, "ref.csv", "force,max_acting_time\n20,0.6\n")
    with pytest.raises(ValueError, match="table.csv: our table needs the column force"):
        mb.scorecard(tmp_path, ref)


# --- the command line --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, words",
    [
        ("force,max_acting_time\n20,0.35,\n", ["line 2", "3 fields"]),
        ("force,max_acting_time\ninf,0.35\n", ["line 2", "force must be a finite number", "'inf'"]),
        ("force;max_acting_time\n20;0.35\n", ["separator must be a comma"]),
    ],
)
def test_the_command_line_refuses_a_bad_reference_before_anything_is_written(
    tmp_path, capsys, fake_rollout, text, words
):
    ref = _write(tmp_path, "ref.csv", text)
    out = tmp_path / "out"
    for command in (
        ["table", "--forces", "20"],
        ["sweep", "--forces", "20", "--durations", "0.5"],
        ["report", "--scale", "tiny"],
    ):
        code, err = run_cli([*command, "--reference", str(ref), "--out", str(out)], capsys)
        assert_refused(code, err, str(ref), *words)
        assert not out.exists()


def test_the_command_line_refuses_a_huge_reference_file_by_its_size(tmp_path, capsys, monkeypatch):
    from mjx_balance.studies import references

    monkeypatch.setattr(references, "MAX_BYTES", 10)
    ref = _write(tmp_path, "ref.csv", "force,max_acting_time\n20,0.6\n")
    code, err = run_cli(["table", "--reference", str(ref), "--out", str(tmp_path / "o")], capsys)
    assert_refused(code, err, "--reference", "at most")


def test_table_says_only_what_it_wrote(tmp_path, capsys, fake_rollout):
    """ "wrote scorecard.csv and scorecard.png" when a reference of recovered pushes only gave
    no panel (and no PNG); the figure an earlier reference left is removed with it."""
    from mjx_balance.cli import main

    out = tmp_path / "out"
    table = _write(tmp_path, "t.csv", "force,max_acting_time\n20,1.5\n")
    assert main(["table", "--forces", "20", "--reference", str(table), "--out", str(out)]) == 0
    said = capsys.readouterr()
    lines = [line for line in (said.out + said.err).splitlines() if "scorecard" in line]
    assert len(lines) == 1 and "scorecard.csv and" in lines[0] and "scorecard.png" in lines[0]
    assert (out / sc.SCORECARD_FIGURE).read_bytes()[:4] == b"\x89PNG"
    lab = _write(tmp_path, "lab.csv", "force,duration,recovered\n20,0.5,1\n20,2.0,0\n")
    assert main(["table", "--forces", "20", "--reference", str(lab), "--out", str(out)]) == 0
    said = capsys.readouterr()
    lines = [line for line in (said.out + said.err).splitlines() if "scorecard" in line]
    assert lines == [f"wrote {out / sc.SCORECARD}"], said
    assert not (out / sc.SCORECARD_FIGURE).exists()


# --- the figure and the report -------------------------------------------------------------------


@pytest.mark.parametrize("measures", [1, 2, 3, 4])
def test_the_scorecard_figure_draws_every_text_inside_it(tmp_path, measures):
    """A one-panel scorecard.png had its title cut on both sides."""
    from mjx_balance.figures import style
    from mjx_balance.figures.scorecard import scorecard_figure

    columns = ["max_acting_time", "energy_total_01", "energy_total_max", "study_energy_total_01"][
        :measures
    ]
    ref = rf.read_reference(
        _write(tmp_path, "r.csv", f"force,{','.join(columns)}\n20,{','.join(['0.5'] * measures)}\n")
    )
    fig = scorecard_figure(sc.score(ref, OURS, runs=RUNS), table=OURS)
    assert [t.get_text() for t in style.outside(fig)] == []
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_a_dollar_in_a_label_is_drawn_as_written(tmp_path):
    """lab $5 of $10 was drawn as mathematics ("lab 5of10" in italics)."""
    from mjx_balance.figures.scorecard import scorecard_figure

    ref = rf.read_reference(
        _write(tmp_path, "r.csv", "force,max_acting_time,label\n20,0.6,lab $5 of $10\n")
    )
    fig = scorecard_figure(sc.score(ref, OURS), table=OURS)
    fig.draw_without_rendering()
    legend = next(t for t in fig.axes[0].get_legend().get_texts() if "lab" in t.get_text())
    assert legend.get_text() == r"lab \$5 of \$10 (within)"
    parsed, *_ = legend._preprocess_math(legend.get_text())
    assert legend._preprocess_math(legend.get_text())[1] is False and "$5" in parsed
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_the_report_scorecard_table_carries_the_citation(tmp_path):
    from mjx_balance.report.reproduction import scorecard_section, store_references

    out = tmp_path / "report"
    _report_folder(out, "joint")
    ref = _write(
        tmp_path,
        "lab.csv",
        'force,max_acting_time,source\n20,0.6,"Doe & Roe, J. Made Up 2026"\n50,0.2,\n',
    )
    store_references(out, [ref])
    (tmp_path / "figures").mkdir()
    section = scorecard_section(out, ["joint"], tmp_path / "figures")
    table = next(b for b in section["blocks"] if b["kind"] == "table")
    assert table["header"][-1] == "citation"
    assert [row[-1] for row in table["rows"]] == ["[1]", ""]
    assert table["notes"] == ["Doe & Roe, J. Made Up 2026"]
    reading = section["blocks"][0]["text"]
    assert "Sources: lab: Doe & Roe, J. Made Up 2026." in reading


def test_a_table_says_when_nothing_uses_a_points_reference(tmp_path, capsys, fake_rollout):
    """`table --reference points.csv` (pushes to draw, no measure to score) exited 0 with no
    scorecard and no word: it says why nothing uses the file, and a sweep's folder draws it."""
    from mjx_balance.cli import main

    points = _write(tmp_path, "points.csv", "force,duration\n20,0.5\n")
    out = tmp_path / "out"
    assert main(["table", "--forces", "20", "--reference", str(points), "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert f"reference {points}: its pushes (force, duration) are drawn on a region map" in (
        said.out + said.err
    )
    assert not (out / sc.SCORECARD).exists()
    sweep = tmp_path / "sweep"
    assert main(["sweep", "--forces", "20", "--durations", "0.5", "--out", str(sweep)]) == 0
    capsys.readouterr()
    assert main(["table", "--forces", "20", "--reference", str(points), "--out", str(sweep)]) == 0
    assert "drawn on a region map" not in "".join(capsys.readouterr())
