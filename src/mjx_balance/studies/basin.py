"""The recovery basin in state space (``mjx-balance basin``): which initial states recover with
no push at all (the feasible-stability-region view of balance, Pai & Patton, J. Biomech. 1997).

A cell is a whole-body CoM position x_com relative to the ankle and a CoM velocity v_com. A
*posture family* turns (x_com, v_com) into a joint state:

- ``rigid`` (default): the body leans as one rigid body about the ankle, hip straight
  (q_h = 0, dq_h = 0): the inverted-pendulum reading of the plane.
- ``trunk``: the lower body leans, the upper body stays vertical (q_h = -q_a, dq_h = -dq_a):
  the CoM moves with less lean of the trunk.

The lean q_a solves x_com(q_a) = x (MuJoCo's kinematics, nonlinear), the rate is
v_com / (dx_com/dq_a). Each cell runs as a scenario with no push from that state (the batched
engine's per-scenario initial state; the foot settled on the floor, ``model.mjcf.settled_rest``),
with the outcome rules and energies of a push map. For reference the map draws the foot's edges
and the linear inverted pendulum's capture-point bound: the capture point
x_com + v_com / ω0 (ω0 = sqrt(g / z_com), z_com the CoM height at upright rest) must lie on the
foot. It also marks where the push map's cells land: the CoM state at the end of each push
(reference runs, cheap), drawn by the push run's outcome, so the two maps can be read together.

Resumable: finished cells are kept in OUT/basin_cells/*.parquet and a rerun computes only
the missing ones; the folder's manifest records the configuration and the grid.
"""

from __future__ import annotations

import math
import os
import time as _time
from pathlib import Path
from typing import Any, Callable

import mujoco
import numpy as np
import pandas as pd
import scipy.optimize

from ..reference import loop as reference
from ..model.mjcf import indices, settled_rest
from ..measures.outcomes import FALL_CAUSES, OUTCOMES
from ..model.params import Config, ParameterError, push_steps
from ..runs.grid import check_durations, describe, parse_grid
from ..runs.folders import check_float32_grid
from ..store.files import write_csv, write_parquet, write_text
from ..store.folder import OutputFolder, folder_lock, same_values
from ..runs.chunks import PlanHook, PlannedWork
from ..rollout import BatchRunner
from .defaults import DEFAULT_V, DEFAULT_X, POSTURES
from ..figures import style as figure_style

BASIN = "basin.parquet"
BASIN_PNG = "basin.png"
PUSHES = "pushes.csv"
BASIN_TXT = "basin.txt"
CELLS_DIR = "basin_cells"
FLUSH_SECONDS = 20.0


def _joints(posture: str, lean: float, rate: float) -> np.ndarray:
    if posture == "rigid":
        return np.array([lean, 0.0, rate, 0.0])
    if posture == "trunk":
        return np.array([lean, -lean, rate, -rate])
    raise ParameterError(f"posture must be one of {', '.join(POSTURES)}, got {posture!r}")


