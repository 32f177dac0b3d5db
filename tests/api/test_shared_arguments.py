"""One checker for the arguments the API functions share (api.checked): a flag given as a
string, a progress given as text, an ``out`` that is a file or not a path, a size that is not a
whole number, each refused by name before any work, by every function that takes it."""

from __future__ import annotations

import inspect

import pytest

import mjx_balance as mb
from mjx_balance import api
from mjx_balance.model.params import ParameterError

# a first positional argument for the functions that need one (never reached: refused first)
FIRST = {
    "simulate": (),
    "sweep": ("0,50", "0.1"),
    "table": ("50",),
    "compare": (["a.toml", "b.toml"],),
    "cohort": ("subjects.csv",),
    "explore": ("folder",),
}
HOSTILE = [
    ("full_length", "no", TypeError),
    ("full_length", "false", TypeError),
    ("wait", None, TypeError),
    ("html_only", "yes", TypeError),
    ("browser", 1, TypeError),
    ("progress", "yes", TypeError),
    ("out", 123, TypeError),
    ("slots", 0, ParameterError),
    ("slots", 2.5, ParameterError),
    ("chunk", "8", ParameterError),
]


def _calls():
    for name in api.__all__:
        function = getattr(mb, name, None)
        if not inspect.isfunction(function) or not hasattr(function, "__wrapped__"):
            continue
        parameters = inspect.signature(function).parameters
        for argument, value, error in HOSTILE:
            if argument in parameters:
                yield pytest.param(name, argument, value, error, id=f"{name}-{argument}={value!r}")


def test_every_function_taking_out_flags_or_sizes_is_checked():
    """Every API function with one of the shared arguments goes through the one checker."""
    for name in api.__all__:
        function = getattr(mb, name, None)
        if not inspect.isfunction(function):
            continue
        shared = set(inspect.signature(function).parameters) & {
            *api.FLAGS,
            *api.SIZES,
            "progress",
            "out",
        }
        assert not shared or hasattr(function, "__wrapped__"), (name, shared)


@pytest.mark.parametrize("name, argument, value, error", list(_calls()))
def test_a_hostile_shared_argument_is_refused_by_name(
    name, argument, value, error, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)  # nothing a refused call could write lands in the repository
    kwargs = {argument: value}
    if "out" in inspect.signature(getattr(mb, name)).parameters and argument != "out":
        kwargs["out"] = tmp_path / "out"
    with pytest.raises(error, match=f"^{argument} = "):
        getattr(mb, name)(*FIRST.get(name, ()), **kwargs)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["sweep", "table", "compare", "basin", "cohort", "report"])
def test_out_as_a_file_is_refused_before_any_work(name, tmp_path):
    file = tmp_path / "results.csv"
    file.write_text("kept\n")
    with pytest.raises(ParameterError, match="is a file, not a folder"):
        getattr(mb, name)(*FIRST.get(name, ()), out=file)
    assert file.read_text() == "kept\n"


@pytest.mark.parametrize("name", ["compare", "cohort", "report"])
def test_a_required_out_is_not_none(name):
    with pytest.raises(TypeError, match="^out = None"):
        getattr(mb, name)(*FIRST.get(name, ()), out=None)


def test_every_api_name_stays_its_function_after_the_subpackages_load():
    """``mb.report`` was the ``mjx_balance.report`` subpackage once anything had imported it
    (the import system sets the package's attribute): every exported name is checked after
    the subpackages are loaded."""
    import importlib
    import pkgutil

    for module in pkgutil.iter_modules(mb.__path__):
        importlib.import_module(f"mjx_balance.{module.name}")
    import types

    for name in mb.__all__:
        assert not isinstance(getattr(mb, name), types.ModuleType), name
    assert mb.report is api.report
