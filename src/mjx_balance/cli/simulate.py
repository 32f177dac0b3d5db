"""``mjx-balance simulate``: the scalar reference closed loop for a few pushes
(``mjx_balance.api.simulate``), written to a folder with figures."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from ..model.params import ParameterError, finite_number
from ..model.config_files import dumps_config
from .common import guard_work, in_folder, load_run_config, progress_enabled
from .options import common_options, figure_options, format_option, write_exports, yes_option

DEFAULT_FORCES, DEFAULT_DURATIONS = "0,20,50,80,100,120", "0.1"

log = logging.getLogger("mjx_balance")


# The summary columns printed to the terminal (summary.csv has them all).
PRINTED_COLUMNS = [
    "force",
    "duration",
    "convention",
    "outcome",
    "settle_time",
    "fall_time",
    "peak_ankle",
    "peak_hip",
    "peak_tau_ankle",
    "peak_tau_hip",
    "ankle_saturation_fraction",
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "nonconverged_solves",
    "max_bound_violation",
]


def add_parser(sub) -> None:
    """The ``simulate`` sub-command (``sub.add_parser`` of ``main.build_parser``)."""
    p = sub.add_parser(
        "simulate", help="scalar reference closed loop (MuJoCo C + OSQP) for a few pushes"
    )
    p.add_argument(
        "--forces",
        default=None,
        help=f"forces [N], a comma list or start:stop:step (default: {DEFAULT_FORCES})",
    )
    p.add_argument(
        "--durations",
        default=None,
        help=f"push durations [s], a comma list or start:stop:step (default: "
        f"{DEFAULT_DURATIONS}); every force with every duration",
    )
    p.add_argument(
        "--pairs",
        default=None,
        metavar="F:T,... | FILE.csv",
        help="given (force, duration) pairs instead of the cross product, e.g. "
        "20:0.7,30:0.45, or a CSV with columns force, duration",
    )
    p.add_argument(
        "--full-window",
        action="store_true",
        help="time axes of the figures up to t_end (default: trimmed to the action, "
        "the last settle or fall plus a margin)",
    )
    format_option(p)
    yes_option(p)
    figure_options(p)
    common_options(p)
    p.set_defaults(target="mjx_balance.cli.simulate:simulate_command")


def parse_values(text: str, name: str, *, nonnegative: bool = False) -> list[float]:
    """Comma-separated finite numbers; ParameterError naming ``name`` otherwise."""
    items = [item.strip() for item in str(text).split(",")]
    if not any(items):
        raise ParameterError(f"--{name}: give at least one value")
    values = []
    for item in items:
        value = finite_number(item, f"--{name}")
        if nonnegative and value < 0:
            raise ParameterError(f"--{name}: {item!r} must be >= 0")
        values.append(value)
    return values


def sweep_folder(out: Path) -> bool:
    """Whether ``out`` holds a sweep, a table or a report (its config.toml must not be
    overwritten): a manifest other than simulate's own, or a config.toml beside chunks, a
    region, the table's kept scenarios or a report's record."""
    from ..store.files import CONFIG, MANIFEST, REGION, TABLE_CELLS  # lazy: loads pandas

    return ((out / MANIFEST).exists() and not _simulate_manifest(out / MANIFEST)) or (
        (out / CONFIG).exists()
        and any((out / name).exists() for name in ("chunks", REGION, TABLE_CELLS, "report.json"))
    )


def _simulate_manifest(path: Path) -> bool:
    """Whether the manifest at ``path`` is the one ``simulate`` writes."""
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return False
    return isinstance(manifest, dict) and manifest.get("kind") == "simulate"


def simulate_command(args: argparse.Namespace) -> int:
    """``mjx-balance simulate``: run the pushes, write tables, configuration and figures
    (each file atomically: whole or absent)."""
    # lazy: the library (JAX, MuJoCo, pandas) loads when the command runs, not for --help
    from ..figures.timeseries import timeseries_figures  # lazy: matplotlib
    from ..measures.strategy import with_strategy  # lazy: pandas
    from ..reference.loop import each_pair  # lazy: MuJoCo, OSQP
    from ..runs.folders import check_pushes  # lazy: the runs floor loads JAX
    from ..store.files import (
        CONFIG,
        MANIFEST,
        write_csv,  # lazy: the store floor: pandas
        write_parquet,
        write_text,
    )
    from ..store.folder import (
        finish_simulation,
        read_pushes,  # lazy: pandas
        record_simulation,
        write_push,
    )
    from ..store.provenance import run_context  # lazy: as above

    config = load_run_config(args)
    # every push, its configuration and the reference's build, before creating anything
    grid = args.pairs is None  # the cross product: the defaults for what is not given
    forces, durations, pairs, todo = check_pushes(
        config,
        DEFAULT_FORCES if grid and args.forces is None else args.forces,
        DEFAULT_DURATIONS if grid and args.durations is None else args.durations,
        args.pairs,
        flag="--",
    )
    guard_work(args, config, len(todo), "pushes", reference=True)
    out = Path(args.out)
    if sweep_folder(out):
        raise ParameterError(
            f"{out} holds a sweep or a report (its {CONFIG} would be "
            "overwritten); use another --out folder"
        )
    result = {}

    def work() -> None:
        # Each push is kept in DIR/pushes/ as it ends, so that an interrupted run resumes
        # where it stopped; the tables are read back from there, resumed or not.
        done = record_simulation(out, config, forces, durations, pairs=pairs)
        for index, row, frame in each_pair(
            config, todo, skip=done, progress=progress_enabled(args)
        ):
            write_push(out, index, row, frame)
        summary, series = read_pushes(out, len(todo))
        summary = result["summary"] = with_strategy(summary)
        write_csv(summary, out / "summary.csv")
        write_parquet(series, out / "timeseries.parquet")
        write_text(dumps_config(config), out / CONFIG)
        # written atomically (figures.timeseries._save)
        result["figures"] = timeseries_figures(
            series, out, config=config, summary=summary, full_window=args.full_window
        )
        write_exports(out, args)
        finish_simulation(out, config, forces, durations, pairs=pairs)

    with run_context(physics="mujoco"):  # the scalar reference: MuJoCo C physics
        code = in_folder(out, work)
    if code:
        return code
    _print_summary(result["summary"])
    log.info(
        f"wrote {out / 'summary.csv'}, {out / 'timeseries.parquet'}, {out / 'config.toml'}, "
        f"{out / MANIFEST} and {len(result['figures'])} figures in {out}"
    )
    return 0


def _print_summary(summary) -> None:
    """Print the summary's printed columns as a table on stdout."""
    import pandas as pd

    with pd.option_context(
        "display.width",
        200,
        "display.max_columns",
        None,
        "display.float_format",
        lambda v: f"{v:.4g}",
    ):
        print(summary[PRINTED_COLUMNS].to_string(index=False))
