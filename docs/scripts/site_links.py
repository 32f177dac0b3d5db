"""A hook of the documentation site (mkdocs.yml, ``hooks``): README.md's links name the docs
pages from the repository's root (``[docs/model.md](docs/model.md)``, as GitHub shows them);
a page that includes README text (pymdownx.snippets, ``--8<-- "README.md:commands"``) lies in
docs/, so there they are made relative to it (``model.md``) and the strict build checks them
like any other link. Only links whose target starts with ``docs/`` change; the text is
README.md's own, never copied.
"""

from __future__ import annotations

import re

from markdown import Extension
from markdown.preprocessors import Preprocessor

DOCS_LINK = re.compile(r"\]\(docs/([^)\s]+)\)")


class _DocsLinks(Preprocessor):
    def run(self, lines: list[str]) -> list[str]:
        return [DOCS_LINK.sub(r"](\1)", line) for line in lines]


class _Extension(Extension):
    def extendMarkdown(self, md) -> None:
        # after pymdownx.snippets (priority 32), so the included lines are the ones rewritten
        md.preprocessors.register(_DocsLinks(md), "readme_docs_links", 31)


def on_config(config):
    config.markdown_extensions.append(_Extension())
    return config
