"""One reading of a number wherever a user writes one (model.params.read_number): grids, pairs
and explore's queries read the same texts as the same numbers and refuse the rest by name.
Python's float() reads "50_0" as 500 and other scripts' digits as numbers; those are refused."""

import math

import pytest

from mjx_balance.model.params import ParameterError, read_number
from mjx_balance.runs.grid import check_durations, grid_values, parse_pairs

READ = {"50": 50.0, " -3.5 ": -3.5, "+.5": 0.5, "5.": 5.0, "1e-3": 1e-3, "2E2": 200.0}
REFUSED = ["50_0", "1_000", "\u0662\u0660", "0x10", "1e", ".", "5,0", "infinity", "1 0"]


@pytest.mark.parametrize("text, value", READ.items())
def test_a_number_as_written_is_read_alike_everywhere(text, value):
    assert read_number(text, "x") == value
    assert grid_values(text, "forces").tolist() == [value]
    forces, durations = parse_pairs(f"{text}:0.1")
    assert forces.tolist() == [value]


@pytest.mark.parametrize("text", REFUSED)
def test_anything_else_is_refused_by_name(text):
    with pytest.raises(ParameterError, match="^x: .* is not a number"):
        read_number(text, "x")
    with pytest.raises(ParameterError, match="forces"):
        grid_values(f"0,{text}", "forces")


def test_an_empty_text_is_not_a_number():
    with pytest.raises(ParameterError, match="is not a number"):
        read_number("  ", "x")


def test_inf_and_nan_are_read_and_refused_where_a_finite_number_is_needed():
    assert math.isinf(read_number("-inf", "x")) and math.isnan(read_number("NaN", "x"))
    with pytest.raises(ParameterError, match="finite"):
        grid_values("0,inf", "forces")


def test_a_duration_far_beyond_the_window_is_refused_as_written(recwarn):
    """1e300 s overflowed the whole-steps check (a RuntimeWarning, then "got inf")."""
    with pytest.raises(ParameterError, match=r"got 1e\+300"):
        check_durations([1e300], 12.0, physics_dt=0.002)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
