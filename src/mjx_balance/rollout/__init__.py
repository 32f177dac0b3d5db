"""Floor 5, rollout: the batched closed loop, MJX physics (or MuJoCo C) with the batched ADMM
MPC, run by continuous batching over the local devices (docs/engine.md).
docs/architecture.md, "The modules", maps its modules.

Throughput and compile times are measured by ``mjx-balance bench`` (BENCHMARKS.md).
"""

from .kernel import Accumulators, Arrays, Static, scenario
from .physics import MJX_OPTIONS, advance, cast_floats, mj_model, mjx_model, open_loop, rest_data
from .sensing import Sensors, sensors
from .runner import BatchRunner, push_steps, summarize

__all__ = [
    "Accumulators",
    "Arrays",
    "BatchRunner",
    "MJX_OPTIONS",
    "Sensors",
    "Static",
    "advance",
    "cast_floats",
    "mj_model",
    "mjx_model",
    "open_loop",
    "push_steps",
    "rest_data",
    "scenario",
    "sensors",
    "summarize",
]
