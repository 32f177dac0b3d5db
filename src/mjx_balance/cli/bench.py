"""``mjx-balance bench`` and its sub-commands ``solver``, ``physics`` and ``engine``: run the
benchmarks of ``mjx_balance.bench`` step by step and print their figures as they come."""

from __future__ import annotations

import argparse
import json
import os
import resource
from pathlib import Path
from typing import Any

from ..model.params import Config
from ..model.params import ParameterError
from .common import load_run_config
from .options import (
    EPILOG,
    HelpFormatter,
    batch_sizes,
    common_options,
    conventions_parent,
    engine_options,
    nonnegative_int,
    positive_float,
    positive_int,
    positive_int_list,
)


def add_parser(sub: Any) -> None:
    """``bench`` and its sub-commands ``bench solver``, ``bench physics`` and ``bench engine``
    (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "bench",
        help="pipeline benchmark: batched MJX + ADMM vs the scalar "
        "reference vs CasADi/IPOPT, scenarios per second (or: "
        "bench solver)",
    )
    _pipeline_arguments(p)
    common_options(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:pipeline_command")
    bench = p.add_subparsers(dest="bench", required=False, metavar="{solver,physics,engine}")
    conventions = conventions_parent()
    p = bench.add_parser(
        "solver",
        help="batched ADMM vs OSQP vs CasADi/IPOPT, solves per second",
        description="batched ADMM vs OSQP vs CasADi/IPOPT, solves per second",
        formatter_class=HelpFormatter,
        epilog=EPILOG,
        parents=[conventions],
    )
    p.add_argument(
        "--batch",
        type=batch_sizes,
        default="1,16,256,4096,16384",
        help="comma-separated batch sizes",
    )
    p.add_argument("--states", type=positive_int, default=4096, help="number of test states")
    p.add_argument("--dtype", choices=("float32", "float64"), default="float32")
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")
    common_options(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:solver_command")
    p = bench.add_parser(
        "physics",
        help="where a CPU sweep's time goes: bare MJX step, closed "
        "loop, pipeline, ADMM, MuJoCo C (mujoco.rollout) and "
        "a C path's bound, per scenario-step",
        description="per scenario-step costs of the physics paths side by "
        "side (bench/physics.py explains each figure)",
        formatter_class=HelpFormatter,
        epilog=EPILOG,
        parents=[conventions],
    )
    p.add_argument(
        "--slots",
        type=positive_int,
        default=64,
        help="scenarios side by side (split over the host devices / C threads)",
    )
    p.add_argument(
        "--seconds", type=positive_float, default=2.0, help="simulated window of each scenario [s]"
    )
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")
    common_options(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:physics_command")
    _engine_parser(bench, conventions)


def _engine_parser(bench: Any, conventions: argparse.ArgumentParser) -> None:
    """``bench engine``: the engine's time per control period, split, on each physics path."""
    p = bench.add_parser(
        "engine",
        help="the engine's time per control period split into "
        "physics, QP build, ADMM, certificate, refill, "
        "transfers and Python, on each physics path",
        description="the continuous-batching engine as sweep runs it, its "
        "time per control period split into its parts on each "
        "physics path (bench/engine.py explains each figure); "
        "about 2 minutes on 2 cores with a warm compilation "
        "cache, longer the first time (it compiles each stage)",
        formatter_class=HelpFormatter,
        epilog=EPILOG,
        parents=[conventions],
    )
    p.add_argument(
        "--forces",
        default="0:155:5",
        help="push forces [N], as sweep --forces (default: 32 forces)",
    )
    p.add_argument(
        "--durations",
        default="0.05,0.1,0.15,0.2,0.3,0.5,1.0,1.5",
        help="push durations [s], as sweep --durations (default: the default sweep's)",
    )
    p.add_argument(
        "--physics",
        default="mjx,c",
        type=_physics_paths,
        help="comma-separated physics paths (mjx, c)",
    )
    p.add_argument(
        "--slots",
        type=positive_int,
        default=None,
        help="slots per device (default: the engine's, as sweep)",
    )
    p.add_argument(
        "--t-end",
        type=positive_float,
        default=None,
        help="scenario length [s] (default: the configuration's, 12)",
    )
    p.add_argument(
        "--admm-tile",
        type=positive_int,
        default=None,
        help="MJX path: slots per ADMM loop, a divisor of the slots per device, "
        "the tiles solved one after the other (default: one loop over a "
        "device's slots, as sweep runs)",
    )
    p.add_argument(
        "--runs",
        type=positive_int,
        default=2,
        help="timed runs of every cell (the figures in run are their mean)",
    )
    p.add_argument(
        "--repeats",
        type=positive_int,
        default=3,
        help="timed calls of each stage over each block's replayed periods (median)",
    )
    p.add_argument(
        "--sampled",
        type=positive_int,
        default=10,
        help="of every 100 control periods (every block), how many are replayed "
        "stage by stage (the stage times are scaled up to all)",
    )
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")
    common_options(p, out_required=False)
    p.set_defaults(target="mjx_balance.cli.bench:engine_command")


