"""Sharding a batch over several JAX devices (rollout.BatchRunner) changes results only by
rounding.

XLA's host platform can pretend to have several CPU devices
(``XLA_FLAGS=--xla_force_host_platform_device_count=2``), but only when set before JAX starts,
so each case runs in a fresh subprocess: one with two devices (the batch split over them with
shard_map), one with one device. Both run the same four short scenarios (0.15 s, pushes that
recover, tip the foot and drive the ankle input onto its bound) and print every summary column
and the inputs of every control period. The two subprocesses run in parallel (one compile each).

What differs, and why (measured on 2 cores, float32, t_end = 0.15 s):

- The two-device program rounds differently from the one-device one. Per-device batch size and
  shard_map itself are not the cause: on two devices, batches of 8 (4 per device) and 16 (8 per
  device, as the one-device batch) give bit-identical results, and shard_map over a one-device
  mesh reproduces the one-device jit bit for bit. Float columns differ by ~1e-6 to 1e-5
  relative (e.g. peak ankle angle 7.223727e-3 vs 7.223709e-3 rad), the inputs by at most
  1.5e-6 (ankle) and 8.3e-6 (hip) of their range, the ADMM iterations by one or two checks.
- Saturation fractions are a threshold on those inputs and may differ by more than that. At
  150 N for 0.15 s the ankle input rides on its lower bound (-20 N m) in 12 of the 15 periods
  in both runs; the ADMM stops 0 to 5.3e-5 N m inside the bound, while ``outcomes.at_input_bound``
  counts a period within SATURATION_TOL of the range (4e-5 N m) of it. So which periods on the
  bound count is decided by rounding: 12 of 15 on two devices, 10 of 15 on one (0.8 vs 0.667);
  every other column of that scenario agrees as stated above. The fractions are therefore not
  compared with each other; the test checks that each run's fractions are the rule applied to
  its own inputs (in float32, as the kernel applies it) and that the inputs agree.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from margins import within

from mjx_balance.measures import outcomes
from mjx_balance.measures.outcomes import Limits
from mjx_balance.model.params import Config

CONFIG = Config().replace(scenario={"t_end": 0.15})

# Outcomes, step-index times and counts must be identical.
EXACT = ("force", "duration", "outcome", "settle_time", "fall_time", "nonconverged_solves")
# Inputs of every control period, as a fraction of each input's range: two ADMM runs whose
# arithmetic rounds differently agree to 1e-4 of the range (float32 against float64 in
# tests/control/test_admm.py::test_float32_agrees_with_float64); measured here at most 8.3e-6.
INPUT_TOL = 1e-4

SCRIPT = r"""
import json, sys
import jax
import numpy as np
from mjx_balance.model.params import Config
from mjx_balance.rollout import BatchRunner

config = Config().replace(scenario={"t_end": 0.15})
runner = BatchRunner(config, trajectories=True)
forces = np.array([0.0, 60.0, 150.0, -120.0])
durations = np.array([0.0, 0.1, 0.15, 0.05])
summary = runner.run(forces, durations)
out = {k: np.asarray(v, np.float64).tolist() for k, v in summary.items()}
u = runner.last_trajectories["u"][:, ::config.scenario.substeps]  # held from each instant
mesh = runner.mesh
print(json.dumps({"devices": len(jax.devices()),
                  "mesh": 0 if mesh is None else int(mesh.devices.size),
                  "batch": runner.padded_batch(4), "summary": out,
                  "u_dtype": str(u.dtype), "u": np.asarray(u, np.float64).tolist()}))
