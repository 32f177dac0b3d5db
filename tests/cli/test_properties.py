"""Property-based tests of the contract at the edges: whatever configuration, grid or
argument a user gives, the answer is either a run or a clear refusal (a ParameterError, which is
a ValueError; exit 2 with one line and nothing written), never a traceback or a silently wrong
result.

Hypothesis with ``derandomize=True`` (the same examples on every machine and run) and no example
database. The sweeps run with the sweep tests' stand-in rollout (no compile: values vary, shapes
do not), so an example costs a fraction of a second; the validation itself (QP, conditioning,
the batched closed loop's build) is the real one.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support import DEFAULT_BATCH, FakeThresholdBatch

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.model.params import (
    BodyParams,
    Config,
    ControllerParams,
    ParameterError,
    ScenarioParams,
)

PROPERTY = settings(
    derandomize=True, database=None, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
SECTIONS = {"body": BodyParams, "controller": ControllerParams, "scenario": ScenarioParams}
FIELDS = [(section, f.name) for section, cls in SECTIONS.items() for f in dataclasses.fields(cls)]

# Values from the ordinary to the absurd, of every type a user may hand over.
NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300, 0.01, 0.5, 2.0, 20.0, 100.0]),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.builds(np.float32, st.floats(width=32, allow_nan=False, allow_infinity=False)),
    st.builds(np.int64, st.integers(min_value=-(2**40), max_value=2**40)),
)
VALUES = st.one_of(
    NUMBERS, st.booleans(), st.text(max_size=5), st.none(), st.lists(NUMBERS, max_size=5)
)


def fake_batch(config, **_engine):
    return FakeThresholdBatch()


@settings(PROPERTY, max_examples=200)
@given(field=st.sampled_from(FIELDS), value=VALUES)
def test_a_configuration_is_built_or_refused_with_a_parameter_error(field, value):
    section, name = field
    try:
        config = Config().replace(**{section: {name: value}})
    except ParameterError as exc:
        assert f"{name}" in str(exc) or section in str(exc)
        return
    assert isinstance(config, Config)  # accepted: it round-trips through its own dict
    assert Config().replace(**config.to_dict()) == config


SET_VALUES = st.one_of(
    st.sampled_from(
        [
            "0",
            "-1",
            "1e-300",
            "1e300",
            "nan",
            "inf",
            "true",
            "abc",
            "[0, 0]",
            "[1e300, 1e300]",
            "2.5",
            "200",
            "0.002",
            "1e-9",
        ]
    ),
    st.floats(allow_nan=False, allow_infinity=False, width=32).map(repr),
)
GRIDS = st.one_of(
    st.sampled_from(
        [
            "0,60",
            "0:120:20",
            "10",
            "-10,10",
            "abc",
            "",
            "5:1:1",
            "0:1:0",
            "1e300",
            "nan",
            "0,0",
            "1,2,x",
        ]
    ),
    st.lists(st.floats(min_value=-500, max_value=500, allow_nan=False), min_size=1, max_size=4).map(
        lambda xs: ",".join(repr(x) for x in xs)
    ),
)


@settings(PROPERTY, max_examples=12)
@given(
    field=st.sampled_from(FIELDS),
    value=SET_VALUES,
    forces=GRIDS,
    durations=st.sampled_from(["0.1", "0.1,0.5", "0:1:0.25", "-1", "100", "0.0031"]),
)
def test_the_command_line_runs_or_refuses_with_one_line(field, value, forces, durations):
    section, name = field
    with (
        tempfile.TemporaryDirectory() as tmp,
        mock.patch(DEFAULT_BATCH, fake_batch),
        mock.patch("sys.stderr") as stderr,
    ):
        out = Path(tmp) / "out"
        try:
            code = main(
                [
                    "-q",
                    "sweep",
                    "--forces",
                    forces,
                    "--durations",
                    durations,
                    "--set",
                    f"{section}.{name}={value}",
                    "--set",
                    "scenario.t_end=2",
                    "--out",
                    str(out),
                ]
            )
        except SystemExit as exc:  # argparse's refusal of a value it parses itself
            code = exc.code
        written = "".join(str(call.args[0]) for call in stderr.write.call_args_list)
        assert "Traceback" not in written
        assert code in (0, 2), (code, written)
        if code == 2:
            assert not out.exists()  # refused before anything was written
            errors = [line for line in written.splitlines() if "error:" in line]
            assert len(errors) == 1, written
        else:
            assert (out / "region.parquet").exists()


ARGUMENTS = st.one_of(
    VALUES,
    st.sampled_from(["0:60:20", "10,20", "abc"]),
    st.builds(np.array, st.lists(NUMBERS, min_size=1, max_size=3)),
)
SIZES = st.one_of(
    st.none(),
    st.integers(min_value=-3, max_value=70),
    st.booleans(),
    st.floats(allow_nan=True),
    st.text(max_size=3),
    st.builds(np.int32, st.integers(min_value=-3, max_value=70)),
)


@settings(PROPERTY, max_examples=15)
@given(forces=ARGUMENTS, chunk=SIZES, slots=SIZES)
def test_the_api_runs_or_refuses_with_a_value_error(forces, chunk, slots):
    config = Config().replace(scenario={"t_end": 2.0})
    with mock.patch(DEFAULT_BATCH, fake_batch):
        try:
            region = mb.sweep(forces, [0.1, 0.5], config, chunk=chunk, slots=slots)
        except ValueError as exc:  # ParameterError is one
            assert str(exc)
            return
    # accepted: the forces were numbers (never a bool), the sizes whole numbers >= 1 or None
    values = [forces] if np.ndim(forces) == 0 and not isinstance(forces, str) else forces
    assert not isinstance(forces, bool)
    for size in (chunk, slots):
        assert size is None or (
            not isinstance(size, bool)
            and float(size) >= 1
            and float(size) == math.floor(float(size))
        )
    assert len(region) == 2 * len(set(region["force"])) and len(values) >= 1


@pytest.mark.parametrize("forces", [True, [True], ["20"], [None], {"f": 1}, [3.5e38]])
def test_examples_the_property_found_on_the_old_api(forces):
    # accepted before (bools as 1 N, strings as numbers) or a traceback (3.5e38 N: inf in
    # float32): now refused, naming the argument
    with pytest.raises(ValueError, match="forces"):
        mb.sweep(forces, [0.1], Config().replace(scenario={"t_end": 2.0}))