def _physics_paths(text: str) -> tuple[str, ...]:
    paths = tuple(dict.fromkeys(t.strip() for t in text.split(",") if t.strip()))
    if not paths or any(t not in ("mjx", "c") for t in paths):
        raise argparse.ArgumentTypeError(f"expected a comma list of mjx and c, got {text!r}")
    return paths


def _pipeline_arguments(p: argparse.ArgumentParser) -> None:
    """Options of ``mjx-balance bench`` (the pipeline benchmark)."""
    p.add_argument(
        "--scenarios",
        type=positive_int,
        default=1024,
        help="scenarios through MJX + ADMM (continuous batching and --full-length)",
    )
    p.add_argument(
        "--reference-runs",
        dest="reference",
        type=nonnegative_int,
        default=16,
        help="of those, how many through the scalar reference (0: skip)",
    )
    p.add_argument(
        "--ipopt",
        type=nonnegative_int,
        default=8,
        help="of those, how many through CasADi/IPOPT + MuJoCo C, with the "
        "reference's outcome mix (0: skip)",
    )
    p.add_argument(
        "--workers",
        type=positive_int,
        default=os.cpu_count() or 2,
        help="worker processes of the reference and the study toolchain",
    )
    engine_options(p)
    p.add_argument("--repeats", type=positive_int, default=1, help="timed MJX runs (median)")
    p.add_argument(
        "--t-end", type=positive_float, default=None, help="scenario length [s] (default 12)"
    )
    p.add_argument(
        "--osqp-max-iter",
        type=positive_int,
        default=None,
        help="reference OSQP iteration cap (default: the configuration's, 20000)",
    )
    p.add_argument(
        "--memory-scaling",
        type=positive_int_list,
        default=None,
        help="comma list of sweep sizes (cells), e.g. 10000,100000",
    )
    p.add_argument(
        "--memory-t-end", type=positive_float, default=0.02, help="t_end of those sweeps [s]"
    )
    p.add_argument(
        "--memory-chunk", type=positive_int, default=None, help="chunk size of those sweeps"
    )
    p.add_argument("--memory-timeout", type=positive_float, default=900.0, help="seconds per sweep")
    p.add_argument(
        "--no-cache-times",
        action="store_true",
        help="skip measuring the engine's compile time with an empty and with a "
        "filled persistent compilation cache (two fresh processes, one compile "
        "each; JSON keys compile_first_s, compile_cached_s, "
        "compile_cached_hits, compile_cached_compiles)",
    )
    p.add_argument("--json", action="store_true", help="print a final JSON line with the figures")


def study_controller_config(args: argparse.Namespace, command: str) -> Any:
    """The run's configuration for a benchmark that times the study's controller with the
    solvers side by side (IPOPT and the C closed loop take no rate limit): a rate limit is
    refused in one line (``bench engine`` runs it)."""
    config = load_run_config(args)
    if config.controller.input_rates is not None:
        raise ParameterError(
            f"bench {command} times the study's controller, whose solvers here (CasADi/IPOPT, "
            "the C closed loop) take no rate limit: leave controller.input_rates out, or time "
            "a rate-limited controller with bench engine"
        )
    return config


