"""Where a CPU sweep's time goes, and what a MuJoCo C physics path could gain
(``mjx-balance bench physics``).

One run measures, per scenario-step (one physics step of one scenario, wall time on all local
cores), side by side on the same slots and push scenarios:

1. ``mjx_step``: bare ``vmap(mjx.step)`` in a ``scan`` with the rollout's MJX options: the MJX
   physics-only limit.
2. ``mjx_step_kinematics``: the same plus an ``mjx.kinematics`` per step (what the closed loop
   paid before it read a sample's positions from the next step's start).
3. ``c_step``: MuJoCo C, ``mujoco.rollout`` on a persistent pool of one thread per core, the
   same model and options, stepped a control period (``substeps`` steps) per call with the
   per-step push and torques as its controls: the C physics-only limit, timed inside (5) as
   its time outside the ADMM calls.
4. ``pipeline``: the shipped closed loop (continuous-batching engine, MJX physics + batched
   ADMM + the outcome bookkeeping), run to t_end without early stopping so that every slot
   does the same work as in (5); simulated scenario-steps over wall time.
   ``closed_loop_admm_floor``: the closed loop's control periods (``kernel.period``, MJX
   physics, the sample bookkeeping) in lock-step over the slots for the whole window, with the
   ADMM cut to one check's worth of iterations (``admm_max_iter = admm_check_every``): the
   physics and its bookkeeping with almost no solver work (scenarios fall more often then; a
   fallen scenario is reset and steps on, so every slot steps all the time).
5. ``c_pipeline_bound``: a C closed loop without its bookkeeping: per control period one
   jitted call of the same batched ADMM for every slot, then (3). It leaves out everything a
   C path would add (the fall rules, the accumulators, refilling slots), so it bounds what
   a MuJoCo C path could reach from above.

``admm`` = the pipeline's ADMM share: (5) minus (3) per scenario-step (the same solves on the
same kind of states). The verdict is ``c_bound_vs_pipeline`` =
(4) / (5): a C path is worth shipping only if even this bound is at least 1.5.
"""

from __future__ import annotations

import math
import time
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from ..control import admm as admm_mod
from ..model.params import Config
from ..runtime.compiled import MATMUL_PRECISION
from ..rollout.physics import mjx
from ..rollout import kernel
from ..rollout.physics import mj_model
from ..model.mjcf import indices
from ..rollout import BatchRunner
from ..rollout.runner import push_steps as to_push_steps
from .pipeline import scenario_set

# a C path must beat the MJX pipeline by this factor to be worth a second physics path
WORTH_IT = 1.5
QUEUE = 4