"""


def _start(devices: int) -> subprocess.Popen:
    env = dict(os.environ)
    env["XLA_FLAGS"] = (
        env.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={devices}"
    ).strip()
    env["JAX_PLATFORMS"] = "cpu"
    env.pop("JAX_ENABLE_X64", None)
    return subprocess.Popen(
        [sys.executable, "-c", SCRIPT],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _result(proc: subprocess.Popen) -> dict:
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr[-2000:]
    return json.loads([line for line in stdout.splitlines() if line.startswith("{")][-1])


@pytest.mark.slow  # tens of seconds on 2 cores: .ci/run runs it after the default suite
def test_two_devices_match_one():
    two, one = _start(2), _start(1)
    two, one = _result(two), _result(one)
    assert two["devices"] == 2 and two["mesh"] == 2
    assert one["devices"] == 1 and one["mesh"] == 0
    assert two["batch"] % 2 == 0
    assert set(two["summary"]) == set(one["summary"])
    for name, values in one["summary"].items():
        a, b = np.array(two["summary"][name]), np.array(values)
        if name.endswith("_saturation_fraction"):  # a threshold: see the module docstring
            continue
        if name == "admm_iterations":  # a convergence test may pass one 10-iteration chunk
            # earlier or later with rounding
            np.testing.assert_allclose(a, b, rtol=0.05, err_msg=name)
        elif name == "max_residual":  # the ADMM's last primal residual: tolerance-level noise
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-4, err_msg=name)
        elif name in EXACT:
            np.testing.assert_array_equal(a, b, err_msg=name)
        else:  # float32 rounding of a differently compiled program, see the module docstring
            scale = np.nanmax(np.abs(b), initial=0.0)
            np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-5 * scale + 1e-9, err_msg=name)

    limits = Limits.from_params(CONFIG.scenario, CONFIG.controller)
    span = np.subtract(limits.input_upper, limits.input_lower)
    u_two, u_one = np.array(two["u"]), np.array(one["u"])
    assert two["u_dtype"] == one["u_dtype"] == "float32"
    assert u_one.shape == (4, CONFIG.scenario.n_control, 2) and np.isfinite(u_one).all()
    du = np.abs(u_two - u_one) / span
    print(f"\nmax |du| of the range: ankle {du[..., 0].max():.1e}, hip {du[..., 1].max():.1e}")
    within(du, 0.0, atol=INPUT_TOL, why="INPUT_TOL: as float32 against float64 (test_admm)")
    flags = {}
    for name, run, u in (("two", two, u_two), ("one", one, u_one)):
        # every period is counted (no scenario falls within 0.15 s)
        flags[name] = outcomes.at_input_bound(np, u.astype(np.float32), limits)
        for i, column in enumerate(("ankle_saturation_fraction", "hip_saturation_fraction")):
            np.testing.assert_allclose(
                run["summary"][column],
                flags[name][..., i].mean(axis=1),
                rtol=1e-12,
                err_msg=f"{name}: {column}",
            )
    print(
        f"periods counted as saturated in one run only: {int((flags['two'] != flags['one']).sum())}"
    )
    # the comparison is not vacuous: the scenarios differ, and some inputs sit on a bound
    assert len(set(one["summary"]["outcome"])) >= 2
    assert flags["one"].any()


PROBE = """
import json, sys
import mjx_balance.cli
cli = sys.modules["mjx_balance.cli.main"]  # (the package's name ``main`` is the function)
assert "jax" not in sys.modules, "importing the command line started JAX"
def probe(args):
    import jax
    print(json.dumps({"devices": jax.device_count()}))
    return 0
cli._run = probe  # everything main does before the command, then report the devices
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.parametrize(
    "argv",
    [
        ["sweep", "--forces", "0,50"],
        ["sweep", "--sweep", "region_dense_paper"],
        ["table", "--sweep", "study_table_paper"],
    ],
)
def test_the_command_line_uses_every_core_whatever_its_arguments(argv, tmp_path):
    """The command line gives XLA one host device per core before JAX starts, also when an
    argument's check imports JAX (a shipped sweep's name is looked up in the runs floor: such
    a sweep once ran on one core of two)."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("XLA_FLAGS", "MJX_BALANCE_HOST_DEVICES", "JAX_ENABLE_X64")
    }
    env["JAX_PLATFORMS"] = "cpu"
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, *argv, "--out", str(tmp_path / "out")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    cores = min(len(os.sched_getaffinity(0)), 8)
    expected = 1 << (cores.bit_length() - 1)  # a power of two, as cli.main.use_host_cores
    got = json.loads(proc.stdout.strip().splitlines()[-1])["devices"]
    assert got == expected, (got, expected, argv)