def pipeline_command(args: argparse.Namespace) -> int:
    """``mjx-balance bench``: batched pipeline vs scalar reference vs the study's toolchain."""
    from ..bench import pipeline  # lazy: JAX and MuJoCo load when the command runs

    config, ref_config = pipeline.benchmark_configs(
        study_controller_config(args, "pipeline"),
        getattr(args, "t_end", None),
        getattr(args, "osqp_max_iter", None),
    )
    sc = config.scenario
    counts = pipeline.scenario_counts(args.scenarios, args.reference, args.ipopt)
    n_mjx, n_ref, n_ipopt = counts
    forces, durations = pipeline.scenario_set(n_mjx, sc.t_end)
    load = os.getloadavg()
    print(
        f"pipeline benchmark: {n_mjx} scenarios of {sc.t_end:g} s (forces 0-150 N, durations "
        f"{durations.min():g}-{durations.max():g} s), convention {config.controller.convention}; "
        f"reference on {n_ref}, CasADi/IPOPT on {n_ipopt}; {args.workers} worker processes; "
        f"{os.cpu_count()} CPUs, load average {load[0]:.2f} at start",
        flush=True,
    )

    def say(text: str) -> None:
        print(text, flush=True)

    # Worker pools first: they are spawned (not forked) anyway, and this keeps JAX idle meanwhile.
    ref, ipopt, ipopt_idx = pipeline.run_pools(
        config, ref_config, forces, durations, counts, args.workers, say
    )
    default, runs, backends = pipeline.run_physics_paths(
        config,
        forces,
        durations,
        physics=args.physics,
        slots=args.slots,
        full_length=args.full_length,
        repeats=args.repeats,
        say=say,
    )
    built, batched = runs.get("continuous batching", runs["--full-length"])
    full = _early_vs_full(runs, batched)
    _print_backends(backends, default)

    cmp = pipeline.compare(counts, batched, ref, ipopt, ipopt_idx)
    rss = dict(
        main=pipeline.peak_rss_mib(resource.RUSAGE_SELF),
        workers=pipeline.peak_rss_mib(resource.RUSAGE_CHILDREN),
    )
    _print_pipeline_table(counts, built, batched, ref, ipopt, cmp, rss, full)
    memory = _memory_scaling(args) if args.memory_scaling else None
    caching = {}
    if not getattr(args, "no_cache_times", False):
        caching = _compile_cache_step(config, args, default)
    if args.json:
        figures = pipeline.pipeline_figures(
            counts=counts,
            t_end=sc.t_end,
            workers=args.workers,
            load_average=load[0],
            built=built,
            batched=batched,
            ref=ref,
            ipopt=ipopt,
            ref_config=ref_config,
            comparison=cmp,
            peak_rss_mib=rss,
            memory_scaling=memory,
            full_length=full,
        )
        figures["physics"] = default
        figures["backends"] = {
            name: {k: v for k, v in b.items() if k != "outcomes"} for name, b in backends.items()
        }
        print(json.dumps({**figures, **caching}))
    return 0


def _early_vs_full(runs: dict, batched) -> dict | None:
    """Continuous batching against ``--full-length``, printed (None: no continuous run)."""
    from ..bench import pipeline  # lazy: JAX and MuJoCo load when the command runs

    full = None
    if "continuous batching" in runs:
        full = pipeline.early_vs_full(batched, runs["--full-length"][1])
        print(
            f"  continuous vs --full-length: {full['speedup']:.2f}x faster; columns that "
            f"must agree exactly and differ: {full['exact_columns_differ'] or 'none'}; "
            f"energies and work within {full['energy_max_rel_diff']:.2g} (relative)",
            flush=True,
        )
    return full


