"""Every refusal of the command line and the Python API: bad input is answered before any work
in one line (exit 2, or 1 for a failure during the work; a ValueError naming the argument in
Python), with no traceback and nothing written or lost. Other floors' rules have their own
homes: a configuration's values (tests/model/test_params_validation.py), work too large to do
(tests/runs/test_work_guard.py), a disk or lock that fails during the work
(tests/store/test_store_faults.py).

- Bad arguments and places: every command refuses a bad configuration, an unusable --out, an
  unwritable place and bad values, in this process (``cli.main``) and, for the exit code and
  stderr, in a few subprocesses.
- Configurations whose results would not be results (runs/folders.py's derived rules: the
  dense QP must fit memory, the ADMM's settings must be float32 numbers with float32
  reciprocals, float32 must resolve the QP, cond(H) x eps_float32 < 1; the batched closed loop
  must build) and runs whose cells mostly diverged.
- Damaged report records and sweep definitions.
- Push durations that are not whole physics steps (``simulate``, ``animate``); ``simulate``
  reads grids as ``sweep`` does and does not write into a sweep folder.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from support import assert_refused, run_cli

import mjx_balance as mb
from mjx_balance import cli
from mjx_balance.cli import main
from mjx_balance.control.qp import FLOAT32_EPS, build_qp, float32_conditioning, qp_bytes
from mjx_balance.measures.outcomes import NotAResult
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.report import PLANS
from mjx_balance.runs import load_sweep
from mjx_balance.runs.grid import check_whole_steps
from mjx_balance.studies.experiments import open_record, read_record

# -- bad arguments and places ---------------------------------------------------------------------


# Each command with the least it needs; OUT is replaced by the --out path of the test.
COMMANDS = {
    "simulate": ["simulate", "--forces", "10", "--out", "OUT"],
    "sweep": ["sweep", "--forces", "0", "--durations", "0.1", "--out", "OUT"],
    "table": ["table", "--forces", "10", "--out", "OUT"],
    "animate": ["animate", "--force", "10", "--out", "OUT.gif"],
    "bench": ["bench", "--out", "OUT"],
    "bench solver": ["bench", "solver", "--out", "OUT"],
    "report": ["report", "--scale", "tiny", "--out", "OUT"],
}


def command(name: str, out, *extra: str) -> list[str]:
    """The command's arguments with --out replaced by ``out`` (``out``.gif for animate)."""
    args = [a.replace("OUT", str(out)) for a in COMMANDS[name]]
    return args + list(extra)


@pytest.fixture
def files(tmp_path):
    """Bad inputs: a folder, a non-UTF-8 file, configurations that break a rule, a plain file."""
    made = {
        "folder": tmp_path / "a_folder",
        "binary": tmp_path / "binary.toml",
        "file": tmp_path / "a_file",
    }
    made["folder"].mkdir()
    made["binary"].write_bytes(b"\xff\xfe[body]\nfoot_mass = 1.0\n")
    made["file"].write_text("not a folder\n")
    for name, text in {
        "nested": "[controller]\ninput1_bounds = [[1, 2], 3]\n",
        "q_text": '[controller]\nq_diag = ["a", 1, 1, 1]\n',
        "q_bool": "[controller]\nq_diag = [true, 1, 1, 1]\n",
        "physics_dt": "[scenario]\nphysics_dt = 1.0\ncontrol_dt = 1.0\n",
        "mass": "[body]\nupper_mass = 1e308\n",
    }.items():
        made[name] = tmp_path / f"{name}.toml"
        made[name].write_text(text)
    return made


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize(
    "config,words",
    [
        ("folder", ["--config", "is not a file"]),
        ("binary", ["--config", "not UTF-8"]),
        ("nested", ["controller.input1_bounds", "list of numbers"]),
        ("q_text", ["controller.q_diag", "list of numbers"]),
        ("q_bool", ["controller.q_diag", "list of numbers"]),
        ("physics_dt", ["scenario.physics_dt", "<= 0.01"]),
        ("mass", ["body.upper_mass", "[0.001, 10000] kg"]),
    ],
)
def test_every_command_refuses_a_bad_config(tmp_path, files, capsys, name, config, words):
    out = tmp_path / "out"
    code, err = run_cli(command(name, out, "--config", str(files[config])), capsys)
    assert_refused(code, err, *words)
    assert not out.exists() and not out.with_suffix(".gif").exists()


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize(
    "where,words",
    [
        ("", ["--out", "give a"]),
        ("file", ["--out", "a_file' exists and is not a folder"]),  # animate: see below
        ("file/sub", ["--out", "a_file' is not a folder"]),  # its parent is a file: cannot be made
    ],
)
def test_every_command_refuses_an_unusable_out(tmp_path, files, capsys, name, where, words):
    out = "" if not where else str(tmp_path / where.replace("file", "a_file"))
    if name == "animate" and where == "file":  # a GIF may be overwritten, a name must be .gif
        words = ["--out", "a_file': the file name must end in .gif"]
    if name == "animate" and where == "file/sub":
        out += ".gif"
    argv = command(name, "OUT")
    argv[argv.index("--out") + 1] = out
    code, err = run_cli(argv, capsys)
    assert_refused(code, err, *words)
    assert files["file"].read_text() == "not a folder\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in files.values())


