"""Every figure of the documentation site is the package's own drawing: each file in
docs/figures/ is drawn again by docs/scripts/site_figures.py from the command whose output it
is (no figure pasted without its command), and each figure the script lists is on a page."""

from __future__ import annotations

from support import REPO, docs_script


def _commands() -> dict:
    return docs_script("site_figures").COMMANDS


def test_every_site_figure_has_the_command_that_draws_it():
    figures = {p.name for p in (REPO / "docs" / "figures").iterdir() if p.is_file()}
    assert figures == set(_commands()), "docs/figures/ against docs/scripts/site_figures.py"


def test_every_listed_figure_is_on_a_page():
    pages = "".join(p.read_text() for p in (REPO / "docs").glob("*.md"))
    unused = [name for name in _commands() if f"figures/{name}" not in pages]
    assert unused == []