def _compile_cache_step(config: Config, args: argparse.Namespace, physics: str) -> dict:
    """``bench.pipeline.compile_cache_times`` of the default path, printed as it comes."""
    from ..bench import pipeline  # lazy: JAX and MuJoCo load when the command runs

    caching = pipeline.compile_cache_times(
        config, args.slots, not args.full_length, physics=physics
    )
    if "compile_cache_error" in caching:
        print(f"compile, persistent cache: not measured ({caching['compile_cache_error']})")
    else:
        print(
            f"compile in a fresh process: {caching['compile_first_s']:.1f} s with an empty "
            f"persistent cache, {caching['compile_cached_s']:.1f} s from the cache "
            f"({caching['compile_cached_hits']} cache hits, "
            f"{caching['compile_cached_compiles']} XLA compilations)",
            flush=True,
        )
    return caching


def _print_backends(backends: dict, default: str) -> None:
    """The physics paths side by side (same scenarios, same process): rates, ratios, and how
    many outcomes differ from the default path's."""
    if len(backends) < 2:
        return
    base = backends[default]
    print(
        f"  physics paths (default: {default}): "
        + "; ".join(
            f"{name} {b['scen_per_s']:.1f} scen/s ({b['scen_per_s'] / base['scen_per_s']:.2f}x "
            f"{default}, compile {b['compile_s']:.1f} s, "
            f"{int((b['outcomes'] != base['outcomes']).sum())} outcomes differ)"
            for name, b in backends.items()
        ),
        flush=True,
    )


def _print_pipeline_table(counts, built, batched, ref, ipopt, cmp, rss, full=None) -> None:
    """The pipeline benchmark's closing table: rates, ratios, outcomes, memory, targets."""
    from ..bench import pipeline  # lazy: JAX and MuJoCo load when the command runs

    n_mjx, n_ref, n_ipopt = counts
    r_mjx, r_ref, r_ipopt = cmp["mjx"], cmp["reference"], cmp["ipopt"]
    print()
    print(f"{'system':44s} {'scenarios':>9s} {'seconds':>9s} {'scen/s':>9s} {'MJX ratio':>10s}")
    print(
        f"{'batched (default path, this process)':44s} {n_mjx:9d} {batched['seconds']:9.1f} "
        f"{r_mjx:9.2f} {1.0:10.1f}"
    )
    if full:
        print(
            f"{'MJX + ADMM --full-length':44s} {n_mjx:9d} {full['seconds']:9.1f} "
            f"{full['scen_per_s']:9.2f} {r_mjx / full['scen_per_s']:10.1f}"
        )
    if ref:
        print(
            f"{'MuJoCo C + OSQP (reference, processes)':44s} {n_ref:9d} {ref['seconds']:9.1f} "
            f"{r_ref:9.3f} {r_mjx / r_ref:10.1f}"
        )
    if ipopt:
        print(
            f"{'MuJoCo C + CasADi/IPOPT (study, processes)':44s} {n_ipopt:9d} "
            f"{ipopt['seconds']:9.1f} {r_ipopt:9.3f} {r_mjx / r_ipopt:10.1f}"
        )
    print(f"outcomes (MJX, all {n_mjx}): {cmp['mix']}")
    labels = dict(
        mjx_vs_reference="MJX vs reference",
        mjx_vs_ipopt="MJX vs CasADi/IPOPT",
        reference_vs_ipopt="reference vs CasADi/IPOPT",
    )
    for key, (a, n) in cmp["agreement"].items():
        print(f"outcome agreement {labels[key]}: {a}/{n}")
    print(
        f"compile {built['compile_s']:.1f} s, build {built['build_s']:.1f} s; peak RSS "
        f"{rss['main']:.0f} MiB (this process), {rss['workers']:.0f} MiB (largest worker)"
    )
    print(
        f"targets: >= {pipeline.TARGET_SCENARIOS_PER_S} scen/s: {r_mjx:.2f} "
        f"({_met(r_mjx >= pipeline.TARGET_SCENARIOS_PER_S)}); "
        f">= {pipeline.TARGET_VS_REFERENCE}x reference: {r_mjx / r_ref:.1f}x "
        f"({_met(r_mjx / r_ref >= pipeline.TARGET_VS_REFERENCE)}); "
        f">= {pipeline.TARGET_VS_STUDY}x study toolchain: {r_mjx / r_ipopt:.1f}x "
        f"({_met(r_mjx / r_ipopt >= pipeline.TARGET_VS_STUDY)})"
    )


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _memory_scaling(args: argparse.Namespace) -> list[dict]:
    from ..bench import pipeline  # lazy: JAX and MuJoCo load when the command runs

    rows = []
    print(
        f"memory scaling: sweeps with t_end = {args.memory_t_end} s, each in a fresh process",
        flush=True,
    )
    for cells in args.memory_scaling:
        row, error = pipeline.memory_sweep(
            cells, args.memory_t_end, args.memory_chunk, args.memory_timeout
        )
        if row.get("timed_out"):
            print(
                f"  {cells:>9,} cells: not finished within {args.memory_timeout:.0f} s", flush=True
            )
        elif row.get("failed"):
            print(f"  {cells:>9,} cells: failed ({error})", flush=True)
        else:
            print(
                f"  {row['cells']:>9,} cells: peak RSS {row['peak_rss_mib']:7.0f} MiB, "
                f"{row['seconds']:7.1f} s ({row['chunks']} chunks, "
                f"{row['cells'] / row['seconds']:,.0f} cells/s incl. compile)",
                flush=True,
            )
        rows.append(row)
    return rows


