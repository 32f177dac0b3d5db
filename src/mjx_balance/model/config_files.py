"""Configuration files and ``--set``: a configuration read from TOML (every value not given
takes its default, a ``[subject]`` table puts that person's body on it), written as TOML, and
``--set SECTION.KEY=VALUE`` overrides on top, each checked by the records' rules
(``params.py``) with one-line errors that name the file or the option."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from PyPI (a dependency there: pyproject.toml)
    import tomli as tomllib

from .params import SECTIONS, Config, ParameterError, build_section
from .subject import Subject, as_subject, check_subject_conflicts


def config_from_dict(data: dict[str, Any]) -> Config:
    """Build a validated Config from a nested dict (missing keys take their defaults). A
    ``subject`` table (height, mass, sex, ankle_strength, hip_strength) puts that person's body
    on the configuration the other sections make (:meth:`Config.replace`'s ``subject``)."""
    if "subject" in data:
        rest = {k: v for k, v in data.items() if k != "subject"}
        subject = as_subject(data["subject"])
        check_subject_conflicts(subject, rest)
        return subject.config(config_from_dict(rest))
    unknown = sorted(set(data) - set(SECTIONS))
    if unknown:
        raise ParameterError(
            f"unknown section(s) {', '.join(unknown)}; known sections: body, controller, "
            "scenario, subject"
        )
    parts = {}
    for name, cls in SECTIONS.items():
        section = data.get(name, {})
        if not isinstance(section, dict):
            raise ParameterError(f"section {name!r} must be a table")
        parts[name] = build_section(cls, name, section)
    return Config(**parts)


def read_toml(path: str | Path, what: str = "configuration file") -> dict[str, Any]:
    """The TOML file at ``path`` as a dict; ParameterError naming the file (and ``what`` it
    should be) when it is missing, a folder, unreadable, not UTF-8 or not valid TOML."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError(f"{what} not found: {path}") from None
    except IsADirectoryError:
        raise ParameterError(f"{path}: a folder, not a {what}") from None
    except OSError as exc:
        raise ParameterError(f"{path}: cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise ParameterError(
            f"{path}: not UTF-8 text (byte {exc.start}); a {what} is TOML"
        ) from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{path}: not valid TOML: {exc}") from None


def load_config(path: str | os.PathLike[str]) -> Config:
    """Load a TOML configuration file; every value not given takes its default.

    Args:
        path: The TOML file: ``[body]``, ``[controller]``, ``[scenario]`` and optionally
            ``[subject]`` tables (the shipped ones are in the repository's sweeps/; the
            command line's ``--config human`` finds them by name).

    Returns:
        The ``Config``.

    Raises:
        ParameterError: an unknown key, a bad value or an unreadable file, naming it.
    """
    path = Path(path)
    data = read_toml(path)
    if "sweep" in data:  # a sweep definition: its grid needs the sweep command
        raise ParameterError(
            f"{path}: a sweep definition (its [sweep] table is a grid): run it with "
            f"mjx-balance sweep --sweep {path.stem}; a --config file gives body, controller, "
            "scenario and subject only"
        )
    try:
        return config_from_dict(data)
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None


def dumps_config(config: Config) -> str:
    """The configuration as TOML text (every field written; ``tomli_w``)."""
    import tomli_w

    return tomli_w.dumps(config.to_dict())


def with_convention(config: Config, convention: str | None) -> Config:
    """``config`` with the controller's convention replaced (unchanged for None)."""
    return config.replace(controller={"convention": convention}) if convention else config


def parse_override(text: str) -> tuple[str, str, Any]:
    """One ``--set SECTION.KEY=VALUE`` as (section, key, value). VALUE is read as a TOML value
    (``30``, ``6.0``, ``true``, ``[-10, 10]``, ``"joint"``); anything that is not one is taken
    as a bare string (``joint``), which the configuration's rules then check."""
    name, sep, raw = str(text).partition("=")
    section, dot, key = name.strip().partition(".")
    if not sep or not dot or not section or not key.strip() or "." in key:
        raise ParameterError(
            f"--set {text!r}: expected SECTION.KEY=VALUE, e.g. "
            "controller.horizon=30 (sections: body, controller, scenario)"
        )
    raw = raw.strip()
    if not raw:
        raise ParameterError(f"--set {text!r}: give a value after '='")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return section, key.strip(), value


def apply_overrides(config: Config, overrides: "list[str] | tuple[str, ...] | None") -> Config:
    """``config`` with ``--set SECTION.KEY=VALUE`` overrides on top, validated as a TOML file's
    values are (:func:`config_from_dict`: the same rules and messages, prefixed ``--set:``)."""
    if not overrides:
        return config
    data = config.to_dict()
    for text in overrides:
        section, key, value = parse_override(text)
        data.setdefault(section, {})[key] = value
    try:
        return config_from_dict(data)
    except ParameterError as exc:
        raise ParameterError(f"--set: {exc}") from None


def run_config(
    path: str | Path | None = None,
    convention: str | None = None,
    overrides: "list[str] | tuple[str, ...] | None" = None,
    subject: Subject | None = None,
) -> Config:
    """A run's configuration: the TOML file at ``path`` (or the defaults) with ``subject``
    (``--subject``) in place of its [subject] table, then ``--set`` ``overrides``, then
    ``convention`` on top (None keeps the configuration's)."""
    if subject is None:
        config = load_config(path) if path else Config()
    else:
        data = dict(read_toml(path)) if path else {}
        data["subject"] = subject
        try:
            config = config_from_dict(data)
        except ParameterError as exc:
            raise ParameterError(f"{path}: {exc}" if path else str(exc)) from None
    return with_convention(apply_overrides(config, overrides), convention)
