"""XLA options for schedule-independent results, set before JAX starts (no JAX import here)."""

from __future__ import annotations

import os
import sys

# XLA CPU options under which every lane of a vmapped program computes the same bits whatever
# its position and the batch size (measured: without them the ADMM's products and the contact
# solver's reductions differ in the last bits between lanes and between batch sizes; with them
# the rollout runs as fast, tests/test_engine.py and BENCHMARKS.md).
DETERMINISTIC_XLA_FLAGS = (
    "--xla_cpu_strict_dot_conv_math=true",
    "--xla_cpu_enable_platform_dependent_math=false",
    "--xla_cpu_use_fusion_emitters=false",
    "--xla_cpu_prefer_vector_width=128",
)


def deterministic_flags() -> bool:
    """Add :data:`DETERMINISTIC_XLA_FLAGS` to XLA_FLAGS if JAX has not started a backend yet.

    Returns whether they are in effect (False when JAX was already running without them)."""
    flags = os.environ.get("XLA_FLAGS", "")
    missing = [f for f in DETERMINISTIC_XLA_FLAGS if f.split("=")[0] not in flags]
    if not missing:
        return True
    if _backend_started():
        return False
    os.environ["XLA_FLAGS"] = " ".join([flags, *missing]).strip()
    return True


def _backend_started() -> bool:
    if "jax" not in sys.modules:
        return False
    try:
        from jax._src import xla_bridge  # noqa: PLC0415
        return bool(xla_bridge._backends)  # noqa: SLF001 - no public "is initialised" query
    except Exception:  # noqa: BLE001 - assume started
        return True