class Plane:
    """The CoM plane of a configuration's body: the posture map, the foot, the capture bound."""

    def __init__(self, config: Config):
        self.model = reference._model(config.body, config.scenario.physics_dt)
        self.ix = indices(self.model)
        self.data = mujoco.MjData(self.model)
        self.rest = settled_rest(self.model)
        self.data.qpos[:] = self.rest
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        self.ankle_x = float(self.data.xanchor[self._ankle_joint(), 0])
        self.z_com = float(self.data.subtree_com[self.ix.foot_body, 2])
        self.omega0 = math.sqrt(config.body.gravity / self.z_com)
        cells = self.data.geom_xpos[list(self.ix.cell_geoms), 0] - self.ankle_x
        self.heel, self.toe = float(cells.min()), float(cells.max())

    def _ankle_joint(self) -> int:
        return int(mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, "ankle"))

    def com_x(self, posture: str, lean: float) -> float:
        """CoM x relative to the ankle at lean ``lean`` of ``posture``."""
        q = _joints(posture, lean, 0.0)
        self.data.qpos[:] = self.rest
        self.data.qpos[[self.ix.ankle_qpos, self.ix.hip_qpos]] = q[:2]
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        return float(self.data.subtree_com[self.ix.foot_body, 0]) - self.ankle_x

    def initial_state(self, posture: str, x: float, v: float) -> np.ndarray:
        """The joint state [q_a, q_h, dq_a, dq_h] of (x_com, v_com) in ``posture``."""
        lo, hi = -1.0, 1.0  # rad: far beyond any state bound
        if not self.com_x(posture, lo) < x < self.com_x(posture, hi):
            raise ParameterError(f"x_com = {x:g} m is beyond any lean of the {posture} posture")
        lean = scipy.optimize.brentq(lambda a: self.com_x(posture, a) - x, lo, hi, xtol=1e-12)
        h = 1e-6
        slope = (self.com_x(posture, lean + h) - self.com_x(posture, lean - h)) / (2 * h)
        return _joints(posture, lean, v / slope)

    def capture_inside(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Whether the linear inverted pendulum's capture point lies on the foot."""
        point = np.asarray(x) + np.asarray(v) / self.omega0
        return (point >= self.heel) & (point <= self.toe)


def cells_of(xs: np.ndarray, vs: np.ndarray) -> pd.DataFrame:
    """Every (x_com, v_com) of the grid, x slowest, with its cell index."""
    x, v = np.meshgrid(xs, vs, indexing="ij")
    return pd.DataFrame({"cell": np.arange(x.size), "x_com": x.ravel(), "v_com": v.ravel()})


def _record(posture: str, xs: np.ndarray, vs: np.ndarray) -> dict[str, Any]:
    return {"posture": posture, "x_com": [float(v) for v in xs], "v_com": [float(v) for v in vs]}


def _check_record(folder: Path, recorded: dict[str, Any] | None, posture: str, xs, vs) -> None:
    if recorded is None:
        return
    if (
        recorded.get("posture") != posture
        or not same_values(recorded["x_com"], xs)
        or not same_values(recorded["v_com"], vs)
    ):
        raise ParameterError(
            f"{folder} holds a basin of posture {recorded.get('posture')!r} over x_com "
            f"{describe(recorded['x_com'])} m, v_com {describe(recorded['v_com'])} m/s; use "
            "another --out folder or the same grid and posture"
        )


def _done(folder: Path) -> pd.DataFrame:
    parts = sorted((folder / CELLS_DIR).glob("part_*.parquet"))
    if not parts:
        return pd.DataFrame()
    return pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True)


def check_basin(
    config: Config, x_com: Any, v_com: Any, posture: str, pushes: Any = None
) -> tuple[np.ndarray, np.ndarray, "Plane"]:
    """Every input of :func:`run_basin` checked (ParameterError) before any work: the grids,
    the posture, every (x_com, v_com) reachable by a lean, the push grid and the window.
    Returns the grids and the body's :class:`Plane`."""
    if posture not in POSTURES:
        raise ParameterError(f"posture must be one of {', '.join(POSTURES)}, got {posture!r}")
    xs, vs = parse_grid(x_com, "x_com"), parse_grid(v_com, "v_com")
    check_float32_grid(xs, "x_com")  # the batched path's initial states are float32
    check_float32_grid(vs, "v_com")
    plane = Plane(config)
    for x in xs:
        plane.initial_state(posture, x, 0.0)
    if pushes is not None:
        forces, durations = pushes
        parse_grid(forces, "push forces")
        check_durations(
            parse_grid(durations, "push durations"),
            config.scenario.t_end,
            "push durations",
            physics_dt=config.scenario.physics_dt,
        )
    return xs, vs, plane


