"""``mjx-balance animate``: a stick-figure GIF of one push (reference simulation)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from .common import one_push
from .options import common_options, finite_float, nonnegative_float, out_gif, positive_float

log = logging.getLogger("mjx_balance")

MAX_FPS = 100.0  # a GIF's frame delay is counted in hundredths of a second


def gif_fps(text: str) -> float:
    """Frames per second a GIF can show: > 0 and at most MAX_FPS."""
    import argparse

    value = positive_float(text)
    if value > MAX_FPS:
        raise argparse.ArgumentTypeError(
            f"must be at most {MAX_FPS:g} (a GIF's frame delay is counted in 0.01 s), got {text!r}"
        )
    return value


def add_parser(sub: Any) -> None:
    """The ``animate`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser("animate", help="stick-figure GIF of one push (matplotlib, no OpenGL)")
    p.add_argument("--force", type=finite_float, required=True, help="push force [N]")
    p.add_argument("--duration", type=nonnegative_float, default=0.1, help="push duration [s]")
    p.add_argument(
        "--fps", type=gif_fps, default=25.0, help=f"frames per second, at most {MAX_FPS:g}"
    )
    p.add_argument("--t-end", type=positive_float, default=None, help="simulate only this long [s]")
    p.add_argument(
        "--no-fast-forward",
        action="store_true",
        help="every frame at real speed (default: 8x speed once the body has settled)",
    )
    common_options(p, out_help="output GIF file", out_type=out_gif)
    p.set_defaults(target="mjx_balance.cli.animate:animate_command")


def animate_command(args) -> int:
    """``mjx-balance animate``: simulate one push with the reference and write a GIF."""
    from ..figures.animation import FAST_FORWARD, animate_timeseries  # lazy: matplotlib
    from ..reference.loop import simulate_scenario  # lazy: MuJoCo; not for --help

    config, duration = one_push(args)
    summary, ts = simulate_scenario(config, args.force, duration, record=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)  # as --out folders are made
    frames = animate_timeseries(
        ts,
        args.out,
        config.body,
        fps=args.fps,
        summary=summary,
        scenario=config.scenario,
        fast_forward=1 if args.no_fast_forward else FAST_FORWARD,
    )
    log.info(f"wrote {args.out} ({frames} frames at {args.fps:g} fps)")
    return 0
