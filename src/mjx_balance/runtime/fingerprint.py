"""The numerics a result was computed under: recorded in a folder's manifest and in every chunk,
compared when a run resumes a folder (docs/reliability.md).

Two kinds of fields:

- :data:`RESULT_KEYS` change a result's bits: JAX's x64 mode (MJX does some of its arithmetic
  in float64 when it is on, even on a float32 model), the XLA flags other than those known not
  to change numbers (the host device count: the engine's results do not depend on it,
  tests/rollout/test_engine.py), and JAX's default matmul precision. Resuming a folder under other
  values would merge rows computed differently: refused.
- :data:`INFO_KEYS` may change bits but are not the user's choice within a session: the
  package's, JAX's and MuJoCo's versions, and the CPU's vector ISA as XLA targets it. A
  difference is a warning (a chunk keeps the fingerprint it was computed under).

The physics path and the slot count also decide a result's bits; a folder records them in its
engine record (``region.engine``, ``table_engine``) and a resume runs with the recorded ones.

Importing this module does not import JAX; :func:`numerics` reads JAX's settings only when JAX
has been imported (else the environment variables that will set them).
"""

from __future__ import annotations

import os
import sys
from importlib.metadata import PackageNotFoundError, version

from .version import __version__

RESULT_KEYS = ("x64", "xla_flags", "matmul_precision")
INFO_KEYS = ("package", "jax", "jaxlib", "mujoco", "mujoco_mjx", "cpu_isa")
# XLA flags that do not change a result's numbers: how many host devices (the engine's
# results are device-count independent) and where XLA writes its debugging dumps.
NEUTRAL_FLAGS = (
    "--xla_force_host_platform_device_count",
    "--xla_dump_to",
    "--xla_dump_hlo_as_text",
)
_TRUE = ("1", "true", "yes", "on")


def _version(name: str) -> str | None:
    try:
        return version(name)
    except PackageNotFoundError:
        return None


def result_flags(flags: str | None = None) -> list[str]:
    """The XLA flags (of ``flags``, default $XLA_FLAGS) that may change numbers, sorted."""
    words = (os.environ.get("XLA_FLAGS", "") if flags is None else flags).split()
    return sorted(w for w in words if not w.startswith(NEUTRAL_FLAGS))


def cpu_isa(flags: str | None = None) -> str:
    """The vector ISA XLA's CPU code targets: ``--xla_cpu_max_isa`` when set, else the best the
    host has (from /proc/cpuinfo; "unknown" where it cannot be read)."""
    for word in (os.environ.get("XLA_FLAGS", "") if flags is None else flags).split():
        if word.startswith("--xla_cpu_max_isa="):
            return word.split("=", 1)[1].upper()
    try:
        with open("/proc/cpuinfo") as fh:
            found = set()
            for line in fh:
                if line.startswith("flags"):
                    found = set(line.split(":", 1)[1].split())
                    break
    except OSError:
        return "unknown"
    for isa, flag in (
        ("AVX512", "avx512f"),
        ("AVX2", "avx2"),
        ("AVX", "avx"),
        ("SSE4_2", "sse4_2"),
    ):
        if flag in found:
            return isa
    return "unknown"


def _jax_settings() -> tuple[bool, str]:
    if "jax" in sys.modules:
        import jax  # lazy: already imported; this module never starts JAX

        return (
            bool(jax.config.jax_enable_x64),  # type: ignore[attr-defined]  # jax.config's flags are set at run time
            str(jax.config.jax_default_matmul_precision or "default"),  # type: ignore[attr-defined]
        )
    x64 = os.environ.get("JAX_ENABLE_X64", "").strip().lower() in _TRUE
    return x64, os.environ.get("JAX_DEFAULT_MATMUL_PRECISION", "") or "default"


def numerics() -> dict:
    """This process's numerics fingerprint (:data:`RESULT_KEYS` and :data:`INFO_KEYS`)."""
    x64, precision = _jax_settings()
    return {
        "x64": x64,
        "xla_flags": result_flags(),
        "matmul_precision": precision,
        "package": __version__,
        "jax": _version("jax"),
        "jaxlib": _version("jaxlib"),
        "mujoco": _version("mujoco"),
        "mujoco_mjx": _version("mujoco-mjx"),
        "cpu_isa": cpu_isa(),
    }


def differences(recorded: dict, current: dict) -> tuple[list[str], list[str]]:
    """(what differs in :data:`RESULT_KEYS`, what differs in :data:`INFO_KEYS`), each as
    ``key: recorded -> current``; keys missing from ``recorded`` (an older folder) are not
    compared."""

    def changed(keys):
        return [
            f"{k}: {recorded[k]!r} -> {current.get(k)!r}"
            for k in keys
            if k in recorded and recorded[k] != current.get(k)
        ]

    return changed(RESULT_KEYS), changed(INFO_KEYS)