def _best(fn, repeats: int) -> float:
    """Least wall time of ``repeats`` calls of ``fn`` (after one untimed call)."""
    fn()
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _mjx_steps(runner, forces: np.ndarray, n_steps: int, kinematics: bool) -> float:
    """Seconds per scenario-step of vmap(mjx.step) (+ mjx.kinematics) over the local devices."""
    arrays, sensors = runner.arrays, runner.sensors
    devices = jax.local_devices()
    mesh = jax.sharding.Mesh(np.array(devices), ("batch",))
    split = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))

    def one(force):
        def body(d, i):
            push = jnp.where(i < n_steps // 4, force, 0.0).astype(d.qpos.dtype)
            d = d.replace(
                xfrc_applied=jnp.zeros_like(d.xfrc_applied).at[sensors.upper_body, 0].set(push)
            )
            d = mjx.step(arrays.mx, d)
            return (mjx.kinematics(arrays.mx, d) if kinematics else d), None

        return jax.lax.scan(body, arrays.d0, jnp.arange(n_steps))[0].qpos

    fn = jax.jit(jax.vmap(one))
    f = jax.device_put(jnp.asarray(forces, runner.dtype), split)
    seconds = _best(lambda: jax.block_until_ready(fn(f)), 3)
    return seconds / (forces.size * n_steps)


def _closed_loop_steps(runner, forces: np.ndarray, push_steps: np.ndarray, periods: int) -> float:
    """Seconds per scenario-step of ``periods`` control periods of ``kernel.period`` for every
    scenario in lock-step, split over the local devices."""
    arrays, sensors, static = runner.arrays, runner.sensors, runner.static
    devices = jax.local_devices()
    split = jax.sharding.NamedSharding(
        jax.sharding.Mesh(np.array(devices), ("batch",)), jax.sharding.PartitionSpec("batch")
    )

    def one(force, n_push):
        def body(carry, k):
            return kernel.period(arrays, sensors, static, carry, k, force, n_push)[0], None

        carry = kernel.initial_carry(arrays, sensors, static)
        return jax.lax.scan(body, carry, jnp.arange(periods, dtype=jnp.int32))[0].acc.alive

    fn = jax.jit(jax.vmap(one))
    f = jax.device_put(jnp.asarray(forces, runner.dtype), split)
    n = jax.device_put(jnp.asarray(push_steps, jnp.int32), split)
    with jax.default_matmul_precision(MATMUL_PRECISION):
        seconds = _best(lambda: jax.block_until_ready(fn(f, n)), 3)
    return seconds / (forces.size * periods * static.substeps)


class CPhysics:
    """MuJoCo C stepping of every slot by one control period per call (``mujoco.rollout``)."""

    def __init__(self, config: Config, slots: int, threads: int):
        self.model = mj_model(config)  # the MJX options, also on the C side
        self.slots, self.threads = slots, threads
        self.substeps = config.scenario.substeps
        self.datas = [mujoco.MjData(self.model) for _ in range(threads)]
        self.models = [self.model] * slots  # one per rollout (skip_checks wants the list)
        data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, data)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.state_spec = int(spec)
        size = mujoco.mj_stateSize(self.model, spec)
        state0 = np.empty(size)
        mujoco.mj_getState(self.model, data, state0, spec)
        self.state = np.tile(state0, (slots, 1))
        self.control_spec = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_XFRC_APPLIED)
        nc = mujoco.mj_stateSize(self.model, self.control_spec)
        self.control = np.zeros((slots, self.substeps, nc))
        self.out = np.empty((slots, self.substeps, size))
        self.sensordata = np.empty((slots, self.substeps, self.model.nsensordata))

        ix = indices(self.model)
        nq = self.model.nq
        # offsets into the full-physics state: [time, qpos, qvel, ...]
        self.q_index = 1 + np.array([ix.ankle_qpos, ix.hip_qpos])
        self.v_index = 1 + nq + np.array([ix.ankle_dof, ix.hip_dof])
        self.push_index = self.model.nu + 6 * ix.upper_body  # x force of the upper body
        self.pool = mj_rollout.Rollout(nthread=threads)

    def period(self, torques: np.ndarray, push: np.ndarray) -> np.ndarray:
        """Advance every slot by one control period; torques [slots, 2], push [slots, S].
        Returns the joint state (q, dq) [slots, 4] at the period's end."""
        self.control[:, :, :2] = torques[:, None, :]
        self.control[:, :, self.push_index] = push
        self.pool.rollout(
            self.models,
            self.datas,
            self.state,
            self.control,
            control_spec=self.control_spec,
            nstep=self.substeps,
            state=self.out,
            sensordata=self.sensordata,
            skip_checks=True,
        )
        self.state = self.out[:, -1].copy()
        return np.concatenate([self.state[:, self.q_index], self.state[:, self.v_index]], 1)

    def close(self) -> None:
        self.pool.close()


