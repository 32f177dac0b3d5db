"""The solver benchmark (``mjx-balance bench solver``): the batched ADMM against OSQP and the
study's CasADi/IPOPT MPC, all on the same states in one run, so that the figures are ratios.

Steps, each a function returning its figures, run in turn by :func:`measure` (which
``cli.bench.solver_command`` calls and prints):

1. :func:`benchmark_states`: whole closed-loop trajectories (``states.closed_loop_states``) in a
   fixed random order over all pushes, until the requested number of states; then the OSQP truth
   at eps 1e-9 (``states.truth_solutions``).
2. :func:`admm_accuracy`: the ADMM along the trajectories, warm-started as in the closed loop
   (one sequential pass, which also makes the warm starts of step 3); first-control misses.
3. :func:`time_admm_batch`: jitted + vmapped solves of a batch of (state, warm start) pairs,
   compiled ahead of time (compile time apart), warmed up, timed with block_until_ready, median
   of repeats; FLOP/s from the iterations each tile executes.
4. :func:`osqp_search`: the warm-started OSQP loop (``states.osqp_loop``) at the loosest eps
   of ``OSQP_EPS`` whose first-control misses do not exceed the ADMM's, with its infeasibility
   detection on (OSQP's fastest setting).
5. :func:`time_ipopt`: the study's CasADi/IPOPT MPC (``bench.ipopt``), warm-started along the
   first states of the trajectories.

:func:`cpu_peak_gflops` gives the CPU's theoretical peak, against which the ADMM's FLOP/s are
put.
"""

from __future__ import annotations

import os
import time
from typing import Any, Callable, Iterator, NamedTuple

import numpy as np

from ..model.params import BodyParams, Config, ControllerParams
from ..control.qp import CondensedQP, build_qp
from .states import (
    PUSH_DURATIONS,
    TILE,
    Truth,
    admm_along_trajectories,
    closed_loop_states,
    first_control_error,
    misses,
    osqp_loop,
    truth_solutions,
)
from ..control import admm
from .ipopt import ipopt_mpc

OSQP_EPS = (1e-4, 1e-5, 1e-6)  # tried loosest first
IPOPT_SOLVES = 50  # CasADi/IPOPT solves timed
IPOPT_PER_TRAJECTORY = 10  # of them, at most this many along one trajectory