def run_basin(
    out: str | os.PathLike[str],
    config: Config,
    x_com: Any = DEFAULT_X,
    v_com: Any = DEFAULT_V,
    posture: str = "rigid",
    pushes: Any = None,
    *,
    physics: str = "mjx",
    progress: bool = True,
    say: Callable[[str], None] = print,
    plan: PlanHook | None = None,
    wait: bool = False,
    **engine: Any,
) -> pd.DataFrame:
    """The basin map of ``config`` in OUT (module docstring): basin.parquet, basin.png.

    x_com [m], v_com [m/s]: grids (``start:stop:step`` or lists); pushes: None or
    (forces, durations) grids whose cells' end-of-push states are drawn on the map
    (pushes.csv). ``engine``: BatchRunner options (slots, devices). Every input is checked
    once (:func:`check_basin`), then ``plan`` (if given) hears the planned work
    (``runs.chunks.PlannedWork``) and the work runs under ``out``'s lock (``wait``: for
    another run that holds it). Returns the cells."""
    if physics not in ("mjx", "auto"):
        raise ParameterError(
            "the basin runs on the MJX path (--physics mjx): the MuJoCo C "
            "path starts every scenario at upright rest"
        )
    xs, vs, plane = check_basin(config, x_com, v_com, posture, pushes)
    if plan is not None:  # before the cells' initial states are built: it may refuse them
        plan(PlannedWork(config, xs.size * vs.size, "cells"))
    out = Path(out)
    with folder_lock(out, wait=wait):
        return _basin(
            out,
            config,
            xs,
            vs,
            plane,
            posture=posture,
            pushes=pushes,
            progress=progress,
            say=say,
            engine=engine,
        )


def _basin(
    out: Path,
    config: Config,
    xs: np.ndarray,
    vs: np.ndarray,
    plane: "Plane",
    *,
    posture: str,
    pushes: Any,
    progress: bool,
    say: Callable[[str], None],
    engine: dict[str, Any],
) -> pd.DataFrame:
    """:func:`run_basin`'s work, its inputs checked (every state reachable: ``check_basin``)
    and the folder locked."""
    grid = cells_of(xs, vs)
    inits = np.array([plane.initial_state(posture, x, v) for x, v in zip(grid.x_com, grid.v_com)])
    folder = OutputFolder(out, config)
    manifest = folder.open()
    _check_record(out, manifest.get("basin"), posture, xs, vs)
    manifest["basin"] = _record(posture, xs, vs)
    folder.write_manifest(manifest)
    done = _done(out)
    missing = grid[~grid.cell.isin(done.cell if len(done) else [])]
    if len(missing):
        say(f"basin: {len(missing)} of {len(grid)} cells to run ({posture} posture); output {out}")
        _run_cells(out, config, missing, inits[missing.cell.to_numpy()], progress, engine)
    else:
        say(f"basin: all {len(grid)} cells done")
    frame = _done(out).sort_values("cell").reset_index(drop=True)
    frame = frame.assign(capture_inside=plane.capture_inside(frame.x_com, frame.v_com))
    write_parquet(frame, out / BASIN)
    ends = None
    if pushes is not None:
        ends = push_ends(config, plane, *pushes, cached=out / PUSHES, progress=progress)
        write_csv(ends, out / PUSHES)
    figure = plot_basin(frame, plane, out / BASIN_PNG, ends, posture)  # in the figure style
    text = reading(frame, ends)
    write_text(text + "\n", out / BASIN_TXT)
    say(text)
    say(f"wrote {out / BASIN}, {figure} and {out / BASIN_TXT}")
    return frame


def _run_cells(
    out: Path,
    config: Config,
    cells: pd.DataFrame,
    inits: np.ndarray,
    progress: bool,
    engine: dict[str, Any],
) -> None:
    from tqdm import tqdm

    runner = BatchRunner(config, physics="mjx", **engine)
    zeros = np.zeros(len(cells))
    parts = out / CELLS_DIR
    parts.mkdir(parents=True, exist_ok=True)
    pending: list[pd.DataFrame] = []
    last = _time.perf_counter()

    def flush():
        if pending:
            frame = pd.concat(pending, ignore_index=True)
            write_parquet(
                frame, parts / f"part_{int(frame.cell.min()):06d}_{_time.time_ns()}.parquet"
            )
            pending.clear()

    with tqdm(total=len(cells), unit="cell", disable=not progress, desc="basin") as bar:
        for index, columns in runner.stream(zeros, zeros, inits):
            part = cells.iloc[index].reset_index(drop=True)
            summary = {k: v for k, v in columns.items() if k not in ("force", "duration")}
            summary["outcome"] = np.asarray(OUTCOMES, dtype=object)[summary["outcome"]]
            summary["fall_cause"] = np.asarray(FALL_CAUSES, dtype=object)[summary["fall_cause"]]
            part = pd.concat([part, pd.DataFrame(summary)], axis=1)
            part[["q_a0", "q_h0", "dq_a0", "dq_h0"]] = inits[index]
            pending.append(part)
            bar.update(len(index))
            if _time.perf_counter() - last > FLUSH_SECONDS:
                flush()
                last = _time.perf_counter()
    flush()


