"""XLA options for schedule-independent results, set before JAX starts (no JAX import here)."""

from __future__ import annotations

import os
import sys

# XLA CPU options that keep the code of every lane of a vmapped program the same whatever its
# position and the batch size: strict (unfused, unreordered) dot products, no platform-specific
# approximations of transcendental functions, one vector width (128 bits). Without them the
# vmapped ADMM gives other bits for other batch sizes, and without the vector width the
# engine's results depend on the order of the cells (tests/rollout/test_engine.py). The vector
# width changes float32 rounding (tests/rollout/test_rollout.py's open-loop drift against MuJoCo
# C). All three are known to jaxlib 0.10 and 0.11 (XLA refuses unknown flags when it starts).
#
# And no FMA: XLA's CPU compiler lets LLVM fuse a multiply and an add into one FMA (one
# rounding instead of two) where the target has it, and whether it does can depend on the code
# path a lane takes (vector body or scalar remainder), so a scenario's bits would depend on its
# slot (tests/rollout/test_engine.py::test_same_bits_in_any_order_and_split) and an early-stopped
# run would differ from a full-length one. With the ISA capped at AVX (no FMA, no AVX2) every
# x86-64 CPU from AVX on computes each lane with the same instructions (docs/reliability.md:
# what is bitwise across CPUs).
#
# And single-threaded Eigen inside each device's ops: with several threads per device Eigen
# splits a product's sums over them, and how it splits depends on the threads a device has, so
# one device (both cores) and two (a core each) would give other bits
# (tests/rollout/test_engine.py::test_one_and_two_host_devices_give_the_same_bits).
#
# What the cap and single-threaded Eigen cost: BENCHMARKS.md, "The deterministic XLA flags'
# cost".
DETERMINISTIC_XLA_FLAGS = (
    "--xla_cpu_strict_dot_conv_math=true",
    "--xla_cpu_enable_platform_dependent_math=false",
    "--xla_cpu_prefer_vector_width=128",
    "--xla_cpu_max_isa=AVX",
    "--xla_cpu_multi_thread_eigen=false",
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
        from jax._src import xla_bridge

        return bool(xla_bridge._backends)
    except Exception:
        return True
