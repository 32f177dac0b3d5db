"""Extreme but finite values of every number a configuration holds: which are refused before a
sweep makes its folder, and what a push does under those that are not.

    python docs/scripts/extreme_values.py [--values 1e300,-1e300,1e-300]

For each numeric field of the body, the controller and the scenario (a pair or a list: every
element), and each value: "config" when the configuration itself refuses it
(``Config.replace``: a field's own bounds), "pre-folder" when the batched path's checks refuse
it (``runs.folders.check_batched``, what ``sweep`` runs before it makes the folder), otherwise
the scalar reference's outcome of one push (50 N for 0.1 s, t_end 1 s) under it, or the
exception it raised. A value accepted and then diverging is one the checks could still catch.
docs/reliability.md records the table.
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

from mjx_balance.model.params import Config, ParameterError
from mjx_balance.reference.loop import simulate_scenario
from mjx_balance.runs.folders import check_batched

SKIP = {("scenario", "force"), ("scenario", "duration")}  # the grid's, not the configuration's


def fields(config: Config):
    """(section, name, current value) of every numeric field."""
    for section in ("body", "controller", "scenario"):
        for f in dataclasses.fields(getattr(config, section)):
            value = getattr(getattr(config, section), f.name)
            numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
            numeric = numeric or (
                isinstance(value, tuple) and all(isinstance(v, (int, float)) for v in value)
            )
            if numeric and (section, f.name) not in SKIP:
                yield section, f.name, value


def verdict(base: Config, section: str, name: str, current, value: float) -> str:
    new = tuple(value for _ in current) if isinstance(current, tuple) else value
    if isinstance(current, int) and not isinstance(current, bool):
        if abs(value) > 1e9 or value != int(value):
            return "not an integer value (skipped)"
        new = int(value)
    try:
        config = base.replace(**{section: {name: new}})
    except (ParameterError, ValueError, TypeError) as exc:
        return "config: " + str(exc).splitlines()[0][:70]
    try:
        check_batched(config)
    except ParameterError as exc:
        return "pre-folder: " + str(exc).splitlines()[0][:70]
    except Exception as exc:  # a check that fails otherwise is itself a finding
        return f"pre-folder CRASH {type(exc).__name__}: {str(exc)[:60]}"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            summary, _ = simulate_scenario(config, 50.0, 0.1, record=False)
        return "runs: " + str(summary["outcome"])
    except Exception as exc:
        return f"runs: {type(exc).__name__}: {str(exc)[:60]}"


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--values", default="1e300,-1e300,1e-300")
    args = parser.parse_args()
    values = [float(v) for v in args.values.split(",")]
    base = Config().replace(scenario={"t_end": 1.0})
    print("| field | " + " | ".join(f"{v:g}" for v in values) + " |")
    print("|---|" + "---|" * len(values))
    for section, name, current in fields(base):
        cells = [verdict(base, section, name, current, v) for v in values]
        print(f"| {section}.{name} | " + " | ".join(c.replace("|", "/") for c in cells) + " |",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
