"""``mjx-balance animate``: a stick-figure GIF of one push (reference simulation)."""

from __future__ import annotations

import logging

from ..animate import FAST_FORWARD, animate_timeseries
from ..reference import simulate_scenario
from ..sweep.grid import check_durations
from . import load_run_config

log = logging.getLogger("mjx_balance")


def animate_command(args) -> int:
    """``mjx-balance animate``: simulate one push with the reference and write a GIF."""
    config = load_run_config(args)
    if args.t_end is not None:
        config = config.replace(scenario={"t_end": args.t_end})
    # As ``sweep``: a duration of whole physics steps in [0, t_end] (snapped to them).
    duration = float(check_durations([args.duration], config.scenario.t_end, "--duration",
                                      physics_dt=config.scenario.physics_dt)[0])
    config.replace(scenario={"duration": duration})  # any other rule: before any work
    summary, ts = simulate_scenario(config, args.force, duration, record=True)
    frames = animate_timeseries(ts, args.out, config.body, fps=args.fps, summary=summary,
                                scenario=config.scenario,
                                fast_forward=1 if args.no_fast_forward else FAST_FORWARD)
    log.info(f"wrote {args.out} ({frames} frames at {args.fps:g} fps)")
    return 0
