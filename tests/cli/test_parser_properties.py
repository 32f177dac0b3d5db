"""Every text a user gives, generated: grid specs, ``--pairs`` and pair files, ``--set``
overrides, TOML configurations, reference files, subjects files and explore's query strings.
Each generated input is either read to what it means (a round trip where one exists) or refused
with a ParameterError of one line; never another exception, never a silent misreading.

Texts are drawn from each format's own alphabet (digits, signs, points, exponents, separators,
words and a few characters from elsewhere) so that most examples come near a valid input.
Hypothesis with ``derandomize=True`` (the same examples on every machine) and no database: a
small count in the default run, a longer profile (``-m slow``) for the parsers that cost
microseconds an example.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mjx_balance.model.config_files import apply_overrides, load_config, parse_override
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.runs.grid import parse_grid, parse_pairs

# (default run, slow run) example counts
EXAMPLES = [pytest.param(150, id="default"), pytest.param(3000, id="long", marks=pytest.mark.slow)]
FEW = [pytest.param(25, id="default"), pytest.param(400, id="long", marks=pytest.mark.slow)]

NUMBER_BITS = ["0", "1", "2", "5", "9", "10", "0.05", "1.5", "-", "+", ".", "e", "E", "e-3"]
ODD_BITS = [" ", "inf", "nan", "_", "٢", "x", "1e400", "1e-400", "0x1", "\t", "", "--"]


def text_of(bits: list[str], separators: list[str], max_size: int = 12) -> st.SearchStrategy:
    """Texts joined from ``bits`` (a format's own pieces), its ``separators`` and odd pieces."""
    return st.lists(st.sampled_from(bits + separators + ODD_BITS), max_size=max_size).map("".join)


def holds(examples: int, strategy: st.SearchStrategy, check: Callable[[Any], None]) -> None:
    """Run ``check`` on ``examples`` generated values."""
    profile = settings(
        derandomize=True,
        database=None,
        deadline=None,
        max_examples=examples,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )
    profile(given(strategy)(check))()


def read_file_or_refused(parts: tuple, name: str, read: Callable[[Path], Any], word: str) -> Any:
    """``read`` of a file made of (header, rows); False when refused (in one line, naming the
    file or ``word``)."""
    head, body = parts
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_text("\n".join([head, *body]) + "\n")
        try:
            return read(path)
        except ParameterError as exc:
            one_line(exc, str(path), word)
            return False


def one_line(exc: ParameterError, *names: str) -> None:
    message = str(exc)
    assert message and "\n" not in message and len(message) < 600, message
    assert any(name in message for name in names), (names, message)


@pytest.mark.parametrize("examples", EXAMPLES)
def test_a_grid_spec_is_read_or_refused(examples):
    """Read: sorted, finite, each once, and the comma list of the values read back is the same
    grid (a round trip); a range's values are start + k step to float rounding."""

    def check(text):
        try:
            values = parse_grid(text, "forces")
        except ParameterError as exc:
            return one_line(exc, "forces")
        assert values.dtype == np.float64 and values.size >= 1
        assert np.all(np.isfinite(values)) and np.all(np.diff(values) > 0)
        again = parse_grid(",".join(repr(float(v)) for v in values), "forces")
        assert np.array_equal(again, values)
        if text.count(":") == 2:
            start, _, step = (float(p) for p in text.split(":"))
            k = np.arange(values.size)
            # the parser's values are the floats nearest start + k step as written; the float
            # sum here rounds start, k step and their sum, a few ulps (2.2e-16 relative each),
            # and its cancellation near 0 is bounded by ulps of |step|: 1e-12 is thousands of ulps
            assert np.allclose(values, start + k * step, rtol=1e-12, atol=1e-12 * abs(step))

    holds(examples, text_of(NUMBER_BITS, [":", ",", ", "]), check)


@pytest.mark.parametrize("examples", EXAMPLES)
def test_pairs_are_read_in_their_order_or_refused(examples):
    """Read: as many forces as durations, finite, in the order written (the text's items
    read back one by one give the same pairs)."""

    def check(text):
        try:
            forces, durations = parse_pairs(text, "--pairs")
        except ParameterError as exc:
            return one_line(exc, "--pairs")
        assert forces.shape == durations.shape and forces.size >= 1
        assert np.all(np.isfinite(forces)) and np.all(np.isfinite(durations))
        items = [item.strip() for item in text.split(",") if item.strip()]
        for item, f, d in zip(items, forces, durations):
            f1, d1 = parse_pairs(item, "--pairs")
            assert (f1[0], d1[0]) == (f, d)

    holds(examples, text_of(NUMBER_BITS, [":", ",", "20:0.1,"]), check)


@pytest.mark.parametrize("examples", FEW)
def test_a_pairs_file_is_read_or_refused(tmp_path, examples):
    header = st.sampled_from(["force,duration", "duration,force", "force", "Force , Duration", ""])
    rows = st.lists(text_of(NUMBER_BITS, [","], max_size=6), max_size=4)

    def check(parts):
        head, lines = parts
        path = tmp_path / "pairs.csv"
        path.write_text("\n".join([head, *lines]) + "\n")
        try:
            forces, durations = parse_pairs(str(path), "--pairs")
        except ParameterError as exc:
            return one_line(exc, "--pairs")
        assert forces.shape == durations.shape and forces.size >= 1
        assert np.all(np.isfinite(forces)) and np.all(np.isfinite(durations))

    check(("force,duration", ["0", ",,"]))  # found by the long profile: pandas' two lines
    holds(examples, st.tuples(header, rows), check)


KEYS = ["controller.horizon", "controller.r_diag", "body.foot_length", "scenario.t_end", "x.y"]


@pytest.mark.parametrize("examples", EXAMPLES)
@pytest.mark.filterwarnings("ignore::mjx_balance.model.params.ParameterWarning")
def test_a_set_override_is_applied_or_refused(examples):
    """Applied: the configuration holds the value as read (a round trip through its dict)."""
    values = text_of(
        NUMBER_BITS + ["true", "[", "]", '"', "joint", "1e3"], [",", "=", "."], max_size=8
    )

    def check(parts):
        key, value = parts
        text = f"{key}={value}"
        try:
            config = apply_overrides(Config(), [text])
        except ParameterError as exc:
            return one_line(exc, "--set")
        section, name, _ = parse_override(text)
        assert Config().replace(**config.to_dict()) == config
        assert name in config.to_dict()[section]

    holds(examples, st.tuples(st.sampled_from(KEYS + ["controller", "=1", ""]), values), check)


@pytest.mark.parametrize("examples", FEW)
def test_a_configuration_file_is_loaded_or_refused(examples):
    """Loaded: saving the configuration and loading it again gives it back."""
    lines = st.lists(
        st.one_of(
            st.sampled_from(["[body]", "[controller]", "[scenario]", "[other]", "[[x]]", "x ="]),
            st.tuples(
                st.sampled_from([k.split(".")[1] for k in KEYS]), text_of(NUMBER_BITS, ["["], 6)
            ).map(lambda kv: f"{kv[0]} = {kv[1]}"),
        ),
        max_size=6,
    )

    def check(rows):
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "config.toml"
            path.write_text("\n".join(rows) + "\n")
            try:
                config = load_config(path)
            except ParameterError as exc:
                return one_line(exc, str(path), "config")
            from mjx_balance.model.config_files import dumps_config

            path.write_text(dumps_config(config))
            assert load_config(path) == config

    holds(examples, lines, check)


@pytest.mark.parametrize("examples", FEW)
def test_a_reference_file_is_read_or_refused(examples):
    from mjx_balance.studies.reference_files import read_reference

    header = st.sampled_from(
        [
            "force,max_acting_time",
            "force,max_acting_time,source",
            "force,duration,recovered",
            "force,duration",
            "Force,Max_Acting_Time",
            "force;max_acting_time",
            "",
        ]
    )
    rows = st.lists(
        text_of(NUMBER_BITS + ["true", "false", "yes", "study"], [",", ";", '"'], 8), max_size=4
    )

    def check(parts):
        ref = read_file_or_refused(parts, "reference.csv", read_reference, "reference")
        assert ref is False or len(ref.frame) >= 1  # refused, or rows read

    holds(examples, st.tuples(header, rows), check)


@pytest.mark.parametrize("examples", FEW)
def test_a_subjects_file_is_read_or_refused(examples):
    from mjx_balance.studies.members import read_subjects

    header = st.sampled_from(
        ["id,height,mass,sex", "height,mass", "height,mass,sex,ankle_strength", "id,mass", ""]
    )
    rows = st.lists(
        text_of(NUMBER_BITS + ["male", "female", "ann", "s01", "1.7", "70"], [","], 8), max_size=4
    )

    def check(parts):
        members = read_file_or_refused(parts, "people.csv", read_subjects, "subjects")
        if members is False:
            return
        assert len({m.id for m in members}) == len(members) >= 1
        for member in members:
            assert math.isfinite(member.subject.height) and member.subject.height > 0

    holds(examples, st.tuples(header, rows), check)


@pytest.mark.parametrize("examples", EXAMPLES)
def test_an_explore_query_number_is_read_or_refused(examples):
    """explore's force and duration: one finite number each (runs.one_number), read as the
    command line reads it."""
    from urllib.parse import parse_qs

    from mjx_balance.report.explore.runs import one_number

    query = text_of(NUMBER_BITS + ["force=", "&", "%20", "%2B", "+"], ["&", "="], 10)

    def check(text):
        fields = parse_qs(text, keep_blank_values=True, max_num_fields=16)
        try:
            value = one_number(fields, "force")
        except ParameterError as exc:
            return one_line(exc, "force")
        assert math.isfinite(value)
        assert value == parse_grid(fields["force"][0], "force")[0]

    holds(examples, query.map(lambda q: "force=" + q), check)
