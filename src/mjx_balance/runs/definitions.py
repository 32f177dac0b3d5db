"""Sweep definitions: the built-in default sweep and the sweep TOML files.

A sweep definition holds [body]/[controller]/[scenario] overrides of a base configuration and
a [sweep] table (forces, durations, table_forces, chunk, physics); the command line overrides
both.
The package ships its definitions (the default sweep, the dense maps, the studies) as package
data in ``mjx_balance/sweeps/*.toml``, found with ``importlib.resources`` (:func:`sweeps_dir`),
so an installed wheel has them too; :func:`find_sweep` accepts a path or a shipped name.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from ..model.params import Config, ParameterError
from ..model.config_files import read_toml
from ..model.subject import with_sections

# The robustness table of the study (docs/study.md, "The study's Table 2, row by row").
STUDY_TABLE_FORCES = (5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 120)

# The built-in default sweep (the README's main job; the same as the shipped default.toml): a coarse
# region map and a short table that finish in a few minutes on a 2-core CPU.
DEFAULT_SWEEP: dict[str, Any] = {
    "forces": "0:150:10",
    "durations": "0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5",
    "table_forces": "20,50,80,100,120",
    "chunk": 64,
}

_SWEEP_KEYS = ("forces", "durations", "table_forces", "chunk", "physics")


def sweeps_dir() -> Path:
    """The folder of the shipped sweep definitions (package data ``mjx_balance/sweeps``).

    The package is installed as files (a wheel or an editable install), so the resource is a
    folder on disk."""
    folder = resources.files("mjx_balance") / "sweeps"
    return Path(str(folder))


def shipped_sweeps() -> list[str]:
    """The names of the shipped sweep definitions (without ``.toml``), sorted."""
    return sorted(p.stem for p in sweeps_dir().glob("*.toml"))


def find_sweep(name: str | Path) -> Path:
    """A sweep definition file: ``name`` itself when it is a file, else the shipped definition
    of that name (``region_dense_paper`` or ``region_dense_paper.toml``); ParameterError naming
    the shipped ones otherwise."""
    path = Path(name)
    if path.is_file():
        return path
    if path.parent == Path(".") and path.name:
        shipped = sweeps_dir() / (path.name if path.suffix == ".toml" else f"{path.name}.toml")
        if shipped.is_file():
            return shipped
    raise ParameterError(
        f"{str(name)!r} not found: neither a file nor a shipped sweep "
        f"definition ({', '.join(shipped_sweeps())})"
    )


@dataclass
class SweepDefinition:
    """A sweep TOML: configuration overrides plus the [sweep] table."""

    config: Config
    forces: Any = None
    durations: Any = None
    table_forces: Any = None
    chunk: int | None = None
    physics: str | None = None  # "auto", "mjx" or "c" (None: the command line's, else auto)


def load_sweep(path: str | Path | None, base: Config) -> SweepDefinition:
    """Read a sweep definition: optional [body]/[controller]/[scenario] (overriding ``base``)
    and a [sweep] table with forces, durations, table_forces (grid strings or number lists),
    chunk and physics. ``None`` gives the built-in default sweep (DEFAULT_SWEEP)."""
    if path is None:
        return SweepDefinition(base, **DEFAULT_SWEEP)
    path = Path(path)
    data = read_toml(path, "sweep definition")
    for section, values in data.items():
        if not isinstance(values, dict):
            raise ParameterError(f"{path}: {section} must be a table ([{section}]), got {values!r}")
    sweep = data.pop("sweep", {})
    if not isinstance(sweep, dict):
        raise ParameterError(f"{path}: [sweep] must be a table")
    unknown = sorted(set(sweep) - set(_SWEEP_KEYS))
    if unknown:
        raise ParameterError(
            f"{path}: [sweep] has unknown key(s) {', '.join(unknown)}; "
            f"known: {', '.join(_SWEEP_KEYS)}"
        )
    try:
        config = with_sections(base, data) if data else base
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None
    chunk = sweep.get("chunk")
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1):
        raise ParameterError(f"{path}: [sweep] chunk must be an integer >= 1, got {chunk!r}")
    physics = sweep.get("physics")
    if physics is not None and physics not in ("auto", "mjx", "c"):
        raise ParameterError(
            f'{path}: [sweep] physics must be "auto", "mjx" or "c", got {physics!r}'
        )
    return SweepDefinition(
        config,
        sweep.get("forces"),
        sweep.get("durations"),
        sweep.get("table_forces"),
        chunk,
        physics,
    )
