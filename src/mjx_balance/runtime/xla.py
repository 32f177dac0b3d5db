"""XLA options for schedule-independent results, set before JAX starts (no JAX import here)."""

from __future__ import annotations

import os
import sys

# XLA CPU options that keep the code of every lane of a vmapped program the same whatever its
# position and the batch size: strict (unfused, unreordered) dot products, no platform-specific
# approximations of transcendental functions, one vector width (128 bits). Measured with jax
# 0.10.2 on this project's CPU: the vmapped ADMM gave other bits for batches of 64 and 256 than
# for 8 without them and the same bits with them; the engine's results were slot-, order- and
# device-count-independent with all three (tests/test_engine.py) and not without the vector
# width (the same 40 cells in another order: peak angles differed at 1e-6), at the same speed
# (docs/engine.md). The vector width changes float32 rounding (tests/test_rollout.py's open-loop
# drift against MuJoCo C). All three are known to jaxlib 0.10 and 0.11 (XLA refuses unknown
# flags when it starts).
#
# And no FMA: XLA's CPU compiler always lets LLVM fuse a multiply and an add into one FMA (one
# rounding instead of two) where the target has it, and whether it does can depend on the code
# path a lane takes (vector body or scalar remainder), so a scenario's bits depended on its
# slot. Measured on an AMD EPYC (Zen 1, AVX2 + FMA, 2 cores): with the three flags above, the
# same 40 cells in another order and split gave other peak_ankle bits
# (tests/test_engine.py::test_same_bits_in_any_order_and_split), and so did early-stopped
# against full-length runs; with the ISA capped at AVX (no FMA, no AVX2) or SSE4_2 they are
# equal, at the same speed (a 160-cell sweep, warm cache: 23.5-24.3 s without the cap,
# 24.3-25.2 s with it). With no FMA and 128-bit vectors every x86-64 CPU from AVX on computes
# each lane with the same instructions (docs/reliability.md: what is bitwise across CPUs).
#
# And single-threaded Eigen inside each device's ops: with several threads per device Eigen
# splits a product's sums over them, and how it splits depends on the threads a device has, so
# one device (both cores) and two (a core each) gave other bits: on the same Zen 1 EPYC, a
# 160-cell sweep's region.parquet differed between MJX_BALANCE_HOST_DEVICES=1 and 2 without
# this flag and was the same with it (tests/test_engine.py::
# test_one_and_two_host_devices_give_the_same_bits). Cost on that machine, 2 devices, warm
# cache: 32.1-32.5 s against 24.3-30.1 s without it (BENCHMARKS.md).
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
        from jax._src import xla_bridge  # noqa: PLC0415
        return bool(xla_bridge._backends)  # noqa: SLF001 - no public "is initialised" query
    except Exception:  # noqa: BLE001 - assume started
        return True
