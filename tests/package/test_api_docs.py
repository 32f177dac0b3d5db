"""The API reference (docs/api.md, built by mkdocstrings into the documentation site; mkdocs.yml)
lists every name of ``mjx_balance.__all__`` and nothing else, each as the object the name is,
and every one of them documents its arguments in Google style: an ``Args:`` (a class's
``Args:`` or ``Attributes:``) section naming each parameter of its signature, no more, and a
``Returns:`` section where it returns something. ``mkdocs build --strict`` (.ci/run) then fails
on an unresolved name, a broken link or a docstring griffe cannot read."""

from __future__ import annotations

import importlib
import inspect
import re

import pytest
from support import REPO

import mjx_balance as mb

API_PAGE = REPO / "docs" / "api.md"
TARGET = re.compile(r"^::: ([\w.]+)\s*$", re.MULTILINE)
NAMES = [n for n in mb.__all__ if n != "__version__"]
NOTHING_RETURNED = {"figure_style"}  # a context manager: the block's figures are its effect


def resolve(dotted: str):
    module, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(module), name)


def documented(doc: str, *sections: str) -> list[str]:
    """The item names of the docstring's first section among ``sections``."""
    lines = doc.splitlines()
    starts = [i for i, line in enumerate(lines) if line.strip() in {f"{s}:" for s in sections}]
    if not starts:
        return []
    names = []
    for line in lines[starts[0] + 1 :]:
        if line.strip() and not line.startswith(" "):
            break  # the next section
        item = re.match(r"^    (\*{0,2}\w+): ", line)
        if item:
            names.append(item.group(1).lstrip("*"))
    return names


def test_the_page_lists_every_public_name_as_the_object_it_is():
    targets = TARGET.findall(API_PAGE.read_text())
    objects = {id(resolve(t)): t for t in targets}
    assert len(objects) == len(targets), "a name listed twice"
    missing = [n for n in NAMES if id(getattr(mb, n)) not in objects]
    assert missing == [], f"not on docs/api.md: {missing}"
    assert len(targets) == len(NAMES), "docs/api.md lists a name mjx_balance does not export"


@pytest.mark.parametrize("name", NAMES)
def test_every_public_name_documents_its_arguments(name):
    obj = getattr(mb, name)
    doc = inspect.getdoc(obj) or ""
    params = [p for p in inspect.signature(obj).parameters if p != "self"]
    sections = ("Args", "Attributes") if inspect.isclass(obj) else ("Args",)
    assert documented(doc, *sections) == params, f"{name}: its Args: section against {params}"
    if inspect.isfunction(obj) and name not in NOTHING_RETURNED:
        assert "\nReturns:\n" in doc, f"{name}: no Returns: section"


def test_the_section_reader_fails_an_undocumented_argument():
    """The check can fail: a parameter missing from Args, or a section missing."""

    def f(a, b):
        """Do.

        Args:
            a: the first.
        """

    assert documented(inspect.getdoc(f), "Args") == ["a"] != ["a", "b"]
    assert documented("Do a thing.", "Args") == []