def solver_command(args: argparse.Namespace) -> int:
    """``mjx-balance bench solver``: batched ADMM vs OSQP vs CasADi/IPOPT on the same states."""
    from ..bench import solver  # lazy: JAX: imported when this command runs

    config = study_controller_config(args, "solver")
    batches = [int(b) for b in args.batch.split(",") if b.strip()]
    run = solver.measure(
        config,
        batches=batches,
        n_states=args.states,
        dtype=args.dtype,
        say=lambda text: print(text, flush=True),
    )
    figures = run.figures
    _print_solver_table(
        figures["admm"],
        figures["osqp"][-1],
        figures["ipopt_seconds_per_solve"],
        figures["peak_gflops"],
        run.peak_note,
        run.flops,
        run.seconds,
    )
    if args.out:
        write_figures(Path(args.out), figures, "bench_solver.json")
    if args.json:
        print(json.dumps(figures))
    return 0


def _print_solver_table(
    rows: list[dict],
    chosen: dict,
    ipopt_per_solve: float,
    peak: float,
    peak_note: str,
    flops: tuple[int, int],
    total_s: float,
) -> None:
    """The solver benchmark's closing table: solves per second and the ratios between them."""
    it_flops, chk_flops = flops
    ref = next((r for r in rows if r["batch"] == 4096), rows[-1])
    osqp_sps = 1 / chosen["seconds_per_solve"]
    osqp_solved_sps = 1 / chosen["seconds_per_solved"]
    ipopt_sps = 1 / ipopt_per_solve if ipopt_per_solve == ipopt_per_solve else float("nan")
    print()
    print(
        "x OSQP: against OSQP over all states; x OSQPf: against OSQP over its solved states only"
        " (the ADMM figures always include the infeasible states, run to the cap)"
    )
    print(
        f"{'solver':38s} {'solves/s':>12s} {'x OSQP':>8s} {'x OSQPf':>8s} {'x IPOPT':>9s} "
        f"{'GFLOP/s':>8s}"
    )
    for r in rows:
        print(
            f"{'ADMM batch ' + str(r['batch']):38s} {r['solves_per_s']:12.0f} "
            f"{r['solves_per_s'] / osqp_sps:8.1f} {r['solves_per_s'] / osqp_solved_sps:8.1f} "
            f"{r['solves_per_s'] / ipopt_sps:9.0f} {r['gflops']:8.2f}"
        )
    print(
        f"{'OSQP loop eps ' + format(chosen['eps'], 'g') + ', all states':38s} "
        f"{osqp_sps:12.0f} {1.0:8.1f} {osqp_sps / osqp_solved_sps:8.2f} "
        f"{osqp_sps / ipopt_sps:9.1f}"
    )
    print(
        f"{'OSQP loop eps ' + format(chosen['eps'], 'g') + ', solved states':38s} "
        f"{osqp_solved_sps:12.0f} {osqp_solved_sps / osqp_sps:8.1f} {1.0:8.2f} "
        f"{osqp_solved_sps / ipopt_sps:9.1f}"
    )
    print(f"{'CasADi/IPOPT':38s} {ipopt_sps:12.1f}")
    print(
        f"ADMM at batch {ref['batch']}: {ref['solves_per_s'] / osqp_sps:.1f}x OSQP "
        f"({ref['solves_per_s'] / osqp_solved_sps:.1f}x on its solved states; target 25x), "
        f"{ref['solves_per_s'] / ipopt_sps:.0f}x IPOPT (target 1000x); "
        f"{ref['gflops']:.2f} GFLOP/s = {100 * ref['gflops'] / peak:.1f}% of peak "
        f"{peak:.0f} GFLOP/s ({peak_note}); flops per iteration {it_flops}, per check "
        f"{chk_flops}; total run {total_s:.0f} s"
    )