def push_ends(
    config: Config,
    plane: Plane,
    forces: Any,
    durations: Any,
    *,
    cached: Path | None = None,
    progress: bool = False,
) -> pd.DataFrame:
    """Every push cell of the grid with the push run's outcome and the CoM state (relative to
    the ankle) and joint state at the end of its push (scalar reference runs; NaN for a push
    that ends the run before it ends). Read from ``cached`` (pushes.csv) when it holds this
    grid."""
    from tqdm import tqdm

    forces, durations = parse_grid(forces, "forces"), parse_grid(durations, "durations")
    cells = [(float(f), float(d)) for f in forces for d in durations]
    if cached is not None and cached.exists():
        old = pd.read_csv(cached)
        if sorted(zip(old.force, old.duration)) == sorted(cells):
            return old
    rows = []
    dt = config.scenario.physics_dt
    for force, duration in tqdm(cells, unit="push", disable=not progress, desc="push ends"):
        n_push = int(push_steps(duration, dt))
        summary, series = reference.simulate_scenario(config, force, duration)
        assert series is not None  # (record=True, the default)
        row = {"force": force, "duration": duration, "outcome": summary["outcome"]}
        end = dict.fromkeys(("x_com", "v_com", "q_a", "q_h", "dq_a", "dq_h"), math.nan)
        if n_push >= 2 and len(series) >= n_push:
            com = series["com"].to_numpy() - series["foot_x"].to_numpy() - plane.ankle_x
            last = series.iloc[n_push - 1]
            end = {
                "x_com": com[n_push - 1],
                "v_com": (com[n_push - 1] - com[n_push - 2]) / dt,
                "q_a": last.q_a,
                "q_h": last.q_h,
                "dq_a": last.dq_a,
                "dq_h": last.dq_h,
            }
        rows.append({**row, **end})
    return pd.DataFrame(rows)


def nearest_outcomes(frame: pd.DataFrame, ends: pd.DataFrame) -> np.ndarray:
    """The basin's outcome at the cell nearest each push end (grid-step units)."""
    xs, vs = np.sort(frame.x_com.unique()), np.sort(frame.v_com.unique())
    dx = np.diff(xs).min() if len(xs) > 1 else 1.0
    dv = np.diff(vs).min() if len(vs) > 1 else 1.0
    d = ((frame.x_com.to_numpy()[None] - ends.x_com.to_numpy()[:, None]) / dx) ** 2 + (
        (frame.v_com.to_numpy()[None] - ends.v_com.to_numpy()[:, None]) / dv
    ) ** 2
    return frame.outcome.to_numpy()[d.argmin(axis=1)]


def reading(frame: pd.DataFrame, ends: pd.DataFrame | None = None) -> str:
    """A paragraph from the map's numbers: how much recovers, against the capture-point bound,
    the basin's extent through rest, the energies, and whether the push cells' end states
    fall where the basin predicts."""
    ok = frame.outcome == "recovered"
    n, k = len(frame), int(ok.sum())
    inside = frame.capture_inside.astype(bool)
    text = (
        f"{k} of {n} initial states recover ({k / n:.0%}); {int((ok & inside).sum())} of "
        f"them have the capture point on the foot, {int((ok & ~inside).sum())} not; of the "
        f"{int(inside.sum())} capturable cells {(ok & inside).sum() / max(inside.sum(), 1):.0%}"
        " recover."
    )
    for name, fixed, along, unit in (
        ("x_com", "x_com", "v_com", "m/s"),
        ("v_com", "v_com", "x_com", "m"),
    ):
        line = frame[np.isclose(frame[fixed], 0.0) & ok]
        if len(line):
            text += (
                f" At {name} = 0 the recovered {along} span {line[along].min():g} to "
                f"{line[along].max():g} {unit}."
            )
    if k:
        energy = frame.energy_total[ok]
        text += f" Recovery energy: median {energy.median():.3g} J, largest {energy.max():.3g} J."
    if ends is not None:
        ends = ends[np.isfinite(ends.x_com)]
        if len(ends):
            basin_says = nearest_outcomes(frame, ends)
            pushed = ends.outcome.to_numpy()
            agree = int(((basin_says == "recovered") == (pushed == "recovered")).sum())
            text += (
                f" Of {len(ends)} push cells' end-of-push states, {agree} land where the "
                "basin (nearest cell) predicts the push run's outcome."
            )
    return text