def _c_closed_loop(
    c: CPhysics, runner, forces: np.ndarray, push_steps: np.ndarray, periods: int
) -> tuple[float, float]:
    """(seconds per scenario-step, ADMM seconds per scenario-step) of the C closed loop bound:
    per period one jitted batched ADMM call, then one C period."""
    arrays, static = runner.arrays, runner.static
    S = c.substeps

    @jax.jit
    def control(joints, warm):
        def one(jq, w):
            x = arrays.to_state @ jq[:2], arrays.to_state @ jq[2:]
            res = admm_mod.admm_solve(arrays.qp, jnp.concatenate(x), w, static.settings)
            return arrays.torque_map @ res.u0, admm_mod.ADMMWarm(*res.warm_next)

        return jax.vmap(one)(joints, warm)

    devices = jax.local_devices()
    split = jax.sharding.NamedSharding(
        jax.sharding.Mesh(np.array(devices), ("batch",)), jax.sharding.PartitionSpec("batch")
    )
    warm0 = jax.device_put(
        jax.vmap(lambda _: admm_mod.initial_warm(arrays.qp))(jnp.arange(c.slots)), split
    )
    state0 = c.state.copy()
    times = {"admm": 0.0}

    def run():
        c.state = state0.copy()
        joints = np.zeros((c.slots, 4), np.float32)
        warm = warm0
        for k in range(periods):
            t0 = time.perf_counter()
            torques, warm = control(jax.device_put(joints, split), warm)
            torques = np.asarray(torques, np.float64)
            times["admm"] += time.perf_counter() - t0
            steps = k * S + np.arange(S)
            push = np.where(steps[None, :] < push_steps[:, None], forces[:, None], 0.0)
            joints = c.period(torques, push).astype(np.float32)

    run()  # compile
    times["admm"] = 0.0
    t0 = time.perf_counter()
    run()
    total = time.perf_counter() - t0
    n = c.slots * periods * S
    return total / n, times["admm"] / n


def measure(
    config: Config, *, slots: int = 64, seconds: float = 3.0, threads: int | None = None
) -> dict[str, Any]:
    """Every figure of the module docstring, per scenario-step in microseconds, and the
    ratios; ``slots`` scenarios side by side (split over the local devices for MJX, over
    ``threads`` C threads, default one per local device), ``seconds`` of simulated time."""
    sc = config.scenario
    config = config.replace(scenario={"t_end": seconds})
    threads = threads or len(jax.local_devices())
    periods = config.scenario.n_control
    n_steps = periods * sc.substeps
    # the pipeline gets QUEUE times as many scenarios as slots, so that its slots stay busy
    # while scenarios fall and are replaced (the C bound runs its slots in lock-step)
    forces, durations = scenario_set(QUEUE * slots, seconds)
    runner = BatchRunner(config, early_stop=False)  # its arrays, for (1), (2) and (5)

    us = {}
    us["mjx_step"] = 1e6 * _mjx_steps(runner, forces[:slots], n_steps, kinematics=False)
    us["mjx_step_kinematics"] = 1e6 * _mjx_steps(runner, forces[:slots], n_steps, kinematics=True)
    per_device = max(1, slots // len(jax.local_devices()))

    engine = BatchRunner(config, early_stop=False, slots=per_device)
    engine.prepare()
    t0 = time.perf_counter()
    engine.run(forces, durations)
    wall = time.perf_counter() - t0
    assert engine.last_periods is not None  # (set by run)
    us["pipeline"] = 1e6 * wall / (engine.last_periods.sum() * sc.substeps)
    floor = BatchRunner(
        config.replace(controller={"admm_max_iter": config.controller.admm_check_every})
    )
    us["closed_loop_admm_floor"] = 1e6 * _closed_loop_steps(
        floor, forces[:slots], to_push_steps(durations[:slots], sc.physics_dt), periods
    )
    c = CPhysics(config, slots, threads)
    try:
        bound, admm = _c_closed_loop(
            c, runner, forces[:slots], to_push_steps(durations[:slots], sc.physics_dt), periods
        )
    finally:
        c.close()
    us["c_pipeline_bound"], us["admm"] = 1e6 * bound, 1e6 * admm
    us["c_step"] = us["c_pipeline_bound"] - us["admm"]
    return {
        "slots": slots,
        "threads": threads,
        "devices": len(jax.local_devices()),
        "simulated_s": seconds,
        "us_per_scenario_step": {k: round(v, 3) for k, v in us.items()},
        "pipeline_vs_mjx_step": round(us["pipeline"] / us["mjx_step"], 3),
        "closed_loop_physics_vs_mjx_step": round(us["closed_loop_admm_floor"] / us["mjx_step"], 3),
        "mjx_step_vs_c_step": round(us["mjx_step"] / us["c_step"], 3),
        "c_bound_vs_pipeline": round(us["pipeline"] / us["c_pipeline_bound"], 3),
        "c_path_worth_it": bool(us["pipeline"] / us["c_pipeline_bound"] >= WORTH_IT),
    }
