"""The batched closed loop: MJX physics + the batched ADMM MPC, jitted and vmapped.

    physics.py   the MuJoCo/MJX model, one physics step with the push, the measurements
    kernel.py    one scenario as a pure function: control periods and physics steps in a
                 ``lax.scan``, the running summary (accumulators) in the carry
    runner.py    BatchRunner: compile once per batch size, vmap and shard the kernel over
                 scenarios, summary columns on the host

Throughput and compile times are measured by ``mjx-balance bench`` (BENCHMARKS.md).
"""

from .kernel import Accumulators, Arrays, Static, scenario
from .physics import (MJX_OPTIONS, Sensors, advance, cast_floats, mj_model, mjx_model,
                      open_loop, rest_data, sensors)
from .runner import BatchRunner, push_steps, summarize

__all__ = [
    "Accumulators", "Arrays", "BatchRunner", "MJX_OPTIONS", "Sensors", "Static", "advance",
    "cast_floats", "mj_model", "mjx_model", "open_loop", "push_steps", "rest_data", "scenario",
    "sensors", "summarize",
]