def physics_command(args: argparse.Namespace) -> int:
    """``mjx-balance bench physics``: per scenario-step costs, MJX and MuJoCo C side by side."""
    from ..bench import physics  # lazy: JAX: imported when this command runs

    config = study_controller_config(args, "physics")
    print(
        f"physics paths side by side: {args.slots} slots, {args.seconds:g} s windows "
        f"(about two minutes on 2 cores)"
    )
    figures = physics.measure(config, slots=args.slots, seconds=args.seconds)
    for name, value in figures["us_per_scenario_step"].items():
        print(f"  {name:24s} {value:8.2f} us per scenario-step")
    print(
        f"pipeline / bare mjx.step {figures['pipeline_vs_mjx_step']:.2f}x; closed loop with "
        "the ADMM at its floor / bare mjx.step "
        f"{figures['closed_loop_physics_vs_mjx_step']:.2f}x;"
        f" bare mjx.step / MuJoCo C {figures['mjx_step_vs_c_step']:.2f}x; a C path's bound "
        f"{figures['c_bound_vs_pipeline']:.2f}x the pipeline (worth a second path at "
        f">= {physics.WORTH_IT}x: {'yes' if figures['c_path_worth_it'] else 'no'})"
    )
    if args.json:
        print(json.dumps(figures))
    return 0


def engine_command(args: argparse.Namespace) -> int:
    """``mjx-balance bench engine``: the engine's time per control period, split, per path."""
    from ..bench import engine  # lazy: JAX: imported when this command runs
    from ..runtime import cache  # lazy: as above

    cache.enable()  # as sweep: the engine (and here its stages) from the persistent cache
    config = load_run_config(args)
    if args.t_end:
        config = config.replace(
            scenario={"t_end": args.t_end, "duration": min(config.scenario.duration, args.t_end)}
        )
    load = os.getloadavg()
    print(
        f"engine split: forces {args.forces} N x durations {args.durations} s, "
        f"{config.scenario.t_end:g} s windows, early stop; {os.cpu_count()} CPUs, load "
        f"average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at start",
        flush=True,
    )
    figures = engine.measure(
        config,
        forces=args.forces,
        durations=args.durations,
        paths=args.physics,
        slots=args.slots,
        runs=args.runs,
        repeats=args.repeats,
        sampled=args.sampled,
        admm_tile=args.admm_tile,
        say=lambda text: print(text, flush=True),
    )
    for fig in figures["paths"].values():
        print()
        for line in engine_table(fig):
            print(line)
    end = figures["load_average_end"]
    print(f"\nload average {end[0]:.2f} {end[1]:.2f} {end[2]:.2f} at the end")
    if args.out:
        write_figures(Path(args.out), figures, "bench_engine.json")
    if args.json:
        print(json.dumps(figures))
    return 0


