"""The pipeline benchmark's pieces that need no compile: the scenario set, the toolchain
subset, and the command line (``bench`` alone is the pipeline benchmark, ``bench solver`` stays)."""

from __future__ import annotations

import numpy as np

from mjx_balance.bench.pipeline import scenario_set, stratified_subset
from mjx_balance.cli.main import build_parser


def test_scenario_set_covers_the_ranges():
    forces, durations = scenario_set(64, 12.0)
    assert forces.shape == durations.shape == (64,)
    assert forces.min() >= 0 and forces.max() <= 150 and np.ptp(forces) > 140
    assert durations.min() >= 0.05 and durations.max() <= 10 and durations.max() > 5
    # a prefix is spread too (the reference runs one)
    f16, d16 = scenario_set(16, 12.0)
    np.testing.assert_array_equal(f16, forces[:16])
    assert np.ptp(f16) > 100 and d16.max() / d16.min() > 20
    assert scenario_set(8, 0.5)[1].max() <= 0.5


def test_stratified_subset_follows_the_mix():
    outcomes = np.array([2, 2, 2, 0, 2, 0, 2, 2, 2, 2, 0, 2, 2, 2, 0, 2])
    idx = stratified_subset(outcomes, 8)
    assert len(idx) == 8 and len(set(idx)) == 8
    assert (outcomes[idx] == 0).sum() == 2 and (outcomes[idx] == 2).sum() == 6
    assert list(stratified_subset(np.array([2, 2]), 4)) == [0, 1]
    assert (outcomes[stratified_subset(outcomes, 2)] == 0).sum() == 1


def test_cli_bench_dispatch():
    parser = build_parser()
    args = parser.parse_args(["bench", "--scenarios", "8", "--json"])
    assert args.target == "mjx_balance.cli.bench:pipeline_command"
    assert args.scenarios == 8 and args.json
    args = parser.parse_args(["bench", "solver", "--batch", "1"])
    assert args.target == "mjx_balance.cli.bench:solver_command" and args.batch == "1"
