"""The package's own files agree with the code and with each other: the README's list of the
Python API is ``mjx_balance.__all__``, LICENSE is the Apache License 2.0 that pyproject.toml
declares, CITATION.cff is a valid citation of this version, CHANGELOG.md starts where Keep a
Changelog starts."""

from __future__ import annotations

import hashlib
import re

import tomllib
from support import REPO

import mjx_balance

PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]
# sha256 of https://www.apache.org/licenses/LICENSE-2.0.txt (11358 bytes), the file every
# Apache-2.0 package ships (jax's, mujoco's, mujoco-mjx's are byte-identical)
APACHE_2_0_SHA256 = "cfc7749b96f63bd31c3c42b5c471bf756814053e847c10f3eb003417bc523d30"
STUDY = "Human-like Balance Recovery Based on Numerical Model Predictive Control Strategy"


def section(text: str, title: str) -> str:
    """A README section: from its ``## title`` line to the next ``## `` heading."""
    found = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert found, f"README.md has no '## {title}' section"
    return found.group(1)


def readme_api_names(text: str) -> list[str]:
    """The names of the README's API list: the bullets of '## Python API' that start with a
    name in backquotes followed by a colon (``- `simulate`: ...``)."""
    return re.findall(r"^- `([A-Za-z_][A-Za-z0-9_]*)`:", section(text, "Python API"), re.M)


def test_the_readme_lists_the_api_as_the_code_exports_it():
    listed = readme_api_names((REPO / "README.md").read_text(encoding="utf-8"))
    assert len(listed) == len(set(listed)), f"listed twice: {sorted(listed)}"
    exported = set(mjx_balance.__all__)
    missing = sorted(exported - set(listed))
    assert not missing, f"in mjx_balance.__all__ but not in README's API list: {missing}"
    extra = sorted(set(listed) - exported)
    assert not extra, f"in README's API list but not in mjx_balance.__all__: {extra}"


def test_the_api_list_parser_reads_bullets_only():
    text = (
        "## Python API\n\nexports\n\n- `simulate`: pushes\n  `sweep` on a continuation\n"
        "- `table`: tables\n* `basin`: other bullet\n\n## Layout\n\n- `cli`: not API\n"
    )
    assert readme_api_names(text) == ["simulate", "table"]


def test_the_license_is_apache_2_0_as_pyproject_says():
    text = (REPO / "LICENSE").read_text(encoding="utf-8")
    assert text.lstrip().startswith(
        "Apache License\n                           Version 2.0, January 2004"
    )
    for part in (
        "TERMS AND CONDITIONS FOR USE, REPRODUCTION, AND DISTRIBUTION",
        "END OF TERMS AND CONDITIONS",
        "APPENDIX: How to apply the Apache License",
    ):
        assert part in text
    assert hashlib.sha256((REPO / "LICENSE").read_bytes()).hexdigest() == APACHE_2_0_SHA256, (
        "LICENSE differs from the Apache License 2.0's text"
    )
    assert PYPROJECT["license"] == "Apache-2.0"  # the SPDX identifier of that text
    assert PYPROJECT["license-files"] == ["LICENSE"]  # shipped in the wheel and the sdist


def read_cff(text: str) -> dict:
    """CITATION.cff as data: PyYAML when installed, else its top-level keys (the values of
    one-line keys; others as True), enough for the required keys' check."""
    try:
        import yaml
    except ImportError:
        found: dict = {}
        for key, value in re.findall(r"^([A-Za-z][A-Za-z0-9-]*):[ \t]*(.*)$", text, re.M):
            found[key] = (
                value.strip().strip("'\"") if value.strip() not in ("", ">-", "|") else True
            )
        return found
    return yaml.safe_load(text)


def test_the_citation_file_cites_this_version_and_the_study():
    cff = read_cff((REPO / "CITATION.cff").read_text(encoding="utf-8"))
    for key in ("cff-version", "message", "title", "authors"):  # CFF 1.2.0's required keys
        assert cff.get(key), f"CITATION.cff lacks {key}"
    assert str(cff["cff-version"]) == "1.2.0"
    assert cff["title"] == "mjx_balance"
    assert str(cff["version"]) == PYPROJECT["version"]
    if mjx_balance.__version__ != "0.0.0+local":  # installed: its metadata's version
        assert str(cff["version"]) == mjx_balance.__version__
    assert cff["license"] == PYPROJECT["license"]
    if isinstance(cff["authors"], list):  # parsed by PyYAML: the whole structure
        assert [a.get("name") for a in cff["authors"]] == [a["name"] for a in PYPROJECT["authors"]]
        (study,) = cff["references"]
        assert study["type"] == "article" and study["title"] == STUDY
        assert study["journal"] == "IEEE Access"
        assert [a["family-names"] for a in study["authors"]] == ["Shen", "Chemori", "Hayashibe"]


def test_the_changelog_starts_with_unreleased_then_this_version():
    headings = re.findall(
        r"^## \[([^\]]+)\]", (REPO / "CHANGELOG.md").read_text(encoding="utf-8"), re.M
    )
    assert headings[:2] == ["Unreleased", PYPROJECT["version"]]
