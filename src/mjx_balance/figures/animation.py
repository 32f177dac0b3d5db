"""Stick-figure animation of one scenario, drawn with matplotlib (no OpenGL needed).

Reads a reference time series (reference.simulate_scenario's long-format frame: time, foot_x,
foot_z, foot_pitch, q_a, q_h, cop, com, force, duration) and draws, frame by frame: the foot,
lower and upper body, the push arrow on the upper body's CoM for the whole push (its length
proportional to the force, ARROW_M_PER_N), the load-cell CoP on the floor, the whole-body CoM's
ground projection, the time and the outcome; beside it the joint angles against time with a
cursor. Once the body has settled (the settle time plus SETTLED_HOLD_S), the frames step
FAST_FORWARD times faster (marked in the frame), so the motionless end of a long window takes
a few frames instead of hundreds. The figure is at least 720 px wide at the default 80 dpi.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping


import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.animation import FuncAnimation, PillowWriter

from ..model.params import BodyParams, ScenarioParams
from ..store.files import write_atomic
from . import style

FIGSIZE = (9.6, 5.4)  # inches: 768 x 432 px at 80 dpi
ARROW_M_PER_N = 0.004  # push arrow length per newton (100 N -> 0.4 m)
FAST_FORWARD = 8  # frame step multiple once settled
SETTLED_HOLD_S = 0.5  # s of real-time frames after the settle time
PUSH_FRAMES = 3  # at least this many frames while the push acts
OUTCOME_COLOURS = style.OUTCOME_COLOURS  # the one outcome palette (figures/style.py)


class _GifWriter(PillowWriter):
    """PillowWriter that writes GIF whatever the file name ends with (the temporary file of
    :func:`store.files.write_atomic`)."""

    def finish(self):
        self._frames[0].save(
            self.outfile,
            format="GIF",
            save_all=True,
            append_images=self._frames[1:],
            duration=int(1000 / self.fps),
            loop=0,
        )


def frame_times(
    t_last: float,
    fps: float,
    *,
    settled_at: float | None = None,
    push: float = 0.0,
    fast_forward: int = FAST_FORWARD,
) -> np.ndarray:
    """Frame times: 0, 1/fps, ... up to t_last, and t_last itself (within float error); with
    ``push`` > 0 at least PUSH_FRAMES frames in [0, push); with ``settled_at``, from
    settled_at + SETTLED_HOLD_S on a step of fast_forward / fps, and t_last as the last frame."""
    if fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    times = np.arange(int(np.floor(t_last * fps + 1e-9)) + 1) / fps
    if times[-1] < t_last - 1e-9:  # the last sample (a fall, say) is always a frame
        times = np.append(times, t_last)
    if push > 0 and (times < push).sum() < PUSH_FRAMES:
        extra = np.linspace(0.0, push, PUSH_FRAMES, endpoint=False)
        times = np.union1d(times, extra[extra <= t_last])
    if settled_at is not None and fast_forward > 1:
        start = settled_at + SETTLED_HOLD_S
        slow = times[times <= start + 1e-9]
        fast = np.arange(slow[-1] + fast_forward / fps, t_last + 1e-9, fast_forward / fps)
        times = np.concatenate([slow, fast])
        if times[-1] < t_last - 1e-9:
            times = np.append(times, t_last)
    return times


def segment_points(body: BodyParams, foot_x, foot_z, foot_pitch, q_a, q_h) -> dict[str, np.ndarray]:
    """World (x, z) of the sole ends, ankle, hip, head and upper-body CoM (arrays [..., 2])."""

    def rot(angle, x, z):  # rotation about +y: a positive angle tilts +z towards +x
        return (np.cos(angle) * x + np.sin(angle) * z, -np.sin(angle) * x + np.cos(angle) * z)

    back, front = body.sole_edges
    heel = np.stack(rot(foot_pitch, back, 0.0), -1) + np.stack([foot_x, foot_z], -1)
    toe = np.stack(rot(foot_pitch, front, 0.0), -1) + np.stack([foot_x, foot_z], -1)
    ankle = np.stack(rot(foot_pitch, 0.0, body.ankle_height), -1) + np.stack([foot_x, foot_z], -1)
    tilt1 = foot_pitch + q_a
    tilt2 = tilt1 + q_h
    dir1 = np.stack([np.sin(tilt1), np.cos(tilt1)], -1)
    dir2 = np.stack([np.sin(tilt2), np.cos(tilt2)], -1)
    hip = ankle + body.lower_length * dir1
    return {
        "heel": heel,
        "toe": toe,
        "ankle": ankle,
        "hip": hip,
        "head": hip + body.upper_length * dir2,
        "upper_com": hip + body.upper_com * dir2,
    }


def settle_time(ts: pd.DataFrame, scenario: ScenarioParams = ScenarioParams()) -> float | None:
    """Time of the last sample outside the settle band (0 if none), or None when the last
    sample is outside it (not settled at the end)."""
    outside = (
        (ts[["q_a", "q_h"]].abs() > scenario.settle_angle_tol).any(axis=1)
        | (ts[["dq_a", "dq_h"]].abs() > scenario.settle_rate_tol).any(axis=1)
    ).to_numpy()
    if outside[-1]:
        return None
    return float(ts["time"].to_numpy()[outside][-1]) if outside.any() else 0.0


def _outcome_text(
    summary: Mapping[str, Any] | None, settled: float | None, t_last: float
) -> tuple[str, str]:
    """(text, outcome class) of the run: from its summary row when given, else from the
    series (settled at the end: recovered; otherwise the run ended at t_last unsettled)."""
    if summary is not None:
        outcome = str(summary["outcome"])
        if outcome == "recovered":
            return f"recovered (settled at {float(summary['settle_time']):.2f} s)", outcome
        if outcome == "fell":
            return f"fell at {float(summary['fall_time']):.2f} s", outcome
        if outcome == "not_settled":
            return "not settled by t_end", outcome
        return outcome, outcome
    if settled is not None:
        return f"recovered (settled at {settled:.2f} s)", "recovered"
    return f"not settled at {t_last:.2f} s (the series ends)", "not_settled"


class _Frames:
    """What the n frames of an animation of the series ``ts`` (sorted by time) show: t
    [samples] the series' times; times [n] the frame times; rows [n] the sample each frame
    shows and pts its stick figure (segment_points, [n, 2] each); the push (force [N],
    duration [s], arrow_len [m]); fast_from [s] where the frames start to step
    fast_forward / fps (inf: never); the outcome's text and class (from ``summary`` when
    given, else the series)."""

    def __init__(
        self,
        ts: pd.DataFrame,
        body: BodyParams,
        fps: float,
        summary: Mapping[str, Any] | None,
        scenario: ScenarioParams,
        fast_forward: int,
    ):
        t = ts["time"].to_numpy()
        force = float(ts["force"].iloc[0])
        duration = float(ts["duration"].iloc[0])
        settled = settle_time(ts, scenario)
        if summary is not None:
            settled = float(summary["settle_time"]) if summary["outcome"] == "recovered" else None
        self.text, self.outcome = _outcome_text(summary, settled, float(t[-1]))
        times = frame_times(
            t[-1],
            fps,
            settled_at=settled,
            push=duration if force else 0.0,
            fast_forward=fast_forward,
        )
        self.fast_from = (
            (settled + SETTLED_HOLD_S) if settled is not None and fast_forward > 1 else np.inf
        )
        idx = np.clip(np.searchsorted(t, times - 1e-12), 0, len(t) - 1)
        rows = ts.iloc[idx]
        self.pts = segment_points(
            body,
            rows["foot_x"].to_numpy(),
            rows["foot_z"].to_numpy(),
            rows["foot_pitch"].to_numpy(),
            rows["q_a"].to_numpy(),
            rows["q_h"].to_numpy(),
        )
        self.t, self.times, self.rows = t, times, rows
        self.force, self.duration, self.arrow_len = force, duration, ARROW_M_PER_N * force


def _stick_axes(ax, fr: _Frames, body: BodyParams) -> tuple:
    """Set up the stick-figure axes: floor, limits, title and the (empty) moving artists;
    returns (foot, body, CoP, CoM, arrow, arrow text, clock, state)."""
    force, arrow_len = fr.force, fr.arrow_len
    height = body.lower_length + body.upper_length
    half_width = max(1.0, abs(arrow_len) + 0.5)
    ax.set_xlim(-half_width, half_width)
    ax.set_ylim(-0.1, height + 0.25)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.axhline(0.0, color="0.4", lw=1)
    (foot_line,) = ax.plot([], [], color="0.2", lw=5, solid_capstyle="butt")
    (body_line,) = ax.plot([], [], "o-", color="tab:blue", lw=4, ms=5)
    (cop_dot,) = ax.plot([], [], "^", color="tab:red", ms=9, label="CoP (load cells)")
    (com_dot,) = ax.plot([], [], "s", color="tab:green", ms=7, label="CoM (ground projection)")
    arrow = ax.annotate(
        "",
        xy=(0, 0),
        xytext=(0, 0),
        arrowprops=dict(arrowstyle="-|>", color="tab:orange", lw=3, mutation_scale=18),
    )
    arrow_text = ax.text(
        0,
        0,
        f"F = {force:g} N",
        color="tab:orange",
        fontsize=9,
        ha="center",
        va="bottom",
        fontweight="bold",
    )
    ax.legend(loc="upper left", fontsize=7, frameon=False)
    ax.set_title(
        f"push F = {force:g} N for T = {fr.duration:g} s "
        f"(arrow {ARROW_M_PER_N * 100:g} m per 100 N)",
        fontsize=9,
    )
    clock = ax.text(
        0.98,
        0.97,
        "",
        transform=ax.transAxes,
        ha="right",
        va="top",
        fontsize=11,
        family="monospace",
    )
    state = ax.text(0.98, 0.90, "", transform=ax.transAxes, ha="right", va="top", fontsize=9)
    return foot_line, body_line, cop_dot, com_dot, arrow, arrow_text, clock, state


def _angle_axes(axt, ts: pd.DataFrame, fr: _Frames, fast_forward: int):
    """Draw the joint angles against time (the push and the fast-forwarded end shaded);
    returns the time cursor."""
    t, duration, fast_from = fr.t, fr.duration, fr.fast_from
    if duration > 0 and fr.force:
        axt.axvspan(0.0, duration, color="#fddbc7", lw=0, label=f"push (0 to {duration:g} s)")
    axt.plot(t, ts["q_a"], color="#2166ac", lw=1.3, label=r"ankle $q_a$")
    axt.plot(t, ts["q_h"], color="#1b7837", lw=1.3, label=r"hip $q_h$")
    if np.isfinite(fast_from) and fast_from < t[-1]:
        axt.axvspan(fast_from, t[-1], color="0.9", lw=0, label=f"settled: ×{fast_forward} speed")
    cursor = axt.axvline(0.0, color="black", lw=1)
    axt.set_xlim(0.0, float(t[-1]))
    axt.set_xlabel("time [s]")
    axt.set_ylabel("joint angle [rad]")
    axt.grid(alpha=0.3)
    axt.legend(fontsize=7, loc="best")
    axt.set_title("joint angles", fontsize=9)
    return cursor


def _draw_frame(i: int, fr: _Frames, artists: tuple, fast_forward: int) -> tuple:
    """Move the artists (foot, body, CoP, CoM, arrow, arrow text, clock, state, cursor) to
    frame i; returns them."""
    foot_line, body_line, cop_dot, com_dot, arrow, arrow_text, clock, state, cursor = artists
    pts, rows, times, force = fr.pts, fr.rows, fr.times, fr.force
    foot_line.set_data([pts["heel"][i, 0], pts["toe"][i, 0]], [pts["heel"][i, 1], pts["toe"][i, 1]])
    chain = np.stack([pts["ankle"][i], pts["hip"][i], pts["head"][i]])
    body_line.set_data(chain[:, 0], chain[:, 1])
    cop = rows["cop"].iloc[i]
    cop_dot.set_data([cop] if np.isfinite(cop) else [], [0.0] if np.isfinite(cop) else [])
    com_dot.set_data([rows["com"].iloc[i]], [0.0])
    pushing = force != 0 and times[i] < fr.duration - 1e-9  # the push acts on [0, T)
    tip = pts["upper_com"][i]
    arrow.xy = tuple(tip)
    arrow.set_position((tip[0] - fr.arrow_len, tip[1]))
    arrow.set_visible(bool(pushing))
    arrow_text.set_position((tip[0] - fr.arrow_len / 2, tip[1] + 0.04))
    arrow_text.set_visible(bool(pushing))
    clock.set_text(f"t = {times[i]:5.2f} s")
    state.set_text(
        "pushing"
        if pushing
        else f"settled: ×{fast_forward} speed"
        if times[i] > fr.fast_from + 1e-9
        else ""
    )
    cursor.set_xdata([times[i], times[i]])
    return artists


def animate_timeseries(
    ts: pd.DataFrame,
    out: str | Path,
    body: BodyParams = BodyParams(),
    fps: float = 25.0,
    dpi: int = 80,
    *,
    summary: Mapping[str, Any] | None = None,
    scenario: ScenarioParams = ScenarioParams(),
    fast_forward: int = FAST_FORWARD,
) -> int:
    """Write an animated GIF of one scenario's time series atomically (the file is whole, or
    the old one or none is left); returns the number of frames.

    summary: the run's summary row (reference.simulate_scenario's first result), for its
    outcome; None: read from the series (the settle band of ``scenario``). fast_forward: the
    frame step multiple once settled (1: real time throughout).
    """
    out = Path(out)
    if ts.empty:
        raise ValueError("empty time series: nothing to animate")
    ts = ts.sort_values("time")
    fr = _Frames(ts, body, fps, summary, scenario, fast_forward)

    fig, (ax, axt) = plt.subplots(1, 2, figsize=FIGSIZE, width_ratios=(1.0, 1.15))
    stick = _stick_axes(ax, fr, body)
    # the outcome's colour as the title's box (yellow text would not read on white)
    fig.suptitle(
        f"outcome: {fr.text}",
        fontsize=11,
        fontweight="bold",
        color="white" if fr.outcome == "diverged" else "black",
        bbox={
            "facecolor": OUTCOME_COLOURS.get(fr.outcome, "white"),
            "edgecolor": "none",
            "boxstyle": "round,pad=0.3",
        },
    )
    # Beside: the joint angles against time, with a cursor.
    artists = (*stick, _angle_axes(axt, ts, fr, fast_forward))

    fig.tight_layout()
    anim = FuncAnimation(
        fig, lambda i: _draw_frame(i, fr, artists, fast_forward), frames=len(fr.times), blit=False
    )
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(out, lambda tmp: anim.save(tmp, writer=_GifWriter(fps=fps), dpi=dpi))  # type: ignore[arg-type]  # matplotlib's stub says int; a float fps works
    finally:
        plt.close(fig)
    return len(fr.times)