def median_seconds(fn: Callable[[], Any], repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn`` (which must block until done)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def admm_dtype(name: str):
    """The JAX dtype called ``name`` ("float32" or "float64"; the latter enables x64)."""
    import jax
    import jax.numpy as jnp

    if name == "float64":
        jax.config.update("jax_enable_x64", True)
        return jnp.float64
    return jnp.float32


def benchmark_states(
    qp: CondensedQP, body: BodyParams, n_states: int
) -> tuple[list[np.ndarray], np.ndarray, Truth]:
    """(trajectories, states [S, 4], truth): whole closed-loop trajectories in a fixed random
    order over all pushes, the last one cut so that S = n_states (or fewer if there are not
    enough), and OSQP's solutions at eps 1e-9."""
    trajectories, count = [], 0
    every = closed_loop_states(qp, body)
    for i in np.random.default_rng(0).permutation(len(every)):
        if count >= n_states:
            break
        traj = every[i][: n_states - count]
        trajectories.append(traj)
        count += len(traj)
    states = np.concatenate(trajectories)
    return trajectories, states, truth_solutions(qp, states)


def admm_accuracy(
    qp: CondensedQP, trajectories: list[np.ndarray], truth: Truth, settings, dtype
) -> dict[str, Any]:
    """The ADMM along the trajectories against the truth.

    Returns seq (``states.admm_along_trajectories``'s arrays, warm starts included), misses,
    max_err (over truth-solved states), max_err_both (over states both solved), mean_iters,
    status_counts [solved, max_iter, infeasible] and seconds (the whole pass).
    """
    t0 = time.perf_counter()
    seq = admm_along_trajectories(qp, trajectories, settings, dtype)
    err = first_control_error(qp, seq["u0"], truth)
    both = truth.solved & (seq["status"] == admm.SOLVED)
    return dict(
        seq=seq,
        misses=misses(err, truth),
        max_err=float(np.nanmax(err[truth.solved])),
        max_err_both=float(np.nanmax(err[both])),
        mean_iters=float(seq["iters"].mean()),
        status_counts=np.bincount(seq["status"], minlength=4)[1:].tolist(),
        seconds=time.perf_counter() - t0,
    )


def batch_indices(n_states: int, batch: int) -> np.ndarray:
    """Consecutive states (trajectory order, as a closed-loop batch would see them), starting a
    third of the way in so that batch 1 is not the trivial upright state; cycled if batch > S."""
    return (n_states // 3 + np.arange(batch)) % n_states


def time_admm_batch(
    qp: CondensedQP, settings, dtype, states: np.ndarray, seq: dict[str, np.ndarray], batch: int
) -> dict[str, Any]:
    """One batch size: compile, warm up, time (median); the row of the figures.

    Row: batch, tile, compile_s, seconds (per batch), solves_per_s, mean_iters, gflops (flops
    executed: every element of a tile runs as many iterations as its slowest one).
    """
    import jax
    import jax.numpy as jnp

    data = admm.build_admm(qp, settings, dtype)
    it_flops, chk_flops = flops_per_solve_step(qp, settings)
    idx = batch_indices(len(states), batch)
    x0 = jnp.asarray(states[idx], dtype)
    warm = admm.ADMMWarm(
        z=jnp.asarray(seq["warm_z"][idx], dtype), y=jnp.asarray(seq["warm_y"][idx], dtype)
    )
    tile = TILE if batch % TILE == 0 and batch > TILE else None
    fn = jax.jit(admm.admm_solve_batch, static_argnums=(3, 4))
    t0 = time.perf_counter()
    compiled = fn.lower(data, x0, warm, settings, tile).compile()
    compile_s = time.perf_counter() - t0
    res = jax.block_until_ready(compiled(data, x0, warm))  # warm-up
    repeats = 7 if batch <= 4096 else 3
    sec = median_seconds(lambda: jax.block_until_ready(compiled(data, x0, warm)), repeats)
    iters = np.asarray(res.iters)
    t = tile or batch
    executed = np.repeat(iters.reshape(-1, t).max(axis=1), t)
    flops = float(np.sum(executed * it_flops + executed / settings.check_every * chk_flops))
    return dict(
        batch=batch,
        tile=t,
        compile_s=compile_s,
        seconds=sec,
        solves_per_s=batch / sec,
        mean_iters=float(iters.mean()),
        gflops=flops / sec / 1e9,
    )


def osqp_at_eps(
    qp: CondensedQP, trajectories: list[np.ndarray], truth: Truth, eps: float
) -> dict[str, Any]:
    """The warm-started OSQP loop at ``eps``: misses, max_err, seconds per solve over all states
    and over the truth-solved ones, iterations (mean, median)."""
    u0, seconds, iters = osqp_loop(qp, trajectories, eps)
    err = first_control_error(qp, u0, truth)
    return dict(
        eps=eps,
        misses=misses(err, truth),
        max_err=float(np.nanmax(err[truth.solved])),
        seconds_per_solve=float(seconds.mean()),
        seconds_per_solved=float(seconds[truth.solved].mean()),
        mean_iters=float(iters.mean()),
        median_iters=float(np.median(iters)),
    )


def osqp_search(
    qp: CondensedQP, trajectories: list[np.ndarray], truth: Truth, admm_misses: int
) -> Iterator[dict[str, Any]]:
    """:func:`osqp_at_eps` for each eps of ``OSQP_EPS`` in turn, up to the first whose misses do
    not exceed ``admm_misses``; the last row yielded is the one compared (the tightest tried if
    none meets it)."""
    for eps in OSQP_EPS:
        row = osqp_at_eps(qp, trajectories, truth, eps)
        yield row
        if row["misses"] <= admm_misses:
            return


def time_ipopt(
    qp: CondensedQP,
    controller: ControllerParams,
    trajectories: list[np.ndarray],
    truth: Truth,
    n_solves: int = IPOPT_SOLVES,
    per_trajectory: int = IPOPT_PER_TRAJECTORY,
) -> dict[str, Any]:
    """CasADi/IPOPT on the first ``per_trajectory`` states of each trajectory, warm-started
    along it, until ``n_solves`` solves.

    Returns solves, seconds_per_solve and errors (first-control error against the truth, on the
    truth-solved states). Raises ImportError when casadi is not installed.
    """
    solve, shift = ipopt_mpc(qp, controller)
    done, errs, t_ipopt = 0, [], 0.0
    for traj, start in zip(trajectories, np.cumsum([0] + [len(t) for t in trajectories])):
        w = None
        for j, x0 in enumerate(traj[:per_trajectory]):
            t0 = time.perf_counter()
            u0, w_opt = solve(x0, w)
            t_ipopt += time.perf_counter() - t0
            w = shift(w_opt)
            if truth.solved[start + j]:
                errs.append(float(first_control_error(qp, u0, truth.select(start + j))))
            done += 1
            if done >= n_solves:
                break
        if done >= n_solves:
            break
    return dict(solves=done, seconds_per_solve=t_ipopt / done, errors=errs)


def cpu_peak_gflops(dtype: str = "float32") -> tuple[float, str]:
    """Theoretical peak from /proc/cpuinfo: cores x clock x flops/cycle (FMA width x 2 units).

    Returns (GFLOP/s, a note saying how it was counted).
    """
    cores = os.cpu_count() or 1
    flags: set[str]
    mhz, flags = 0.0, set()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("cpu MHz") and not mhz:
                    mhz = float(line.split(":")[1])
                elif line.startswith("flags") and not flags:
                    flags = set(line.split(":")[1].split())
    except OSError:
        pass
    lanes32 = 16 if "avx512f" in flags else 8 if "avx2" in flags else 4
    fma = 2 if "fma" in flags else 1
    units = 2  # two FMA ports per core (Xeon Scalable / recent client cores)
    per_cycle = lanes32 * fma * units // (2 if dtype == "float64" else 1)
    peak = cores * mhz * 1e-3 * per_cycle
    isa = "avx512f" if "avx512f" in flags else "avx2" if "avx2" in flags else "sse"
    return peak, (
        f"{cores} cores x {mhz / 1e3:.2f} GHz x {per_cycle} {dtype} flops/cycle "
        f"({isa}, {'FMA' if fma == 2 else 'no FMA'}, {units} vector units assumed)"
    )


def flops_per_solve_step(qp: CondensedQP, settings) -> tuple[int, int]:
    """(flops per ADMM iteration, flops per convergence check) of this QP and settings."""
    return admm.flops_per_iteration(qp.n, qp.m, settings.sigma), admm.flops_per_check(qp.n, qp.m)


def solver_figures(
    *,
    states: np.ndarray,
    controller: ControllerParams,
    dtype: str,
    accuracy: dict[str, Any],
    truth: Truth,
    admm_rows: list[dict],
    osqp_rows: list[dict],
    ipopt_seconds_per_solve: float,
    peak_gflops: float,
    settings,
) -> dict[str, Any]:
    """The benchmark's figures (what ``--json`` prints and ``--out`` writes)."""
    return dict(
        states=len(states),
        convention=controller.convention,
        dtype=dtype,
        admm_misses=accuracy["misses"],
        solved=int(truth.solved.sum()),
        infeasible=int(truth.infeasible.sum()),
        saturated=int(truth.saturated.sum()),
        admm=admm_rows,
        osqp=osqp_rows,
        osqp_chosen_eps=osqp_rows[-1]["eps"],
        ipopt_seconds_per_solve=ipopt_seconds_per_solve,
        peak_gflops=peak_gflops,
        settings=settings._asdict(),
    )


class SolverRun(NamedTuple):
    """One run of the solver benchmark: its figures (:func:`solver_figures`), how the CPU's
    peak was counted, the flops of one ADMM iteration and of one check, the run's seconds."""

    figures: dict[str, Any]
    peak_note: str
    flops: tuple[int, int]
    seconds: float


def measure(
    config: Config,
    *,
    batches: list[int],
    n_states: int,
    dtype: str = "float32",
    say: Callable[[str], None] = print,
) -> SolverRun:
    """The benchmark's steps in turn on ``n_states`` states of ``config``'s controller, each
    step's figures said through ``say`` as they come (the ADMM timed at each batch size of
    ``batches``, in ``dtype``)."""
    working = admm_dtype(dtype)
    controller, body = config.controller, config.body
    qp = build_qp(controller, body, config.scenario.control_dt)
    settings = admm.settings_from_controller(controller)
    t_start = time.perf_counter()

    trajectories, states, truth = benchmark_states(qp, body, n_states)
    say(
        f"states: {len(states)} from {len(trajectories)} closed-loop pushes (F 20..120 N, T "
        f"{'/'.join(str(d) for d in PUSH_DURATIONS)} s), convention {controller.convention}: "
        f"{truth.solved.sum()} solved by OSQP at 1e-9, {truth.infeasible.sum()} infeasible, "
        f"{(~truth.solved & ~truth.infeasible).sum()} not solved in 4000 iterations, "
        f"{truth.saturated.sum()} with a saturated first input"
    )

    acc = admm_accuracy(qp, trajectories, truth, settings, working)
    admm_miss = acc["misses"]
    say(
        f"ADMM ({dtype}, rho {settings.rho}, alpha {settings.alpha}, sigma "
        f"{settings.sigma}, cap {settings.iteration_cap} iterations, check every "
        f"{settings.check_every}, eps_abs {settings.eps_abs:g}, eps_rel {settings.eps_rel:g}): "
        f"misses {admm_miss}/"
        f"{truth.solved.sum()} ({100 * admm_miss / max(1, truth.solved.sum()):.2f}%), max "
        f"first-control error {acc['max_err']:.2e} of range (both solved: "
        f"{acc['max_err_both']:.2e}), mean iterations {acc['mean_iters']:.1f}, status "
        f"solved/max_iter/infeasible {acc['status_counts']} [{acc['seconds']:.1f} s]"
    )

    flops = flops_per_solve_step(qp, settings)
    peak, peak_note = cpu_peak_gflops(dtype)
    rows = []
    for B in batches:
        r = time_admm_batch(qp, settings, working, states, acc["seq"], B)
        rows.append(r)
        say(
            f"  ADMM batch {B:6d} (tile {r['tile']:5d}): compile {r['compile_s']:5.2f} s, "
            f"{r['seconds'] * 1e3:9.3f} ms/batch, {r['solves_per_s']:11.0f} solves/s, mean "
            f"iterations {r['mean_iters']:5.1f}, {r['gflops']:6.2f} GFLOP/s"
        )

    osqp_rows = []
    for r in osqp_search(qp, trajectories, truth, admm_miss):
        osqp_rows.append(r)
        per_solve, per_solved = r["seconds_per_solve"], r["seconds_per_solved"]
        say(
            f"  OSQP eps {r['eps']:g}: misses {r['misses']}/{truth.solved.sum()}, max error "
            f"{r['max_err']:.2e}, {per_solve * 1e6:8.1f} us/solve over all "
            f"states ({1 / per_solve:6.0f} solves/s; iterations mean {r['mean_iters']:.1f}, "
            f"median {r['median_iters']:.0f}: infeasible states run to 4000), "
            f"{per_solved * 1e6:8.1f} us/solve over the OSQP-solved states "
            f"({1 / per_solved:6.0f} solves/s)"
        )

    ipopt_per_solve = ipopt_seconds_per_solve(qp, controller, trajectories, truth, say)
    figures = solver_figures(
        states=states,
        controller=controller,
        dtype=dtype,
        accuracy=acc,
        truth=truth,
        admm_rows=rows,
        osqp_rows=osqp_rows,
        ipopt_seconds_per_solve=ipopt_per_solve,
        peak_gflops=peak,
        settings=settings,
    )
    return SolverRun(figures, peak_note, flops, time.perf_counter() - t_start)


def ipopt_seconds_per_solve(
    qp: CondensedQP,
    controller: ControllerParams,
    trajectories: list[np.ndarray],
    truth: Truth,
    say: Callable[[str], None] = print,
) -> float:
    """CasADi/IPOPT's seconds per solve on the benchmark's states (:func:`time_ipopt`), said
    through ``say``; NaN, and said, without casadi."""
    try:
        ip = time_ipopt(qp, controller, trajectories, truth)
    except ImportError:
        say("  CasADi/IPOPT: casadi not installed, skipped")
        return float("nan")
    per_solve, errs = ip["seconds_per_solve"], ip["errors"]
    say(
        f"  CasADi/IPOPT (multiple shooting, RK4 on Ac, Bc): {ip['solves']} solves, "
        f"{per_solve * 1e3:.2f} ms/solve ({1 / per_solve:.0f} solves/s); "
        f"first control vs the ZOH QP: median {np.median(errs):.1e}, max {max(errs):.1e} "
        f"of range (RK4 on Ac differs from exact ZOH)"
    )
    return per_solve
