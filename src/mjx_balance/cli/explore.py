"""``mjx-balance explore DIR``: a page on this machine where every cell of a folder's map opens
its run (``mjx_balance.api.explore``; the page: ``report/explore/``)."""

from __future__ import annotations

import argparse
import logging
from typing import Any

from .options import input_folder

log = logging.getLogger("mjx_balance")


def port_number(text: str) -> int:
    """A TCP port: a whole number in [0, 65535] (0: a free one)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"must be in [0, 65535] (0: a free one), got {text!r}")
    return value


def add_parser(sub: Any) -> None:
    """The ``explore`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "explore",
        help="a page on this machine (127.0.0.1) where every cell of a sweep, "
        "compare or cohort folder's map opens its run, computed on demand by "
        "the scalar reference and kept in the folder",
    )
    p.add_argument(
        "folder",
        type=input_folder,
        metavar="DIR",
        help="a folder written by sweep, compare or cohort (also one being written)",
    )
    p.add_argument(
        "--port", type=port_number, default=0, help="the port on 127.0.0.1 (default: 0, a free one)"
    )
    p.add_argument(
        "--no-browser",
        action="store_true",
        help="do not open the page in the web browser; print its address only",
    )
    p.set_defaults(target="mjx_balance.cli.explore:explore_command")


def explore_command(args) -> int:
    """Serve the page until Ctrl-C (exit code 130; SIGTERM 143)."""
    from ..api import explore  # lazy: the library loads JAX, MuJoCo and pandas
    from ..runtime import signals  # lazy: with the library

    try:
        explore(args.folder, port=args.port, browser=not args.no_browser, wait=True)
    except KeyboardInterrupt as exc:
        signals.seen(exc)
        log.info("explore: stopped")
        return getattr(exc, "code", signals.Interrupted.code)
    return 0
