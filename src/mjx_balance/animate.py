"""Stick-figure animation of one scenario, drawn with matplotlib (no OpenGL needed).

Reads a reference time series (reference.simulate_scenario's long-format frame: time, foot_x,
foot_z, foot_pitch, q_a, q_h, cop, com, force, duration) and draws, frame by frame: the foot,
lower and upper body, the push arrow on the upper body's CoM while the push is on, the load-cell
CoP on the floor and the whole-body CoM's ground projection.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402

from .params import BodyParams  # noqa: E402
from .sweep.store import write_atomic  # noqa: E402


class _GifWriter(PillowWriter):
    """PillowWriter that writes GIF whatever the file name ends with (the temporary file of
    :func:`sweep.store.write_atomic`)."""

    def finish(self):
        self._frames[0].save(
            self.outfile, format="GIF", save_all=True, append_images=self._frames[1:],
            duration=int(1000 / self.fps), loop=0)


def frame_times(t_last: float, fps: float) -> np.ndarray:
    """Frame times 0, 1/fps, ... up to and including t_last (within float error)."""
    if fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    return np.arange(int(np.floor(t_last * fps + 1e-9)) + 1) / fps


def segment_points(body: BodyParams, foot_x, foot_z, foot_pitch, q_a, q_h) -> dict[str, np.ndarray]:
    """World (x, z) of the sole ends, ankle, hip, head and upper-body CoM (arrays [..., 2])."""
    def rot(angle, x, z):  # rotation about +y: a positive angle tilts +z towards +x
        return (np.cos(angle) * x + np.sin(angle) * z, -np.sin(angle) * x + np.cos(angle) * z)

    hx = body.foot_length / 2
    heel = np.stack(rot(foot_pitch, -hx, 0.0), -1) + np.stack([foot_x, foot_z], -1)
    toe = np.stack(rot(foot_pitch, hx, 0.0), -1) + np.stack([foot_x, foot_z], -1)
    ankle = np.stack(rot(foot_pitch, 0.0, body.ankle_height), -1) + np.stack([foot_x, foot_z], -1)
    tilt1 = foot_pitch + q_a
    tilt2 = tilt1 + q_h
    dir1 = np.stack([np.sin(tilt1), np.cos(tilt1)], -1)
    dir2 = np.stack([np.sin(tilt2), np.cos(tilt2)], -1)
    hip = ankle + body.lower_length * dir1
    return {
        "heel": heel, "toe": toe, "ankle": ankle, "hip": hip,
        "head": hip + body.upper_length * dir2,
        "upper_com": hip + body.upper_com * dir2,
    }


def animate_timeseries(ts: pd.DataFrame, out: str | Path, body: BodyParams = BodyParams(),
                       fps: float = 25.0, dpi: int = 80) -> int:
    """Write an animated GIF of one scenario's time series atomically (the file is whole, or
    the old one or none is left); returns the number of frames."""
    out = Path(out)
    if ts.empty:
        raise ValueError("empty time series: nothing to animate")
    ts = ts.sort_values("time")
    t = ts["time"].to_numpy()
    times = frame_times(t[-1], fps)
    idx = np.clip(np.searchsorted(t, times - 1e-12), 0, len(t) - 1)
    rows = ts.iloc[idx]
    pts = segment_points(body, rows["foot_x"].to_numpy(), rows["foot_z"].to_numpy(),
                         rows["foot_pitch"].to_numpy(), rows["q_a"].to_numpy(), rows["q_h"].to_numpy())
    force = float(ts["force"].iloc[0])
    duration = float(ts["duration"].iloc[0])
    height = body.lower_length + body.upper_length

    fig, ax = plt.subplots(figsize=(4.5, 5.5))
    ax.set_xlim(-0.9, 0.9)
    ax.set_ylim(-0.1, height + 0.2)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.axhline(0.0, color="0.4", lw=1)
    (foot_line,) = ax.plot([], [], color="0.2", lw=5, solid_capstyle="butt")
    (body_line,) = ax.plot([], [], "o-", color="tab:blue", lw=4, ms=5)
    (cop_dot,) = ax.plot([], [], "^", color="tab:red", ms=9, label="CoP (load cells)")
    (com_dot,) = ax.plot([], [], "s", color="tab:green", ms=7, label="CoM (ground projection)")
    arrow = ax.annotate("", xy=(0, 0), xytext=(0, 0),
                        arrowprops=dict(arrowstyle="-|>", color="tab:orange", lw=2.5))
    title = ax.set_title("")
    ax.legend(loc="upper left", fontsize=7, frameon=False)
    arrow_len = 0.35 * np.sign(force) if force else 0.0

    def draw(i: int):
        foot_line.set_data([pts["heel"][i, 0], pts["toe"][i, 0]], [pts["heel"][i, 1], pts["toe"][i, 1]])
        chain = np.stack([pts["ankle"][i], pts["hip"][i], pts["head"][i]])
        body_line.set_data(chain[:, 0], chain[:, 1])
        cop = rows["cop"].iloc[i]
        cop_dot.set_data([cop] if np.isfinite(cop) else [], [0.0] if np.isfinite(cop) else [])
        com_dot.set_data([rows["com"].iloc[i]], [0.0])
        pushing = times[i] < duration and force != 0
        tip = pts["upper_com"][i]
        arrow.xy = tuple(tip)
        arrow.set_position((tip[0] - arrow_len, tip[1]))
        arrow.set_visible(bool(pushing))
        title.set_text(f"F = {force:g} N for {duration:g} s    t = {times[i]:5.2f} s")
        return foot_line, body_line, cop_dot, com_dot, arrow, title

    fig.tight_layout()
    anim = FuncAnimation(fig, draw, frames=len(times), blit=False)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(out, lambda tmp: anim.save(tmp, writer=_GifWriter(fps=fps), dpi=dpi))
    finally:
        plt.close(fig)
    return len(times)
