"""The batch runner: many scenarios of one configuration through the compiled closed loop.

:class:`BatchRunner` builds the MuJoCo model, the QP and the ADMM matrices once. Scenarios run
on the continuous-batching engine (``engine.py``: fixed slots per device, each refilled when its
scenario is decided); with ``trajectories=True`` they run instead to t_end in one padded batch
of :func:`kernel.scenario` under ``jax.vmap`` (the next power of two, at least 8), which returns
every physics step. Summary columns are made on the host in float64 (:func:`summarize`). The
model, QP and ADMM data are traced arguments of the compiled functions, which are cached per
shape key: configurations that differ only in numbers (body, convention, weights) share one
compile. With several local devices the work is split over them (shard_map over a 1-D mesh).
"""

from __future__ import annotations

import functools
import math
import time as _time
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from ..control import admm as admm_mod
from ..control import law as law_mod
from ..measures import capture, outcomes
from ..control import offset_free
from ..model.linear import S as JOINT_TO_ABS
from ..model.linear import LinearModel, delay_predictor
from ..measures.metrics import study_energies
from ..measures.outcomes import FELL, RECOVERED, Limits, summary_frame
from ..model.params import Config, ControllerParams, ScenarioParams, push_steps
from ..control.qp import build_qp
from ..runtime.compiled import get_or_compile
from .cpath import CEngine, unsupported
from .engine import Engine
from .kernel import Accumulators, Arrays, Static, scenario, split_limits
from ..model.mjcf import settled_rest
from .physics import canonical_hfield_bounds, mj_model, mjx_model, rest_data
from .sensing import sensors


def _bucket(n: int, minimum: int = 8) -> int:
    """Padded batch size: the next power of two (>= minimum), so few sizes are compiled."""
    return max(minimum, 1 << max(0, math.ceil(math.log2(max(n, 1)))))


def _static(
    config: Config,
    settings: admm_mod.ADMMSettings,
    limits: Limits,
    compensate: bool,
    trajectories: bool,
    law: law_mod.Controller | None,
) -> Static:
    """The compile-time part of a runner's configuration (``kernel.Static``)."""
    sc = config.scenario
    return Static(
        n_control=sc.n_control,
        substeps=sc.substeps,
        delay_steps=sc.delay_steps,
        push_at_hip=sc.push_body == "hip",
        settings=settings,
        trajectories=trajectories,
        limits=limits,
        compensate=compensate,
        offset_free=config.controller.offset_free,
        law=None if law is None else law.law,
    )


def _delay_prediction(
    lm: LinearModel, ctrl: ControllerParams, sc: ScenarioParams
) -> tuple[bool, np.ndarray, np.ndarray]:
    """Whether the controller compensates its delay, and its predictor's (A, G) matrices."""
    compensate = bool(ctrl.delay_compensation and sc.assumed_delay_steps > 0)
    pred_A, pred_G = (
        delay_predictor(lm.Ac, lm.Bc, sc.physics_dt, sc.assumed_delay_steps, sc.substeps)
        if compensate
        else (np.eye(4), np.zeros((0, 4, 2)))
    )
    return compensate, pred_A, pred_G


