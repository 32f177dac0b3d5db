"""Configurations that would give results that are not results are refused before any work and
before any file is written (issue 26, items 3, 5 and 6): ``mjx-balance sweep``/``table`` and
the API answer with exit 2 / a ParameterError (a ValueError) that names the value and the bound,
and the output folder is not created.

The derived rules (runs/folders.py): the dense QP must fit memory (sizes in Python integers,
so a horizon of 2**70 is answered at once); the ADMM's settings must be float32 numbers with
float32 reciprocals; the QP must build; float32 must resolve it, cond(H) x eps_float32 < 1
(measured: the batched ADMM's first input against OSQP, docs/reliability.md); the rest of the
batched closed loop must build.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.measures.outcomes import NotAResult
from mjx_balance.control.qp import FLOAT32_EPS, build_qp, float32_conditioning, qp_bytes
from mjx_balance.model.params import Config, ParameterError

BAD = [  # --set value, what the message names
    ("controller.horizon=200", "too ill-conditioned for the batched float32 ADMM"),
    ("scenario.control_dt=2", "too ill-conditioned"),
    ("controller.admm_rho=1e-300", "controller.admm_rho = 1e-300"),
    ("controller.admm_eps_abs=1e-300", "controller.admm_eps_abs"),
    (f"controller.horizon={2 ** 70}", "more than the memory budget"),
    ("controller.q_diag=[1e300,1e300,1e300,1e300]", "QP cannot be built"),
    ("body.hip_servo_stiffness=1e300", "cannot be built"),
    ("body.gravity=1e-300", "body.gravity = 1e-300: must lie in"),
]


@pytest.mark.parametrize("setting, message", BAD)
@pytest.mark.parametrize("command", ["sweep", "table"])
def test_the_command_refuses_before_writing(tmp_path, capsys, setting, message, command):
    out = tmp_path / "out"
    grid = ["--forces", "0,60"] + (["--durations", "0.1"] if command == "sweep" else [])
    assert main(["-q", command, *grid, "--set", setting, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()  # nothing written: the corrected configuration may use the folder


@pytest.mark.parametrize("setting, message", [BAD[4], BAD[6], BAD[7]])
def test_simulate_refuses_before_writing(tmp_path, capsys, setting, message):
    out = tmp_path / "out"
    assert main(["-q", "simulate", "--forces", "20", "--durations", "0.1", "--set", setting,
                 "--out", str(out)]) == 2
    assert message.split(":")[0] in capsys.readouterr().err
    assert not out.exists()


def test_the_api_refuses_with_a_value_error(tmp_path):
    config = Config().replace(controller={"horizon": 200})
    with pytest.raises(ValueError, match="ill-conditioned"):
        mb.sweep([10.0], [0.1], config, out=tmp_path / "out")
    with pytest.raises(ParameterError, match="memory budget"):
        mb.table([10.0], Config().replace(controller={"horizon": 2 ** 70}))
    assert not (tmp_path / "out").exists()


def test_the_conditioning_rule_on_known_horizons():
    # cond(H) grows with the prediction of an unstable body: the study's 20 x 0.01 s is far
    # inside, 80 x 0.01 s beyond (measured: its first input 26 % of its range off OSQP's)
    ratios = {}
    for horizon in (20, 60, 80):
        controller = Config().controller.__class__(horizon=horizon)
        qp = build_qp(controller, Config().body, 0.01)
        ratios[horizon] = float32_conditioning(qp)
    assert ratios[20] < 1e-3 < ratios[60] < 1.0 <= ratios[80]
    assert FLOAT32_EPS == 2.0 ** -23
    assert qp_bytes(20) == 2 * 16 * 40 * 40 * 8 and qp_bytes(2 ** 70) > 2 ** 140


# -- a run that is not a result (issue 26.3): half or more of its scenarios diverged ---------

class DivergingBatch:
    """A stand-in rollout whose scenarios diverge where F > ``above`` (else recover), as a
    controller whose numbers leave the finite range would."""

    def __init__(self, above: float):
        self.above = above

    def __call__(self, forces, durations):
        from mjx_balance.measures.outcomes import DIVERGED, SUMMARY_COLUMNS

        forces = np.asarray(forces, np.float32)
        out = {c: np.zeros(forces.size) for c in SUMMARY_COLUMNS if c != "convention"}
        out["force"], out["duration"] = forces, np.asarray(durations, np.float32)
        out["outcome"] = np.where(forces > self.above, DIVERGED, 0).astype(np.int32)
        out["settle_time"] = np.where(forces > self.above, np.nan, 1.0)
        out["fall_time"] = np.full(forces.size, np.nan)
        return out


@pytest.fixture
def diverging(monkeypatch):
    def use(above):
        monkeypatch.setattr("mjx_balance.runs.batch.default_batch",
                            lambda config, **_engine: DivergingBatch(above))
    return use


@pytest.mark.parametrize("command", ["sweep", "table"])
def test_a_mostly_diverged_run_fails_with_one_line(tmp_path, capsys, diverging, command):
    diverging(above=15.0)  # forces 20, 40, 60 of 10..60 diverge: 75 % of the cells
    out = tmp_path / "out"
    grid = ["--forces", "10,20,40,60"] + (["--durations", "0.1,0.2"] if command == "sweep"
                                          else [])
    assert main(["-q", command, *grid, "--set", "scenario.t_end=2", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "diverged" in err[0] and "not results" in err[0], err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["runs"][-1]["status"] == "failed"
    assert not (out / "region.png").exists() and not (out / "table.png").exists()
    # the same folder again: the finished numbers are still not results
    assert main(["-q", command, *grid, "--set", "scenario.t_end=2", "--out", str(out)]) == 1


def test_a_few_diverged_cells_are_results(tmp_path, diverging):
    diverging(above=50.0)  # one force of four: 25 % diverged
    out = tmp_path / "out"
    assert main(["-q", "sweep", "--forces", "10,20,40,60", "--durations", "0.1,0.2", "--set",
                 "scenario.t_end=2", "--out", str(out)]) == 0
    assert (out / "region.png").exists()
    with pytest.raises(NotAResult):  # the API raises it
        diverging(above=0.0)
        mb.sweep([10.0, 20.0], [0.1], Config().replace(scenario={"t_end": 2.0}))


def test_an_absurd_push_gives_its_outcome_row_and_figures(tmp_path, capsys):
    """Issue 26.7: 1e12 N diverges at the first step; the run still writes its summary row and
    figures that say there is nothing to draw, instead of a traceback."""
    out = tmp_path / "out"
    assert main(["-q", "simulate", "--forces", "1e12", "--durations", "0.1", "--set",
                 "scenario.t_end=0.2", "--out", str(out)]) == 0
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["outcome"]) == ["diverged"]
    assert (out / "ankle_angle.png").exists() and (out / "energy.png").exists()
    assert "Traceback" not in capsys.readouterr().err


# -- numerics on resume (issue 26.4) -------------------------------------------------------------

def test_the_numerics_fingerprint_is_recorded_and_a_mismatch_refused(tmp_path, caplog):
    from test_sweep import FakeThresholdBatch, sweep_fake

    from mjx_balance.runtime import fingerprint
    from mjx_balance.store.folder import chunk_numerics

    sweep_fake(tmp_path, FakeThresholdBatch())
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert set(manifest["numerics"]) == {*fingerprint.RESULT_KEYS, *fingerprint.INFO_KEYS}
    assert manifest["numerics"] == fingerprint.numerics()
    chunk = sorted((tmp_path / "chunks").glob("chunk-*.parquet"))[0]
    assert chunk_numerics(chunk) == fingerprint.numerics()  # each chunk keeps its own
    assert pd.read_parquet(tmp_path / "region.parquet").attrs == {}  # the merge carries none

    # a folder computed under x64 (as if by JAX_ENABLE_X64=1): resuming it is refused, naming
    # what differs and how to start afresh
    manifest["numerics"]["x64"] = not manifest["numerics"]["x64"]
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    (tmp_path / "region.parquet").unlink()  # unfinished: there are rows to compute again
    sorted((tmp_path / "chunks").glob("chunk-*.parquet"))[-1].unlink()
    with pytest.raises(ParameterError, match=r"other numerics \(x64: .*start a fresh folder"):
        sweep_fake(tmp_path, FakeThresholdBatch())

    # another CPU ISA only warns, and the run goes on
    manifest["numerics"]["x64"] = not manifest["numerics"]["x64"]
    manifest["numerics"]["cpu_isa"] = "SSE4_2-elsewhere"
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    with caplog.at_level("WARNING"):
        sweep_fake(tmp_path, FakeThresholdBatch())
    assert "cpu_isa: 'SSE4_2-elsewhere'" in caplog.text
    assert (tmp_path / "region.parquet").exists()


def test_the_fingerprint_reads_the_environment_without_jax():
    from mjx_balance.runtime import fingerprint

    assert fingerprint.result_flags("--xla_force_host_platform_device_count=2 --b=1 --a=2") == [
        "--a=2", "--b=1"]
    assert fingerprint.cpu_isa("--xla_cpu_max_isa=avx") == "AVX"
    assert fingerprint.differences({"x64": False, "cpu_isa": "AVX2"},
                                   {"x64": True, "cpu_isa": "AVX"}) == (
        ["x64: False -> True"], ["cpu_isa: 'AVX2' -> 'AVX'"])