@pytest.mark.parametrize("name", ["simulate", "sweep", "animate", "report"])
def test_an_unwritable_place_is_refused(tmp_path, capsys, monkeypatch, name):
    """A read-only parent, as os.access reports it (tests may run as root, who may write
    anywhere: the permission check is what is tested)."""
    parent = tmp_path / "read_only"
    parent.mkdir()
    real_access = os.access
    monkeypatch.setattr(
        os,
        "access",
        lambda path, mode: False if str(path) == str(parent) else real_access(path, mode),
    )
    out = parent / "new" / "deeper"
    code, err = run_cli(command(name, out), capsys)
    assert_refused(code, err, "--out", "read_only' is not writable")
    assert list(parent.iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_a_read_only_folder_is_refused(tmp_path, capsys):
    parent = tmp_path / "read_only"
    parent.mkdir(mode=0o555)
    code, err = run_cli(command("sweep", parent / "new"), capsys)
    assert_refused(code, err, "--out", "is not writable")
    assert list(parent.iterdir()) == []


def test_a_write_that_fails_is_one_line(tmp_path, capsys, monkeypatch):
    """A place that passes the checks but refuses the write (root on /proc, a full disk): main
    reports the OSError in one line, as a failure (exit 1)."""
    from mjx_balance.cli import simulate

    def refuse(args):
        raise PermissionError(13, "Permission denied", str(tmp_path / "out" / "summary.csv"))

    monkeypatch.setattr(simulate, "simulate_command", refuse)
    code, err = run_cli(command("simulate", tmp_path / "out"), capsys)
    assert_refused(code, err, "summary.csv", "Permission denied", exit_code=1)


BAD_VALUES = [
    ("animate", ["--fps", "0"], ["--fps", "must be > 0"]),
    ("animate", ["--fps", "nan"], ["--fps", "finite"]),
    ("animate", ["--fps", "-5"], ["--fps", "must be > 0"]),
    ("animate", ["--force", "inf"], ["--force", "finite"]),
    ("animate", ["--duration", "-0.1"], ["--duration", ">= 0"]),
    ("animate", ["--t-end", "0"], ["--t-end", "> 0"]),
    ("bench solver", ["--batch", "abc"], ["--batch", "not an integer"]),
    ("bench solver", ["--batch", "0"], ["--batch", "integer >= 1"]),
    ("bench solver", ["--batch", "16,2.5"], ["--batch", "integer >= 1"]),
    ("bench solver", ["--batch", ","], ["--batch", "at least one"]),
    ("bench solver", ["--states", "0"], ["--states", "integer >= 1"]),
    ("bench", ["--scenarios", "0"], ["--scenarios", "integer >= 1"]),
    ("bench", ["--reference-runs", "-1"], ["--reference-runs", "integer >= 0"]),
    ("bench", ["--workers", "0"], ["--workers", "integer >= 1"]),
    ("bench", ["--slots", "0"], ["--slots", "integer >= 1"]),
    ("sweep", ["--slots", "0"], ["--slots", "integer >= 1"]),
    ("bench", ["--repeats", "0"], ["--repeats", "integer >= 1"]),
    ("bench", ["--t-end", "-1"], ["--t-end", "> 0"]),
    ("bench", ["--memory-scaling", "10,abc"], ["--memory-scaling", "not an integer"]),
    ("sweep", ["--chunk", "-3"], ["--chunk", "integer >= 1"]),
    ("sweep", ["--chunk", "0"], ["--chunk", "integer >= 1"]),
    ("sweep", ["--sweep", "no_such.toml"], ["--sweep", "not found"]),
    ("sweep", ["--reference", "no_such.csv"], ["--reference", "not found"]),
    ("table", ["--sweep", "no_such.toml"], ["--sweep", "not found"]),
    ("report", ["--sweeps", "no_such_folder"], ["--sweeps", "not a folder"]),
    ("simulate", ["--forces", "abc"], ["--forces", "not a number"]),
    ("simulate", ["--pairs", "20"], ["--pairs", "FORCE:DURATION"]),
    ("simulate", ["--pairs", "20:abc"], ["--pairs", "not a number"]),
    ("simulate", ["--pairs", "20:0.1", "--forces", "20"], ["--pairs", "leave out --forces"]),
    ("simulate", ["--pairs", "20:0.1005"], ["--pairs", "not a whole number of physics steps"]),
    ("table", ["--reference", "no_such.csv"], ["--reference", "not found"]),
    ("report", ["--reference", "no_such.csv"], ["--reference", "not found"]),
    ("simulate", ["--durations", "0.1005"], ["--durations", "not a whole number of physics steps"]),
    ("simulate", ["--forces", "0:10:0"], ["--forces", "step must be > 0"]),
    ("animate", ["--duration", "0.1005"], ["--duration", "not a whole number of physics steps"]),
]


@pytest.mark.parametrize(
    "name,extra,words",
    BAD_VALUES,
    ids=[f"{name} {' '.join(extra)}" for name, extra, _ in BAD_VALUES],
)
def test_bad_values_are_refused(tmp_path, capsys, name, extra, words):
    out = tmp_path / "out"
    code, err = run_cli(command(name, out, *extra), capsys)
    assert_refused(code, err, *words)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "where,words",
    [
        ("movie", ["--out", "must end in .gif"]),  # no extension
        ("movie.mp4", ["--out", "must end in .gif"]),
        ("a_folder", ["--out", "is a folder"]),
        ("a_folder.gif", ["--out", "is a folder"]),
    ],
)
def test_animate_out_must_be_a_gif_file(tmp_path, capsys, where, words):
    (tmp_path / "a_folder").mkdir()
    (tmp_path / "a_folder.gif").mkdir()
    code, err = run_cli(["animate", "--force", "10", "--out", str(tmp_path / where)], capsys)
    assert_refused(code, err, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_folder", "a_folder.gif"]
    assert not any((tmp_path / "a_folder").iterdir())


@pytest.mark.parametrize(
    "argv,words",
    [
        (["sweep", "--forces", "0", "--durations", "0.1", "--chunk", "-3"], ["--chunk"]),
        (["animate", "--force", "10", "--fps", "nan"], ["--fps", "finite"]),
        (["simulate", "--forces", "10", "--config", "CONFIG"], ["controller.input1_bounds"]),
    ],
)
def test_the_process_exits_2_without_a_traceback(tmp_path, argv, words):
    """The installed entry point, in its own process: exit status 2, one error line."""
    config = tmp_path / "nested.toml"
    config.write_text("[controller]\ninput1_bounds = [[1, 2], 3]\n")
    out = tmp_path / ("out.gif" if argv[0] == "animate" else "out")
    argv = [a.replace("CONFIG", str(config)) for a in argv] + ["--out", str(out)]
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from mjx_balance.cli import main; sys.exit(main())",
            *argv,
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.stdout == ""
    assert_refused(done.returncode, done.stderr, *words)
    assert not out.exists()


# -- configurations whose results would not be results --------------------------------------------


BAD = [  # --set value, what the message names
    ("controller.horizon=200", "too ill-conditioned for the batched float32 ADMM"),
    ("scenario.control_dt=2", "too ill-conditioned"),
    ("controller.admm_rho=1e-300", "controller.admm_rho = 1e-300"),
    ("controller.admm_eps_abs=1e-300", "controller.admm_eps_abs"),
    (f"controller.horizon={2**70}", "more than the memory budget"),
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
    assert (
        main(
            [
                "-q",
                "simulate",
                "--forces",
                "20",
                "--durations",
                "0.1",
                "--set",
                setting,
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert message.split(":")[0] in capsys.readouterr().err
    assert not out.exists()


def test_the_api_refuses_with_a_value_error(tmp_path):
    config = Config().replace(controller={"horizon": 200})
    with pytest.raises(ValueError, match="ill-conditioned"):
        mb.sweep([10.0], [0.1], config, out=tmp_path / "out")
    with pytest.raises(ParameterError, match="memory budget"):
        mb.table([10.0], Config().replace(controller={"horizon": 2**70}))
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
    assert FLOAT32_EPS == 2.0**-23
    assert qp_bytes(20) == 2 * 16 * 40 * 40 * 8 and qp_bytes(2**70) > 2**140


# -- a run that is not a result: half or more of its scenarios diverged ---------


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
        monkeypatch.setattr(
            "mjx_balance.runs.batch.default_batch", lambda config, **_engine: DivergingBatch(above)
        )

    return use


@pytest.mark.parametrize("command", ["sweep", "table"])
def test_a_mostly_diverged_run_fails_with_one_line(tmp_path, capsys, diverging, command):
    diverging(above=15.0)  # forces 20, 40, 60 of 10..60 diverge: 75 % of the cells
    out = tmp_path / "out"
    grid = ["--forces", "10,20,40,60"] + (["--durations", "0.1,0.2"] if command == "sweep" else [])
    assert main(["-q", command, *grid, "--set", "scenario.t_end=2", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "diverged" in err[0] and "not results" in err[0], err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["runs"][-1]["status"] == "failed"
    assert not (out / "region.png").exists() and not (out / "table.png").exists()
    # the same folder again: the finished numbers are still not results
    assert main(["-q", command, *grid, "--set", "scenario.t_end=2", "--out", str(out)]) == 1
    # a corrected configuration takes the folder over (it held no result worth keeping; it
    # refused "made with a different configuration") and computes every cell anew
    diverging(above=1000.0)
    assert main(["-q", command, *grid, "--set", "scenario.t_end=3", "--out", str(out)]) == 0
    assert "holds no results of the configuration it was made with" in capsys.readouterr().err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["scenario"]["t_end"] == 3.0
    assert manifest["runs"][-1]["status"] == "completed"
    kept = out / ("region.parquet" if command == "sweep" else "table_runs.parquet")
    assert "diverged" not in set(pd.read_parquet(kept)["outcome"])  # none of the failed run's


def test_a_few_diverged_cells_are_results(tmp_path, diverging):
    diverging(above=50.0)  # one force of four: 25 % diverged
    out = tmp_path / "out"
    assert (
        main(
            [
                "-q",
                "sweep",
                "--forces",
                "10,20,40,60",
                "--durations",
                "0.1,0.2",
                "--set",
                "scenario.t_end=2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert (out / "region.png").exists()
    with pytest.raises(NotAResult):  # the API raises it
        diverging(above=0.0)
        mb.sweep([10.0, 20.0], [0.1], Config().replace(scenario={"t_end": 2.0}))


def test_an_absurd_push_gives_its_outcome_row_and_figures(tmp_path, capsys):
    """1e12 N diverges at the first step; the run still writes its summary row and
    figures that say there is nothing to draw, instead of a traceback."""
    out = tmp_path / "out"
    assert (
        main(
            [
                "-q",
                "simulate",
                "--forces",
                "1e12",
                "--durations",
                "0.1",
                "--set",
                "scenario.t_end=0.2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["outcome"]) == ["diverged"]
    assert (out / "ankle_angle.png").exists() and (out / "energy.png").exists()
    assert "Traceback" not in capsys.readouterr().err


# -- numerics on resume -------------------------------------------------------------


def test_the_numerics_fingerprint_is_recorded_and_a_mismatch_refused(tmp_path, caplog):
    from support import FakeThresholdBatch, sweep_fake

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
        "--a=2",
        "--b=1",
    ]
    assert fingerprint.cpu_isa("--xla_cpu_max_isa=avx") == "AVX"
    assert fingerprint.differences(
        {"x64": False, "cpu_isa": "AVX2"}, {"x64": True, "cpu_isa": "AVX"}
    ) == (["x64: False -> True"], ["cpu_isa: 'AVX2' -> 'AVX'"])


# -- damaged records and sweep definitions --------------------------------------------------------


DAMAGED = [
    ("not json", "{not json", "damaged"),
    ("a list", "[1, 2]", "holds a list"),
    ("no config", '{"conventions": ["paper"]}', "has no configuration"),
    ("no conventions", '{"config": {}}', "has no list of conventions"),
]


@pytest.mark.parametrize("case,text,words", DAMAGED, ids=[c[0] for c in DAMAGED])
def test_html_only_on_a_damaged_record_is_one_line(tmp_path, capsys, case, text, words):
    (tmp_path / "report.json").write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = cli.main(["report", "--html-only", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mjx-balance: error: "), err
    assert "report.json" in lines[0] and words in lines[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_a_new_run_refuses_a_damaged_record(tmp_path):
    (tmp_path / "report.json").write_text("[]")
    with pytest.raises(ParameterError, match="holds a list"):
        open_record(tmp_path, Config(), PLANS["tiny"], "reference", ("paper",))


def test_a_missing_record_is_empty_for_a_new_run_and_an_error_otherwise(tmp_path):
    assert read_record(tmp_path / "report.json", required=False) == {}
    with pytest.raises(ParameterError, match="not found"):
        read_record(tmp_path / "report.json")


def test_sweep_definition_that_is_a_folder_or_binary_is_one_error(tmp_path):
    with pytest.raises(ParameterError, match="a folder, not a sweep definition"):
        load_sweep(tmp_path, Config())
    binary = tmp_path / "bad.toml"
    binary.write_bytes(b"\xff\xfe[sweep]\n")
    with pytest.raises(ParameterError, match="not UTF-8 text"):
        load_sweep(binary, Config())


def test_sweep_definition_section_must_be_a_table(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('controller = 3\n[sweep]\nforces = "0:10:5"\n')
    with pytest.raises(ParameterError, match=r"controller must be a table"):
        load_sweep(path, Config())


# -- durations of whole physics steps; simulate's grids and folder --------------------------------


PHYSICS_DT = Config().scenario.physics_dt


class Called(Exception):
    """Raised by a stand-in simulation: the command got as far as simulating."""


def whole_steps_message(duration: float, name: str = "--duration") -> str:
    with pytest.raises(ParameterError) as exc:
        check_whole_steps([duration], PHYSICS_DT, name)
    return str(exc.value)


@pytest.mark.parametrize("name", ["simulate", "animate"])
def test_durations_off_the_physics_steps_are_refused(tmp_path, capsys, monkeypatch, name):
    def refuse(*args, **kwargs):
        raise Called

    monkeypatch.setattr("mjx_balance.reference.loop.simulate_many", refuse)
    monkeypatch.setattr("mjx_balance.reference.loop.simulate_scenario", refuse)
    out = tmp_path / ("push.gif" if name == "animate" else "out")
    # simulate takes lists (--forces, --durations), animate one push (--force, --duration)
    force, duration = (
        ("--force", "--duration") if name == "animate" else ("--forces", "--durations")
    )
    code, err = run_cli([name, force, "10", duration, "0.1005", "--out", str(out)], capsys)
    assert_refused(code, err, whole_steps_message(0.1005, duration))
    assert list(tmp_path.iterdir()) == []

    # Float error is not an offence: the value is snapped to its whole steps.
    with pytest.raises(Called):
        cli.main([name, force, "10", duration, "0.10000000001", "--out", str(out)])


def test_simulate_reads_forces_and_durations_as_sweep_does(tmp_path, capsys, monkeypatch):
    asked = {}

    def record(config, pairs, **_options):  # the cross product, every force per duration
        asked.update(
            forces=list(dict.fromkeys(f for f, _ in pairs)),
            durations=list(dict.fromkeys(d for _, d in pairs)),
        )
        raise Called

    monkeypatch.setattr("mjx_balance.reference.loop.each_pair", record)
    with pytest.raises(Called):
        cli.main(
            [
                "simulate",
                "--forces",
                "0:40:20",
                "--durations",
                "0.05:0.1:0.05",
                "--out",
                str(tmp_path / "out"),
            ]
        )
    assert asked == {"forces": [0.0, 20.0, 40.0], "durations": [0.05, 0.1]}
    with pytest.raises(Called):
        cli.main(
            ["simulate", "--forces=-20,10", "--durations", "0,0.1", "--out", str(tmp_path / "out")]
        )
    assert asked == {"forces": [-20.0, 10.0], "durations": [0.0, 0.1]}
    for bad, words in [
        ("0:1:0", ["--durations", "step must be > 0"]),
        ("0.1,0.1", ["--durations", "more than once"]),
        ("0:0.101:0.0505", ["--durations", "not a whole number of physics steps"]),
    ]:
        code, err = run_cli(
            ["simulate", "--durations", bad, "--out", str(tmp_path / "bad")], capsys
        )
        assert_refused(code, err, *words)
        assert not (tmp_path / "bad").exists()


# --- simulate does not write into a sweep folder --------------------------------------


@pytest.mark.parametrize(
    "holds",
    [
        ["manifest.json", "config.toml"],
        ["config.toml", "chunks/"],
        ["config.toml", "region.parquet"],
        ["config.toml", "report.json"],
    ],
)
def test_simulate_refuses_a_sweep_folder(tmp_path, capsys, monkeypatch, holds):
    def refuse(*args, **kwargs):
        raise Called

    monkeypatch.setattr("mjx_balance.reference.loop.simulate_many", refuse)
    out = tmp_path / "sweep"
    out.mkdir()
    for name in holds:
        if name.endswith("/"):
            (out / name).mkdir()
        else:
            (out / name).write_text("the sweep's own\n")
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    code, err = run_cli(["simulate", "--forces", "10", "--out", str(out)], capsys)
    assert_refused(code, err, str(out), "sweep")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in out.iterdir()) == sorted(n.rstrip("/") for n in holds)
