"""The batched closed loop: MJX physics + the batched ADMM MPC, jitted and vmapped.

    physics.py   the MuJoCo/MJX model, one physics step with the push, the measurements
    kernel.py    one scenario as a pure function: control periods and physics steps in a
                 ``lax.scan``, the running summary (accumulators) in the carry
    engine.py    continuous batching: fixed slots per device, refilled on the device when a
                 scenario is decided (fall, t_end, certified recovery: certificate.py)
    runner.py    BatchRunner: the engine (or a padded batch with trajectories), sharded over
                 the local devices, summary columns on the host

Throughput and compile times are measured by ``mjx-balance bench`` (BENCHMARKS.md).
"""

from .kernel import Accumulators, Arrays, Static, scenario
from .physics import MJX_OPTIONS, advance, cast_floats, mj_model, mjx_model, open_loop, rest_data
from .sensing import Sensors, sensors
from .runner import BatchRunner, push_steps, summarize

__all__ = [
    "Accumulators", "Arrays", "BatchRunner", "MJX_OPTIONS", "Sensors", "Static", "advance",
    "cast_floats", "mj_model", "mjx_model", "open_loop", "push_steps", "rest_data", "scenario",
    "sensors", "summarize",
]
