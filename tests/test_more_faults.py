"""Damaged report records and sweep definitions end in one clear line, not a traceback."""

from __future__ import annotations

import pytest

from mjx_balance import cli
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.report import PLANS
from mjx_balance.studies.experiments import open_record, read_record
from mjx_balance.runs import load_sweep

DAMAGED = [
    ("not json", "{not json", "damaged"),
    ("a list", "[1, 2]", "holds a list"),
    ("no config", '{"conventions": ["paper"]}', "has no configuration"),
    ("no conventions", '{"config": {}}', "has no list of conventions"),
]


@pytest.mark.parametrize("case,text,words", DAMAGED, ids=[c[0] for c in DAMAGED])
def test_html_only_on_a_damaged_record_is_one_line(tmp_path, capsys, case, text, words):
    (tmp_path / "report.json").write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = cli.main(["report", "--html-only", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mjx-balance: error: "), err
    assert "report.json" in lines[0] and words in lines[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_a_new_run_refuses_a_damaged_record(tmp_path):
    (tmp_path / "report.json").write_text("[]")
    with pytest.raises(ParameterError, match="holds a list"):
        open_record(tmp_path, Config(), PLANS["tiny"], "reference", ("paper",))


def test_a_missing_record_is_empty_for_a_new_run_and_an_error_otherwise(tmp_path):
    assert read_record(tmp_path / "report.json", required=False) == {}
    with pytest.raises(ParameterError, match="not found"):
        read_record(tmp_path / "report.json")


def test_sweep_definition_that_is_a_folder_or_binary_is_one_error(tmp_path):
    with pytest.raises(ParameterError, match="a folder, not a sweep definition"):
        load_sweep(tmp_path, Config())
    binary = tmp_path / "bad.toml"
    binary.write_bytes(b"\xff\xfe[sweep]\n")
    with pytest.raises(ParameterError, match="not UTF-8 text"):
        load_sweep(binary, Config())


def test_sweep_definition_section_must_be_a_table(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('controller = 3\n[sweep]\nforces = "0:10:5"\n')
    with pytest.raises(ParameterError, match=r"controller must be a table"):
        load_sweep(path, Config())
