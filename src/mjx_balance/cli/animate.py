"""``mjx-balance animate``: a stick-figure GIF of one push (reference simulation)."""

from __future__ import annotations

import logging

from ..figures.animation import FAST_FORWARD, animate_timeseries
from ..reference.loop import simulate_scenario
from . import one_push

log = logging.getLogger("mjx_balance")


def animate_command(args) -> int:
    """``mjx-balance animate``: simulate one push with the reference and write a GIF."""
    config, duration = one_push(args)
    summary, ts = simulate_scenario(config, args.force, duration, record=True)
    frames = animate_timeseries(ts, args.out, config.body, fps=args.fps, summary=summary,
                                scenario=config.scenario,
                                fast_forward=1 if args.no_fast_forward else FAST_FORWARD)
    log.info(f"wrote {args.out} ({frames} frames at {args.fps:g} fps)")
    return 0