def _agreement(replay: dict, path: str) -> str:
    """The replay's bit-for-bit check, in words."""
    if replay["identical"] is None:
        return " (no whole block replayed: the replay's bits are not checked)"
    what = "blocks' end states" if path == "mjx" else "calls' outputs"
    if replay["identical"]:
        return f"; replay = engine bit for bit ({replay['checked']} {what}): yes"
    return (
        f"; replay = engine bit for bit ({replay['checked']} {what}): NO, "
        f"{replay['differ']} of {replay['values']} values differ, largest relative "
        f"difference {replay['max_rel_diff']:.1e}"
    )


_HOW = {
    "isolated": "isolated",
    "in run": "in run",
    "remainder": "REMAINDER",
    "measured": "measured",
}


def engine_table(fig: dict) -> list[str]:
    """One path's split as table lines: each part, how it was measured, its seconds over the
    run, per control period, per slot and period, and its share of the end-to-end time."""
    from ..bench.pipeline import PATH_NAMES  # lazy: JAX and MuJoCo load with the benchmarks

    name = PATH_NAMES.get(fig["physics"], fig["physics"])
    it = fig["admm_iterations"]
    lines = [
        f"{name}: {fig['scenarios']} scenarios in {fig['seconds']:.2f} s ({fig['scen_per_s']:.1f}"
        f" scen/s; mean of runs {', '.join(f'{s:.2f}' for s in fig['runs'])} s); "
        f"{fig['slots']} slots x {fig['devices']} device(s) = {fig['lanes']} slots, "
        f"{fig['periods']} control periods in {fig['calls']} calls (block {fig['block']}), "
        f"slots busy {100 * fig['occupancy']:.1f} % of slot-periods, {fig['certified']} "
        f"certified; compile {fig['compile_s']:.1f} s",
        f"ADMM iterations per period: {it['per_busy_slot']:.1f} per busy slot, "
        f"{it['per_block']:.1f} per loop and period (its slowest slot; ADMM tile "
        f"{fig.get('admm_tile', fig['slots'])}: {it['block_over_slot']:.2f}x); at the cap of "
        f"{it['cap']}: {100 * it['busy_slots_at_cap']:.1f} % of busy slots' solves, "
        f"{100 * it['blocks_at_cap']:.1f} % of loops' periods",
        f"a compiled call that does nothing: {1e3 * fig['call']['seconds']:.2f} ms "
        f"({fig['call']['arrays_in']} arrays in, {fig['call']['arrays_out']} out); replayed "
        f"{fig['replay']['sampled_periods']} periods stage by stage ({fig['repeats']} calls "
        f"each, median)" + _agreement(fig["replay"], fig["physics"]),
        f"{'part':48s} {'how':>9s} {'s':>8s} {'ms/period':>10s} {'us/slot-period':>14s} "
        f"{'share':>6s}",
    ]

    def row(r: dict, indent: str = "") -> str:
        return (
            f"{indent + r['label']:48.48s} {_HOW.get(r['how'], r['how']):>9s} "
            f"{r['seconds']:8.3f} {r['ms_per_period']:10.3f} "
            f"{r['us_per_slot_period']:14.2f} {100 * r['share']:5.1f}%"
        )

    lines += [row(r) for r in fig["parts"].values()]
    rem = fig["remainder"]
    lines.append(row(rem))
    lines.append(
        f"  (of it: inside the compiled calls {rem['device_s']:.3f} s = the calls' time "
        f"in run minus the isolated parts; on the host {rem['host_s']:.3f} s)"
    )
    lines.append(row(fig["total"]))
    lines.append("not in the sum:")
    lines += [row(r, "  ") for r in fig["info"].values()]
    if fig.get("below_resolution"):
        lines.append(
            f"counted as 0 (below the no-op's correction): {', '.join(fig['below_resolution'])}"
        )
    return lines


def write_figures(out: Path, figures: dict, name: str) -> None:
    """A benchmark's figures as JSON into ``out/name`` (made), written atomically."""
    from ..store.files import write_text  # lazy: pandas loads when a benchmark writes

    out.mkdir(parents=True, exist_ok=True)
    write_text(json.dumps(figures, indent=1), out / name)
    print(f"figures written to {out / name}")