class BatchRunner:
    """Closed-loop scenarios of one configuration, batched (MJX physics + ADMM MPC).

    The MuJoCo model, the QP and the ADMM matrices are built once; one compiled function per
    padded batch size (the next power of two, at least 8; padding cells are F = 0, T = 0).
    With several local JAX devices (``devices``, default ``jax.local_devices()``) each batch
    is split over them along the scenario axis (a 1-D mesh, NamedSharding, shard_map).
    """

    def __init__(
        self,
        config: Config,
        *,
        dtype=jnp.float32,
        trajectories: bool = False,
        mjx_options: dict[str, Any] | None = None,
        devices: list | None = None,
        slots: int | None = None,
        early_stop: bool = True,
        physics: str = "mjx",
        threads: int | None = None,
        admm_tile: int | None = None,
    ):
        if physics not in ("mjx", "c"):
            raise ValueError(
                f"physics must be 'mjx' or 'c' (resolve 'auto' first), got {physics!r}"
            )
        self.config = config
        self.physics = physics
        self.dtype = jnp.dtype(dtype)
        self.trajectories = trajectories
        body, ctrl, sc = config.body, config.controller, config.scenario
        self.model = mj_model(config, mjx_options)
        mx = mjx_model(self.model, self.dtype)
        d0 = rest_data(self.model, self.dtype)
        self.sensors = sensors(self.model, d0)
        qp = build_qp(ctrl, body, sc.control_dt)
        self.qp = qp
        settings = admm_mod.settings_from_controller(ctrl)
        lm = qp.linear
        to_state = np.linalg.solve(lm.P, JOINT_TO_ABS)
        compensate, pred_A, pred_G = _delay_prediction(lm, ctrl, sc)
        limits, bounds = split_limits(Limits.from_params(sc, ctrl), self.dtype)
        law = law_mod.controller_of(config)  # None: the MPC
        self.arrays = Arrays(
            mx=canonical_hfield_bounds(mx, self.model),
            d0=d0,
            qp=admm_mod.build_admm(qp, settings, dtype=self.dtype),
            to_state=jnp.asarray(to_state, self.dtype),
            torque_map=jnp.asarray(lm.torque_map, self.dtype),
            pred_A=jnp.asarray(pred_A, self.dtype),
            pred_G=jnp.asarray(pred_G, self.dtype),
            ofs=offset_free.cast(offset_free.build(qp, ctrl), jnp, self.dtype),
            settled=jnp.asarray(settled_rest(self.model), self.dtype),
            bounds=bounds,
            rate_step=jnp.asarray(ctrl.rate_steps(sc.control_dt), self.dtype),
            relaxed=jnp.asarray(sc.relaxed_start),
            ramp_steps=jnp.asarray(sc.ramp_steps, self.dtype),
            capture=jnp.asarray(capture.step_model(config).data(), self.dtype),
            n_control=jnp.asarray(sc.n_control, jnp.int32),
            law=() if law is None else law_mod.cast(law.params, self.dtype),
        )
        self.static = _static(config, settings, limits, compensate, trajectories, law)
        devices = list(jax.local_devices() if devices is None else devices)
        self.mesh = jax.sharding.Mesh(np.array(devices), ("batch",)) if len(devices) > 1 else None
        if self.mesh is not None:  # the shared arrays, replicated on every device once
            self.arrays = jax.device_put(self.arrays, self._shardings()[1])
        self._compiled_fns: dict[int, Any] = {}
        self.compile_seconds: dict[int, float] = {}
        self.last_trajectories: dict[str, np.ndarray] | None = None
        self._engine_options = dict(slots=slots, early_stop=early_stop)
        if physics == "c":
            reason = unsupported(config, trajectories)
            if reason:
                raise ValueError(reason)
            self._engine_options["threads"] = threads
        elif admm_tile is not None:  # slots per ADMM loop (Engine's tile)
            self._engine_options["tile"] = admm_tile
        self._engine = None
        self.last_periods: np.ndarray | None = None  # control periods simulated per scenario
        self.last_certified: np.ndarray | None = None

    @property
    def engine(self):
        """The continuous-batching engine (``engine.py``) that runs scenarios without
        trajectories."""
        if self._engine is None:
            engine = CEngine if self.physics == "c" else Engine
            self._engine = engine(self, **self._engine_options)
        return self._engine

    def is_prepared(self) -> bool:
        """Whether :meth:`run` would compile nothing."""
        if self.trajectories:
            return self.is_compiled(8)
        return self._engine is not None and self._engine._fn is not None

    def prepare(self) -> float:
        """Compile what :meth:`run` uses now; returns the seconds it took (0 if done)."""
        t0 = _time.perf_counter()
        if self.trajectories:
            self.compiled(8)
        else:
            self.engine.block_fn()
        return _time.perf_counter() - t0

    # -- compilation ----------------------------------------------------------------------

    def _batched(self):
        sensors, static = self.sensors, self.static

        def run_batch(arrays: Arrays, force: jax.Array, n_push: jax.Array):
            one = functools.partial(scenario, arrays, sensors, static)
            return jax.vmap(one)(force, n_push)  # the one place batching is added

        mesh = self.mesh
        if mesh is None:
            return jax.jit(run_batch)
        # Several devices: each runs ``run_batch`` on its slice of the batch (shard_map), so
        # its loops (the ADMM while_loop, the contact solver) stop for its own scenarios only
        # and no device waits on another inside the scan.
        P = jax.sharding.PartitionSpec
        sharded = jax.shard_map(
            run_batch,
            mesh=mesh,
            in_specs=(P(), P("batch"), P("batch")),
            out_specs=P("batch"),
            check_vma=False,
        )
        return jax.jit(sharded)

    def _shape_key(self, batch: int, static: Static | None = None) -> tuple:
        """What the compiled function depends on besides the traced arrays' values: their
        tree structure, shapes and dtypes, the static addresses and settings (``static``:
        what the function bakes in, default the runner's), the batch."""
        leaves, treedef = jax.tree.flatten(self.arrays)
        sensors = tuple(
            tuple(np.asarray(v).ravel().tolist()) + (np.shape(v),) for v in self.sensors
        )
        devices = None if self.mesh is None else tuple(d.id for d in self.mesh.devices.flat)
        return (
            treedef,
            tuple((np.shape(v), str(v.dtype)) for v in leaves),
            sensors,
            self.static if static is None else static,
            batch,
            devices,
            jax.config.jax_enable_x64,  # type: ignore[attr-defined]  # flags set at run time
        )

    def compiled(self, batch: int):
        """The compiled batch function for a padded batch size (compiled ahead of time).

        The model, QP and ADMM data and the outcome rules' state and input bounds are traced
        arguments, so configurations of equal shapes (another body or subject, convention,
        weights or bounds; the same horizon, delay, t_end, ADMM settings and thresholds, which
        are static) share one compiled function (``runtime.compiled``)."""
        fn = self._compiled_fns.get(batch)
        if fn is None:
            t0 = _time.perf_counter()
            batch_sharding, _ = self._shardings()
            force = jax.ShapeDtypeStruct((batch,), self.dtype, sharding=batch_sharding)
            n_push = jax.ShapeDtypeStruct((batch,), jnp.int32, sharding=batch_sharding)
            fn = get_or_compile(
                self._shape_key(batch),
                lambda: self._batched().lower(self.arrays, force, n_push).compile(),
            )
            self.compile_seconds[batch] = _time.perf_counter() - t0
            self._compiled_fns[batch] = fn
        return fn

    def is_compiled(self, batch: int) -> bool:
        """Whether this runner already holds the compiled function for ``batch``."""
        return batch in self._compiled_fns

    def _shardings(self):
        """(batch axis split over the devices, replicated) NamedShardings; (None, None) on
        one device."""
        if self.mesh is None:
            return None, None
        P = jax.sharding.PartitionSpec
        return (
            jax.sharding.NamedSharding(self.mesh, P("batch")),
            jax.sharding.NamedSharding(self.mesh, P()),
        )

    def padded_batch(self, n: int) -> int:
        """The compiled batch size for n scenarios: the next power of two (>= 8), rounded up
        to a multiple of the number of devices (unchanged for 1, 2, 4 or 8 devices, so a
        sweep's chunk size is the compiled size)."""
        devices = 1 if self.mesh is None else self.mesh.devices.size
        return -(-_bucket(n) // devices) * devices

    # -- running --------------------------------------------------------------------------

    def _inputs(self, forces, durations) -> tuple[np.ndarray, np.ndarray]:
        forces = np.atleast_1d(np.asarray(forces, np.float64))
        durations = np.atleast_1d(np.asarray(durations, np.float64))
        if forces.ndim != 1 or forces.shape != durations.shape:
            raise ValueError(
                f"forces and durations must be 1-D arrays of one length, got "
                f"shapes {forces.shape} and {durations.shape}"
            )
        if not (np.isfinite(forces).all() and np.isfinite(durations).all()):
            raise ValueError("forces and durations must be finite")
        if (durations < 0).any():
            raise ValueError("durations must be >= 0")
        return forces, durations

    def run_raw(
        self, forces, durations, inits=None
    ) -> tuple[Accumulators, dict[str, np.ndarray] | None]:
        """Device results as numpy (accumulators, series), padding removed.

        Without trajectories the scenarios run on the continuous-batching engine (stopped when
        decided); with them, every scenario runs to t_end in one batch (padded). ``inits``
        [n, 4]: each scenario's initial joint state [q_a, q_h, dq_a, dq_h] (None: upright
        rest; the engine on the MJX path only)."""
        forces, durations = self._inputs(forces, durations)
        n = forces.shape[0]
        inits = self._initial_states(inits, n)
        if inits is not None and self.trajectories:
            raise ValueError("initial states run on the engine only (no trajectories)")
        if not self.trajectories:
            raw = self.engine.run(
                forces, push_steps(durations, self.config.scenario.physics_dt), inits
            )
            self.last_periods = raw.pop("periods").astype(np.int64)
            self.last_certified = raw.pop("certified").astype(bool)
            return Accumulators(*(raw[name] for name in Accumulators._fields)), None
        batch = self.padded_batch(n)
        f = np.zeros(batch, np.float64)
        f[:n] = forces
        steps = np.zeros(batch, np.int32)
        steps[:n] = push_steps(durations, self.config.scenario.physics_dt)
        fn = self.compiled(batch)
        batch_sharding, _ = self._shardings()
        f = np.asarray(f, self.dtype)
        if batch_sharding is None:
            acc, series = fn(self.arrays, jnp.asarray(f), jnp.asarray(steps))
        else:  # the batch axis split over the devices (padding cells F = 0, T = 0)
            acc, series = fn(
                self.arrays,
                jax.device_put(f, batch_sharding),
                jax.device_put(steps, batch_sharding),
            )
        acc = Accumulators(*(np.asarray(v)[:n] for v in acc))  # type: ignore[arg-type]  # the record's host (numpy) copy
        if series is not None:
            series = {k: np.asarray(v)[:n] for k, v in series.items()}
        return acc, series

    @staticmethod
    def _initial_states(inits, n: int) -> np.ndarray | None:
        if inits is None:
            return None
        inits = np.asarray(inits, np.float64)
        if inits.shape != (n, 4) or not np.isfinite(inits).all():
            raise ValueError(
                f"initial states must be finite, one [q_a, q_h, dq_a, dq_h] per "
                f"scenario ({n}, 4), got shape {inits.shape}"
            )
        return inits

    def run(self, forces, durations, inits=None) -> dict[str, np.ndarray]:
        """Summary of each scenario (SUMMARY_COLUMNS except convention, plus
        ``admm_iterations``, the ADMM iterations summed over the counted control periods):
        numpy arrays, one entry per scenario, outcome as int codes (``outcomes.OUTCOMES``).
        With ``trajectories=True`` the per-physics-step series of the batch are left in
        ``self.last_trajectories`` (arrays [B, n_steps, ...], plus time [n_steps])."""
        forces, durations = self._inputs(forces, durations)
        acc, series = self.run_raw(forces, durations, inits)
        summary = {
            "force": forces,
            "duration": durations,
            **summarize(acc, self.config, forces, durations),
        }
        if series is not None:
            sc = self.config.scenario
            n_steps = sc.n_control * sc.substeps
            series["time"] = (np.arange(n_steps) + 1) * sc.physics_dt
        self.last_trajectories = series
        return summary

    def stream(self, forces, durations, inits=None):
        """Run the scenarios on the engine; yield (indices, summary columns) as they are
        decided (the columns of :meth:`run`, plus ``periods``, the control periods simulated,
        and ``certified``). ``inits``: as :meth:`run_raw`."""
        forces, durations = self._inputs(forces, durations)
        inits = self._initial_states(inits, forces.shape[0])
        steps = push_steps(durations, self.config.scenario.physics_dt)
        for index, raw in self.engine.stream(forces, steps, inits):
            acc = Accumulators(*(raw[name] for name in Accumulators._fields))
            yield (
                index,
                {
                    "force": forces[index],
                    "duration": durations[index],
                    **summarize(acc, self.config, forces[index], durations[index]),
                    "periods": raw["periods"],
                    "certified": raw["certified"],
                },
            )

    def run_frame(self, forces, durations, inits=None) -> pd.DataFrame:
        """As :meth:`run`, as a table with columns ``outcomes.SUMMARY_COLUMNS`` (outcome as
        strings)."""
        summary = self.run(forces, durations, inits)
        return summary_frame(summary, self.config.controller.convention, extra=False)


def summarize(
    acc: Accumulators, config: Config, force=None, duration=None
) -> dict[str, np.ndarray]:
    """Summary columns from the final accumulators [B] (host side, float64); ``force`` [B]
    picks each margin of stability's edge (None: forward pushes); ``force`` and ``duration``
    [B] are the push still on after a fall for the capture columns (None: no push)."""
    sc = config.scenario
    dt = sc.physics_dt

    def f64(v):
        return np.asarray(v, np.float64)

    def finite_or_nan(v):
        v = f64(v)
        return np.where(np.isfinite(v), v, np.nan)

    settled = np.asarray(acc.alive) & np.asarray(acc.in_band)
    outcome = outcomes.classify(np, np.asarray(acc.diverged), np.asarray(acc.fell), settled)
    outcome = outcome.astype(np.int32)
    settle = np.where(acc.last_outside >= 0, (f64(acc.last_outside) + 1) * dt, 0.0)
    settle = np.where(outcome == RECOVERED, settle, np.nan)
    fall_time = np.where(outcome == FELL, (f64(acc.fall_step) + 1) * dt, np.nan)
    periods = f64(acc.control_periods)
    with np.errstate(invalid="ignore", divide="ignore"):
        sat_ankle = np.where(periods > 0, f64(acc.saturated_ankle) / periods, np.nan)
        sat_hip = np.where(periods > 0, f64(acc.saturated_hip) / periods, np.nan)
    energy_ankle, energy_hip = f64(acc.energy_ankle), f64(acc.energy_hip)
    return {
        "outcome": outcome,
        "settle_time": settle,
        "fall_time": fall_time,
        "peak_ankle": finite_or_nan(acc.peak_ankle),
        "peak_hip": finite_or_nan(acc.peak_hip),
        "peak_foot_pitch": finite_or_nan(acc.peak_foot_pitch),
        "cop_min": finite_or_nan(acc.cop_min),
        "cop_max": finite_or_nan(acc.cop_max),
        "com_min": finite_or_nan(acc.com_min),
        "com_max": finite_or_nan(acc.com_max),
        "peak_tau_ankle": finite_or_nan(acc.peak_tau_ankle),
        "peak_tau_hip": finite_or_nan(acc.peak_tau_hip),
        "ankle_saturation_fraction": sat_ankle,
        "hip_saturation_fraction": sat_hip,
        "energy_ankle": energy_ankle,
        "energy_hip": energy_hip,
        "energy_total": energy_ankle + energy_hip,
        "work_ankle": f64(acc.work_ankle),
        "work_hip": f64(acc.work_hip),
        "energy_u1": f64(acc.energy_u1),
        "energy_u2": f64(acc.energy_u2),
        **study_energies(f64(acc.work_u1), f64(acc.work_u2)),
        "nonconverged_solves": np.asarray(acc.nonconverged_solves, np.int64),
        "max_residual": finite_or_nan(acc.max_residual),
        "max_bound_violation": f64(acc.max_bound_violation),
        "fall_cause": np.asarray(acc.fall_cause, np.int32),
        "first_infeasible_time": np.where(
            acc.first_infeasible >= 0, f64(acc.first_infeasible) * sc.control_dt, np.nan
        ),
        "admm_iterations": np.asarray(acc.admm_iterations, np.int64),
        **balance_columns(acc, dt, force),
        **capture.columns(
            capture.step_model(config),
            outcome,
            (f64(acc.decision_step) + 1) * dt,
            f64(acc.decision_xcom),
            0.0 if force is None else force,
            0.0 if duration is None else duration,
        ),
    }


def balance_columns(acc: Accumulators, dt: float, force=None) -> dict[str, np.ndarray]:
    """The CoM velocity extremes and the smallest margin of stability in each push's direction
    (the toe margin for force >= 0, the heel margin for a backward push; None: forward) with
    the time of its sample (docs/model.md)."""

    def finite_or_nan(v):
        v = np.asarray(v, np.float64)
        return np.where(np.isfinite(v), v, np.nan)

    forward = (
        np.ones(np.shape(acc.mos_toe_min), bool)
        if force is None
        else (np.asarray(force, np.float64) >= 0)
    )
    step = np.where(forward, acc.mos_toe_step, acc.mos_heel_step)
    return {
        "com_vel_min": finite_or_nan(acc.com_vel_min),
        "com_vel_max": finite_or_nan(acc.com_vel_max),
        "mos_min": finite_or_nan(np.where(forward, acc.mos_toe_min, acc.mos_heel_min)),
        "mos_min_time": np.where(step >= 0, (np.asarray(step, np.float64) + 1) * dt, np.nan),
    }
