"""Floor 4, reference: the scalar closed loop, one scenario at a time (MuJoCo C physics, the MPC
solved by OSQP), and its time series and summary. The batched paths are tested against it.
docs/architecture.md, "The modules", maps its modules.
"""

from .loop import (
    TIMESERIES_COLUMNS,
    push_wrench,
    reference_mpc,
    simulate_many,
    simulate_pairs,
    simulate_scenario,
    timeseries_frame,
)

__all__ = [
    "TIMESERIES_COLUMNS",
    "push_wrench",
    "reference_mpc",
    "simulate_many",
    "simulate_pairs",
    "simulate_scenario",
    "timeseries_frame",
]
