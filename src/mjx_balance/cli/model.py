"""``mjx-balance model``: the MJCF of the configured body; ``mjx-balance view``: one push
replayed in MuJoCo's passive viewer.

``model`` writes what ``model.mjcf`` generates from the configuration's body (and the
scenario's physics_dt as the time step), after MuJoCo compiled it: the file loads with
``mujoco.MjModel.from_xml_path`` and opens in MuJoCo's own viewer (``python -m mujoco.viewer
--mjcf body.xml``).

``view`` runs the push through the scalar reference (MuJoCo C + OSQP, as ``simulate`` and
``animate`` do), then replays its recorded joint positions in ``mujoco.viewer.launch_passive``.
It needs a display: on Linux, without DISPLAY or WAYLAND_DISPLAY it says so in one line and
exits with 1 before any work; a viewer that cannot start (no OpenGL, macOS without mjpython)
ends the same way.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

from .common import load_run_config, one_push
from .options import config_options, finite_float, nonnegative_float, out_file, positive_float

log = logging.getLogger("mjx_balance")

NO_DISPLAY = 1  # exit code of `view` without a display (a failure, not a usage error)


def add_parser(sub: Any) -> None:
    """The ``model`` and ``view`` sub-commands (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "model",
        help="write the MJCF (MuJoCo XML) of the configured body (its "
        "time step: scenario.physics_dt)",
    )
    config_options(p)
    p.add_argument("--out", type=out_file, required=True, help="output MJCF file, e.g. body.xml")
    p.set_defaults(target="mjx_balance.cli.model:model_command")

    p = sub.add_parser(
        "view", help="replay one push in MuJoCo's interactive (passive) viewer (needs a display)"
    )
    p.add_argument("--force", type=finite_float, required=True, help="push force [N]")
    p.add_argument("--duration", type=nonnegative_float, default=0.1, help="push duration [s]")
    p.add_argument(
        "--t-end",
        type=positive_float,
        default=None,
        help="simulate only this long [s] (default: the configuration's t_end)",
    )
    p.add_argument(
        "--speed", type=positive_float, default=1.0, help="playback speed (1: real time)"
    )
    p.add_argument("--loop", action="store_true", help="replay until the viewer is closed")
    config_options(p)
    p.set_defaults(target="mjx_balance.cli.model:view_command")


def model_command(args) -> int:
    """Write the configured body's MJCF to --out (atomically), checked by compiling it."""
    import mujoco

    from ..model.mjcf import mjcf  # lazy: MuJoCo; not for --help
    from ..store.files import write_text  # lazy: the store floor loads pandas

    config = load_run_config(args)
    text = mjcf(config.body, config.scenario.physics_dt)
    model = mujoco.MjModel.from_xml_string(text)  # what we write must load
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)  # as --out folders are made
    write_text(text, out)
    log.info(
        f"wrote {out} (total mass {float(model.body_mass.sum()):.4g} kg, time step "
        f"{model.opt.timestep:g} s)"
    )
    return 0


def display_missing() -> str | None:
    """Why no viewer window can open here, or None (only checked on Linux, where a window
    needs an X11 or Wayland display)."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        return "no display (DISPLAY and WAYLAND_DISPLAY are not set)"
    return None


def view_command(args) -> int:
    """Simulate one push with the reference, then replay it in MuJoCo's passive viewer."""
    missing = display_missing()
    if missing:
        print(
            f"mjx-balance: error: view needs a display: {missing}; `mjx-balance animate` "
            "writes a GIF of the push, `mjx-balance model` the MJCF",
            file=sys.stderr,
        )
        return NO_DISPLAY
    config, duration = one_push(args)

    import mujoco

    from ..model.mjcf import build_model  # lazy: MuJoCo, after the display check
    from ..reference.loop import simulate_scenario  # lazy: as above

    summary, series = simulate_scenario(config, args.force, duration, record=True)
    assert series is not None  # (record=True)
    log.info(
        f"push {args.force:g} N for {duration:g} s: {summary['outcome']}; replaying "
        f"{series['time'].iloc[-1]:.2f} s at {args.speed:g}x (close the window to end)"
    )
    model = build_model(config.body, config.scenario.physics_dt)
    data = mujoco.MjData(model)
    address = {
        name: int(model.joint(name).qposadr[0])
        for name in ("foot_x", "foot_z", "foot_pitch", "ankle", "hip")
    }
    columns = {
        "foot_x": "foot_x",
        "foot_z": "foot_z",
        "foot_pitch": "foot_pitch",
        "ankle": "q_a",
        "hip": "q_h",
    }
    frames = series[["time", *columns.values()]].to_numpy()
    try:
        import mujoco.viewer

        viewer = mujoco.viewer.launch_passive(model, data)
    except Exception as exc:
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        print(f"mjx-balance: error: the viewer cannot start here: {first}", file=sys.stderr)
        return NO_DISPLAY
    frame_dt = 1 / 60  # wall-clock seconds between drawn frames
    with viewer:
        while viewer.is_running():
            start, shown = time.perf_counter(), -1.0
            for row in frames:
                if not viewer.is_running():
                    break
                sim_t = row[0]
                if sim_t - shown < frame_dt * args.speed and row is not frames[-1]:
                    continue
                shown = sim_t
                for k, (name, _) in enumerate(columns.items()):
                    data.qpos[address[name]] = row[1 + k]
                data.time = sim_t
                mujoco.mj_forward(model, data)
                viewer.sync()
                wait = sim_t / args.speed - (time.perf_counter() - start)
                if wait > 0:
                    time.sleep(wait)
            if not args.loop:
                break
    return 0