def plot_basin(
    frame: pd.DataFrame, plane: Plane, path: Path, ends: pd.DataFrame | None, posture: str
) -> Path:
    """Outcome and recovery energy over (x_com, v_com), the foot's edges, the capture-point
    bound, and the push cells' end states."""
    from matplotlib.colors import ListedColormap

    xs, vs = np.sort(frame.x_com.unique()), np.sort(frame.v_com.unique())
    table = frame.pivot(index="v_com", columns="x_com", values="outcome").loc[vs, xs]
    recovered = (table == "recovered").to_numpy(float)
    energy = frame.pivot(index="v_com", columns="x_com", values="energy_total").loc[vs, xs]
    energy = np.where(recovered > 0, energy.to_numpy(float), np.nan)

    def edges(v):
        mid = (v[1:] + v[:-1]) / 2
        first = v[0] - (mid[0] - v[0]) if len(v) > 1 else v[0] - 0.5
        last = v[-1] + (v[-1] - mid[-1]) if len(v) > 1 else v[-1] + 0.5
        return np.concatenate([[first], mid, [last]])

    fig, axes = figure_style.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    ex, ev = edges(xs), edges(vs)
    colours = figure_style.OUTCOME_COLOURS  # not recovered: the fell colour, hatched
    axes[0].pcolormesh(
        ex,
        ev,
        recovered,
        cmap=ListedColormap([colours["fell"], colours["recovered"]]),
        vmin=0,
        vmax=1,
    )
    axes[0].pcolor(
        ex,
        ev,
        np.ma.masked_where(recovered > 0, np.ones_like(recovered)),
        hatch=figure_style.OUTCOME_HATCHES["fell"],
        facecolor="none",
        edgecolor="0.15",
        linewidth=0.0,
    )
    mesh = axes[1].pcolormesh(ex, ev, energy, cmap="viridis")
    fig.colorbar(mesh, ax=axes[1], label="recovery energy (energy_total) [J]")
    line = np.linspace(ex[0], ex[-1], 50)
    for ax in axes:
        for x, name in ((plane.heel, "heel"), (plane.toe, "toe")):
            ax.axvline(x, color="0.2", lw=1.2, ls=":")
            ax.text(x, ev[-1], f" {name}", va="top", fontsize=8)
        for edge, label in ((plane.heel, "capture point on the foot (LIP)"), (plane.toe, None)):
            ax.plot(line, plane.omega0 * (edge - line), color="k", lw=1.5, ls="--", label=label)
        if ends is not None and len(ends):
            ends = ends[np.isfinite(ends.x_com)]
            ok = ends.outcome == "recovered"
            ax.scatter(
                ends.x_com[ok],
                ends.v_com[ok],
                s=14,
                marker="o",
                facecolors="none",
                edgecolors="black",
                label="push end, push recovered",
            )
            ax.scatter(
                ends.x_com[~ok],
                ends.v_com[~ok],
                s=14,
                marker="x",
                color="black",
                label="push end, push not recovered",
            )
        ax.set_xlim(ex[0], ex[-1])
        ax.set_ylim(ev[0], ev[-1])
        ax.set_xlabel("CoM position relative to the ankle x_com [m]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("CoM velocity v_com [m/s]")
    axes[0].set_title(f"Recovery basin ({posture} posture): green recovers, hatched does not")
    axes[1].set_title("Energy of the recovered initial states")
    axes[0].legend(loc="lower left", fontsize=8, framealpha=0.9)
    return figure_style.save(fig, path, dpi=110)
