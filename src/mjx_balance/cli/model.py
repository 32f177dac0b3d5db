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

from ..store.folder import write_text
from . import load_run_config, one_push

log = logging.getLogger("mjx_balance")

NO_DISPLAY = 1  # exit code of `view` without a display (a failure, not a usage error)


def model_command(args) -> int:
    """Write the configured body's MJCF to --out (atomically), checked by compiling it."""
    import mujoco

    from ..model.mjcf import mjcf

    config = load_run_config(args)
    text = mjcf(config.body, config.scenario.physics_dt)
    model = mujoco.MjModel.from_xml_string(text)  # what we write must load
    out = Path(args.out)
    write_text(text, out)
    log.info(f"wrote {out} (total mass {float(model.body_mass.sum()):.4g} kg, time step "
             f"{model.opt.timestep:g} s)")
    return 0


def display_missing() -> str | None:
    """Why no viewer window can open here, or None (only checked on Linux, where a window
    needs an X11 or Wayland display)."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        return "no display (DISPLAY and WAYLAND_DISPLAY are not set)"
    return None


def view_command(args) -> int:
    """Simulate one push with the reference, then replay it in MuJoCo's passive viewer."""
    missing = display_missing()
    if missing:
        print(f"mjx-balance: error: view needs a display: {missing}; `mjx-balance animate` "
              "writes a GIF of the push, `mjx-balance model` the MJCF", file=sys.stderr)
        return NO_DISPLAY
    config, duration = one_push(args)

    import mujoco

    from ..model.mjcf import build_model
    from ..reference.loop import simulate_scenario

    summary, series = simulate_scenario(config, args.force, duration, record=True)
    log.info(f"push {args.force:g} N for {duration:g} s: {summary['outcome']}; replaying "
             f"{series['time'].iloc[-1]:.2f} s at {args.speed:g}x (close the window to end)")
    model = build_model(config.body, config.scenario.physics_dt)
    data = mujoco.MjData(model)
    address = {name: int(model.joint(name).qposadr[0])
               for name in ("foot_x", "foot_z", "foot_pitch", "ankle", "hip")}
    columns = {"foot_x": "foot_x", "foot_z": "foot_z", "foot_pitch": "foot_pitch",
               "ankle": "q_a", "hip": "q_h"}
    frames = series[["time", *columns.values()]].to_numpy()
    try:
        import mujoco.viewer

        viewer = mujoco.viewer.launch_passive(model, data)
    except Exception as exc:  # noqa: BLE001 - no OpenGL, no window system, mjpython needed
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
