"""``mjx-balance simulate``: the scalar reference closed loop for a few pushes."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import pandas as pd

from ..params import ParameterError, save_config
from ..plots import timeseries_figures
from ..reference import simulate_many
from . import load_run_config

# The summary columns printed to the terminal (summary.csv has them all).
PRINTED_COLUMNS = ["force", "duration", "convention", "outcome", "settle_time", "fall_time",
                   "peak_ankle", "peak_hip", "peak_tau_ankle", "peak_tau_hip",
                   "ankle_saturation_fraction", "energy_ankle", "energy_hip", "energy_total",
                   "nonconverged_solves", "max_bound_violation"]


def parse_values(text: str, name: str, *, nonnegative: bool = False) -> list[float]:
    """Comma-separated finite numbers; ParameterError naming ``name`` otherwise."""
    items = [item.strip() for item in str(text).split(",")]
    if not any(items):
        raise ParameterError(f"--{name}: give at least one value")
    values = []
    for item in items:
        try:
            value = float(item)
        except ValueError:
            raise ParameterError(f"--{name}: {item!r} is not a number") from None
        if not math.isfinite(value):
            raise ParameterError(f"--{name}: {item!r} must be a finite number")
        if nonnegative and value < 0:
            raise ParameterError(f"--{name}: {item!r} must be >= 0")
        values.append(value)
    return values


def simulate_command(args: argparse.Namespace) -> int:
    """``mjx-balance simulate``: run the pushes, write tables, configuration and figures."""
    forces = parse_values(args.force, "force")
    durations = parse_values(args.duration, "duration", nonnegative=True)
    config = load_run_config(args)
    for duration in durations:  # fail before creating anything
        config.replace(scenario={"duration": duration})
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary, series = simulate_many(config, forces, durations)
    summary.to_csv(out / "summary.csv", index=False)
    series.to_parquet(out / "timeseries.parquet", index=False)
    save_config(config, out / "config.toml")
    figures = timeseries_figures(series, out)
    with pd.option_context("display.width", 200, "display.max_columns", None,
                           "display.float_format", lambda v: f"{v:.4g}"):
        print(summary[PRINTED_COLUMNS].to_string(index=False))
    print(f"wrote {out / 'summary.csv'}, {out / 'timeseries.parquet'}, {out / 'config.toml'} "
          f"and {len(figures)} figures in {out}")
    return 0
