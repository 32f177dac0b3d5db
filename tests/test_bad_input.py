"""Every command refuses bad arguments before any work: exit code 2, one error line on stderr
(argparse's, after its usage, or ``mjx-balance: error: ...``), no traceback, nothing written.

The commands run in this process (``cli.main``), a few in a subprocess to see the real exit code
and stderr. None of them gets far enough to simulate anything.
"""

import os
import subprocess
import sys

import pytest

from mjx_balance import cli

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


def run(argv: list[str], capsys) -> tuple[int, str]:
    """(exit code, stderr) of cli.main(argv); argparse's errors exit through SystemExit."""
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def assert_refused(code: int, err: str, *words: str, exit_code: int = 2) -> None:
    """Exit 2 (1 for a failure during the work) and a single error line naming ``words``, last
    on stderr; with no usage before it, stderr is that one line."""
    assert code == exit_code, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    errors = [line for line in lines if "error:" in line]
    assert len(errors) == 1 and errors[0] == lines[-1], err
    assert lines[-1].startswith("mjx-balance") and "error: " in lines[-1]
    if not lines[0].startswith("usage:"):
        assert len(lines) == 1, err
    for word in words:
        assert word in lines[-1], err


@pytest.fixture
def files(tmp_path):
    """Bad inputs: a folder, a non-UTF-8 file, configurations that break a rule, a plain file."""
    made = {"folder": tmp_path / "a_folder", "binary": tmp_path / "binary.toml",
            "file": tmp_path / "a_file"}
    made["folder"].mkdir()
    made["binary"].write_bytes(b"\xff\xfe[body]\nfoot_mass = 1.0\n")
    made["file"].write_text("not a folder\n")
    for name, text in {"nested": "[controller]\ninput1_bounds = [[1, 2], 3]\n",
                       "q_text": '[controller]\nq_diag = ["a", 1, 1, 1]\n',
                       "q_bool": "[controller]\nq_diag = [true, 1, 1, 1]\n",
                       "physics_dt": "[scenario]\nphysics_dt = 1.0\ncontrol_dt = 1.0\n",
                       "mass": "[body]\nupper_mass = 1e308\n"}.items():
        made[name] = tmp_path / f"{name}.toml"
        made[name].write_text(text)
    return made


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("config,words", [
    ("folder", ["--config", "is not a file"]),
    ("binary", ["--config", "not UTF-8"]),
    ("nested", ["controller.input1_bounds", "list of numbers"]),
    ("q_text", ["controller.q_diag", "list of numbers"]),
    ("q_bool", ["controller.q_diag", "list of numbers"]),
    ("physics_dt", ["scenario.physics_dt", "<= 0.01"]),
    ("mass", ["body.upper_mass", "[0.001, 10000] kg"]),
])
def test_every_command_refuses_a_bad_config(tmp_path, files, capsys, name, config, words):
    out = tmp_path / "out"
    code, err = run(command(name, out, "--config", str(files[config])), capsys)
    assert_refused(code, err, *words)
    assert not out.exists() and not out.with_suffix(".gif").exists()


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("where,words", [
    ("", ["--out", "give a"]),
    ("file", ["--out", "a_file' exists and is not a folder"]),  # animate: see below
    ("file/sub", ["--out", "a_file' is not a folder"]),  # its parent is a file: cannot be made
])
def test_every_command_refuses_an_unusable_out(tmp_path, files, capsys, name, where, words):
    out = "" if not where else str(tmp_path / where.replace("file", "a_file"))
    if name == "animate" and where == "file":  # a GIF may be overwritten, a name must be .gif
        words = ["--out", "a_file': the file name must end in .gif"]
    if name == "animate" and where == "file/sub":
        out += ".gif"
    argv = command(name, "OUT")
    argv[argv.index("--out") + 1] = out
    code, err = run(argv, capsys)
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
    monkeypatch.setattr(os, "access", lambda path, mode: (
        False if str(path) == str(parent) else real_access(path, mode)))
    out = parent / "new" / "deeper"
    code, err = run(command(name, out), capsys)
    assert_refused(code, err, "--out", "read_only' is not writable")
    assert list(parent.iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_a_read_only_folder_is_refused(tmp_path, capsys):
    parent = tmp_path / "read_only"
    parent.mkdir(mode=0o555)
    code, err = run(command("sweep", parent / "new"), capsys)
    assert_refused(code, err, "--out", "is not writable")
    assert list(parent.iterdir()) == []


def test_a_write_that_fails_is_one_line(tmp_path, capsys, monkeypatch):
    """A place that passes the checks but refuses the write (root on /proc, a full disk): main
    reports the OSError in one line, as a failure (exit 1)."""
    from mjx_balance.cli import simulate

    def refuse(args):
        raise PermissionError(13, "Permission denied", str(tmp_path / "out" / "summary.csv"))

    monkeypatch.setattr(simulate, "simulate_command", refuse)
    code, err = run(command("simulate", tmp_path / "out"), capsys)
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


@pytest.mark.parametrize("name,extra,words", BAD_VALUES,
                         ids=[f"{name} {' '.join(extra)}" for name, extra, _ in BAD_VALUES])
def test_bad_values_are_refused(tmp_path, capsys, name, extra, words):
    out = tmp_path / "out"
    code, err = run(command(name, out, *extra), capsys)
    assert_refused(code, err, *words)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where,words", [
    ("movie", ["--out", "must end in .gif"]),  # no extension
    ("movie.mp4", ["--out", "must end in .gif"]),
    ("a_folder", ["--out", "is a folder"]),
    ("a_folder.gif", ["--out", "is a folder"]),
])
def test_animate_out_must_be_a_gif_file(tmp_path, capsys, where, words):
    (tmp_path / "a_folder").mkdir()
    (tmp_path / "a_folder.gif").mkdir()
    code, err = run(["animate", "--force", "10", "--out", str(tmp_path / where)], capsys)
    assert_refused(code, err, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_folder", "a_folder.gif"]
    assert not any((tmp_path / "a_folder").iterdir())


@pytest.mark.parametrize("argv,words", [
    (["sweep", "--forces", "0", "--durations", "0.1", "--chunk", "-3"], ["--chunk"]),
    (["animate", "--force", "10", "--fps", "nan"], ["--fps", "finite"]),
    (["simulate", "--forces", "10", "--config", "CONFIG"], ["controller.input1_bounds"]),
])
def test_the_process_exits_2_without_a_traceback(tmp_path, argv, words):
    """The installed entry point, in its own process: exit status 2, one error line."""
    config = tmp_path / "nested.toml"
    config.write_text("[controller]\ninput1_bounds = [[1, 2], 3]\n")
    out = tmp_path / ("out.gif" if argv[0] == "animate" else "out")
    argv = [a.replace("CONFIG", str(config)) for a in argv] + ["--out", str(out)]
    done = subprocess.run([sys.executable, "-c", "import sys; from mjx_balance.cli import main; "
                           "sys.exit(main())", *argv], capture_output=True, text=True, timeout=300)
    assert done.stdout == ""
    assert_refused(done.returncode, done.stderr, *words)
    assert not out.exists()
