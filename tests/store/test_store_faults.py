"""Lost or damaged work in an output folder, and the disk and the lock failing during the work:
faults injected, then a rerun.

Damaged figures are drawn again; a folder that lost its manifest is taken up again when its
config.toml and chunk files check out; a second run into a folder that another process holds
is refused at once, or waits for it with --wait; a failed write (a full disk, a file-size
limit) ends in one line and the rerun resumes; ``simulate``, ``animate`` and ``report`` write
their files atomically (a write that fails half-way leaves the old file, or none); files get
the mode the umask gives and no temporary file is left.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import stat
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pandas as pd
import pytest
from support import (
    CLI_GRID,
    GRID,
    REPO,
    FakeThresholdBatch,
    cli_sweep,
    held_sweep,
    held_table,
    run_cli,
    sweep_fake,
    tiny_config,
)

from mjx_balance import cli
from mjx_balance.cli import main
from mjx_balance.cli.main import build_parser
from mjx_balance.model.params import ParameterError
from mjx_balance.runs import region as region_module
from mjx_balance.store.files import readable_png
from mjx_balance.store.folder import FolderBusy, folder_lock
from mjx_balance.runs.grid import Grid

# -- damaged and lost work, the lock, the disk ----------------------------------------------------


def error_lines(stderr: str) -> list[str]:
    """The error lines of a command's stderr (the progress bar aside); none may be a traceback."""
    assert "Traceback" not in stderr
    return [line for line in stderr.splitlines() if "error" in line]


# --- damaged figures are drawn again ---------------------------------------------------


def test_truncated_or_missing_figures_are_redrawn_on_rerun(tmp_path, fake_rollout, capsys):
    out = tmp_path / "run"
    assert cli_sweep(out) == 0
    region_png, energy_png = out / "region.png", out / "energy.png"
    assert readable_png(region_png) and readable_png(energy_png)
    whole = region_png.read_bytes()
    region_png.write_bytes(whole[: len(whole) // 2])  # cut short, as by a file-size limit
    assert not readable_png(region_png)
    energy_png.unlink()
    idle = fake_rollout(FakeThresholdBatch(fail_on_call=1))
    capsys.readouterr()
    assert cli_sweep(out) == 0
    assert idle.calls == []  # the sweep itself was complete: nothing computed
    printed = capsys.readouterr().out
    assert "nothing to do" in printed and f"wrote {region_png}" in printed
    assert readable_png(region_png) and readable_png(energy_png)
    # A whole figure is left alone.
    assert cli_sweep(out) == 0
    assert "wrote" not in capsys.readouterr().out


def test_truncated_table_figure_is_redrawn_on_rerun(tmp_path, fake_rollout, capsys):
    command = ["table", "--forces", "20,40", "--out", str(tmp_path)]
    assert main(command) == 0
    table_png = tmp_path / "table.png"
    table_png.write_bytes(table_png.read_bytes()[:-100])
    idle = fake_rollout(FakeThresholdBatch(fail_on_call=1))
    capsys.readouterr()
    assert main(command) == 0
    printed = capsys.readouterr().out
    assert idle.calls == [] and "nothing to do" in printed and f"wrote {table_png}" in printed
    assert readable_png(table_png)


def test_readable_png_rejects_cut_and_corrupt_files(tmp_path, fake_rollout):
    assert cli_sweep(tmp_path) == 0
    whole = (tmp_path / "region.png").read_bytes()
    bad = tmp_path / "bad.png"
    for damaged in (
        b"",
        whole[:8],
        whole[:-1],
        whole[:1000] + whole[-12:],
        whole[:200] + bytes(100) + whole[300:],
    ):
        bad.write_bytes(damaged)
        assert not readable_png(bad)
    assert not readable_png(tmp_path / "missing.png")
    bad.write_bytes(whole)
    assert readable_png(bad)


# --- a lost manifest is rebuilt ----------------------------------------------------------


def test_lost_manifest_is_rebuilt_from_config_and_chunks(tmp_path):
    whole = tmp_path / "whole"
    sweep_fake(whole, FakeThresholdBatch())
    out = tmp_path / "cut"
    with pytest.raises(KeyboardInterrupt):
        sweep_fake(out, FakeThresholdBatch(fail_on_call=3))
    recorded = without_runs(json.loads((out / "manifest.json").read_text()))
    (out / "manifest.json").unlink()

    lines: list[str] = []
    resumed = FakeThresholdBatch()
    result = held_sweep(
        out,
        tiny_config(),
        Grid.of(*GRID, tiny_config()),
        run_batch=resumed,
        chunk=100,
        progress=False,
        say=lines.append,
    )
    assert resumed.calls == [8] * 3 and result.reused_chunks == 2  # chunk size from the files
    rebuilt = [line for line in lines if "lost its manifest.json" in line]
    assert len(rebuilt) == 1 and "config.toml matches" in rebuilt[0] and "2 of 2" in rebuilt[0]
    assert without_runs(json.loads((out / "manifest.json").read_text())) == recorded
    pd.testing.assert_frame_equal(
        pd.read_parquet(out / "region.parquet"), pd.read_parquet(whole / "region.parquet")
    )

    # A finished folder without its manifest: nothing to compute.
    (out / "manifest.json").unlink()
    idle = FakeThresholdBatch(fail_on_call=1)
    assert sweep_fake(out, idle).already_complete and idle.calls == []
    assert without_runs(json.loads((out / "manifest.json").read_text())) == recorded


def without_runs(manifest: dict) -> dict:
    """A manifest less its provenance records (``runs``: one per run, differing by design)."""
    return {key: value for key, value in manifest.items() if key != "runs"}


def test_lost_manifest_is_not_rebuilt_for_other_results(tmp_path):
    sweep_fake(tmp_path, FakeThresholdBatch())
    (tmp_path / "manifest.json").unlink()
    other = tiny_config().replace(controller={"horizon": 10})
    with pytest.raises(ParameterError, match="config.toml differs.*controller.horizon"):
        sweep_fake(tmp_path, FakeThresholdBatch(), config=other)
    with pytest.raises(ParameterError, match="do not match this grid"):
        held_sweep(
            tmp_path,
            tiny_config(),
            Grid.of("0:100:20", GRID[1], tiny_config()),
            run_batch=FakeThresholdBatch(),
            progress=False,
            say=None,
        )
    assert not (tmp_path / "manifest.json").exists()  # nothing rewritten by a refused run
    shutil.rmtree(tmp_path / "chunks")  # region.parquet alone, of another grid: kept, refused
    region = (tmp_path / "region.parquet").read_bytes()
    with pytest.raises(ParameterError, match="do not match this grid"):
        held_sweep(
            tmp_path,
            tiny_config(),
            Grid.of("0:100:20", GRID[1], tiny_config()),
            run_batch=FakeThresholdBatch(),
            progress=False,
            say=None,
        )
    assert (tmp_path / "region.parquet").read_bytes() == region
    (tmp_path / "config.toml").unlink()
    with pytest.raises(ParameterError, match="no manifest.json and no config.toml"):
        sweep_fake(tmp_path, FakeThresholdBatch())


def test_lost_manifest_of_a_table_folder_lets_a_sweep_start(tmp_path):
    held_table(
        tmp_path, tiny_config(), [20, 40], run_batch=FakeThresholdBatch(), progress=False, say=None
    )
    (tmp_path / "manifest.json").unlink()
    lines: list[str] = []
    held_sweep(
        tmp_path,
        tiny_config(),
        Grid.of(*GRID, tiny_config()),
        run_batch=FakeThresholdBatch(),
        chunk=8,
        progress=False,
        say=lines.append,
    )
    assert [line for line in lines if "lost its manifest.json" in line]
    assert json.loads((tmp_path / "manifest.json").read_text())["region"]["cells"] == 35


# --- one run per folder ----------------------------------------------------------------


HOLD_LOCK = textwrap.dedent("""
    import sys
    from mjx_balance.store.folder import folder_lock
    with folder_lock(sys.argv[1]):
        print("locked", flush=True)
        sys.stdin.read()  # until the test closes our stdin
""")


def test_second_run_is_refused_while_another_holds_the_folder(tmp_path, fake_rollout, capsys):
    out = tmp_path / "shared"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD_LOCK, str(out)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        fake = fake_rollout(FakeThresholdBatch())
        assert cli_sweep(out) == 2
        lines = error_lines(capsys.readouterr().err)
        assert len(lines) == 1
        assert f"in use by another run (PID {holder.pid}, started " in lines[0]
        assert fake.calls == [] and not (out / "manifest.json").exists()
        with pytest.raises(FolderBusy):
            sweep_fake(out, FakeThresholdBatch())
    finally:
        holder.stdin.close()
        holder.wait(timeout=60)
    assert cli_sweep(out) == 0  # the lock went with the other process
    assert fake.calls


def test_a_run_takes_the_folder_lock_once(tmp_path):
    """The run's entry takes the lock; a second take in the same run is a bug (raised), and
    the floors that write a run's files refuse to run without it."""
    from mjx_balance.runs import run_sweep, run_table
    from mjx_balance.runs.grid import Grid

    with folder_lock(tmp_path):
        sweep_fake(tmp_path / "inner", FakeThresholdBatch())  # another folder: its own lock
        with pytest.raises(RuntimeError, match="taken twice"), folder_lock(tmp_path):
            pass
        sweep_fake(tmp_path / "inner", FakeThresholdBatch())  # the inner lock was let go
    assert "PID" in (tmp_path / ".lock").read_text()
    config = tiny_config()
    with pytest.raises(RuntimeError, match="not held"):
        run_sweep(
            tmp_path / "bare",
            config,
            Grid.of(*GRID, config),
            run_batch=FakeThresholdBatch(),
            progress=False,
            say=None,
        )
    with pytest.raises(RuntimeError, match="not held"):
        run_table(
            tmp_path / "bare",
            config,
            [20.0],
            run_batch=FakeThresholdBatch(),
            progress=False,
            say=None,
        )
    assert not (tmp_path / "bare" / "manifest.json").exists()


def test_another_thread_is_refused_while_one_holds_the_folder(tmp_path):
    """The lock is the holding thread's, not the process's: two threads of one process
    sweeping into one folder with different bodies would otherwise write one body's manifest
    beside the other body's rows. The second thread is refused at the named point (its
    folder_lock) while the first is inside its own."""
    import threading

    outcome = {}

    def other():
        try:
            sweep_fake(tmp_path, FakeThresholdBatch())
            outcome["result"] = "ran"
        except FolderBusy as exc:
            outcome["result"] = str(exc)

    with folder_lock(tmp_path):
        worker = threading.Thread(target=other)
        worker.start()
        worker.join(timeout=120)
    assert "in use by another run" in outcome["result"]
    assert not (tmp_path / "region.parquet").exists()
    sweep_fake(tmp_path, FakeThresholdBatch())  # the folder is free again
    assert (tmp_path / "region.parquet").exists()


def test_a_waiting_thread_runs_after_the_holder_lets_go(tmp_path):
    import threading

    order = []
    entered = threading.Event()

    def other():
        with folder_lock(tmp_path, wait=True):
            order.append("second")

    with folder_lock(tmp_path):
        worker = threading.Thread(target=other)
        worker.start()
        entered.wait(0.5)  # give it time to block on the lock (it must not get in)
        order.append("first")
    worker.join(timeout=60)
    assert order == ["first", "second"]


def test_a_folder_that_cannot_hold_a_lock_file_is_still_read(tmp_path, monkeypatch):
    """A finished sweep shared read-only: no lock file can be made, and none is needed."""
    sweep_fake(tmp_path, FakeThresholdBatch())
    (tmp_path / ".lock").unlink()
    real_open = os.open

    def read_only(path, flags, *args):
        if str(path).endswith(".lock"):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real_open(path, flags, *args)

    monkeypatch.setattr(os, "open", read_only)
    assert sweep_fake(tmp_path, FakeThresholdBatch(fail_on_call=1)).already_complete


# --- write errors ----------------------------------------------------------------------


def test_full_disk_mid_sweep_is_one_line_and_the_rerun_resumes(
    tmp_path, fake_rollout, capsys, monkeypatch
):
    whole = tmp_path / "whole"
    assert cli_sweep(whole) == 0
    out = tmp_path / "full"
    writes = []
    real_write = region_module.write_chunk

    def fill_disk_on_third_chunk(frame, folder, index):
        writes.append(index)
        if len(writes) == 3:
            path = folder / "chunks" / f"chunk-{index:05d}.parquet"
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        real_write(frame, folder, index)

    monkeypatch.setattr(region_module, "write_chunk", fill_disk_on_third_chunk)
    capsys.readouterr()
    assert cli_sweep(out) == 1
    lines = error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    assert str(out) in lines[0] and "No space left on device" in lines[0]
    assert "run the same command again" in lines[0]
    assert len(list((out / "chunks").glob("chunk-*.parquet"))) == 2  # finished chunks kept
    assert not (out / "region.parquet").exists()

    monkeypatch.setattr(region_module, "write_chunk", real_write)
    resumed = fake_rollout(FakeThresholdBatch())
    assert cli_sweep(out) == 0
    assert resumed.calls == [4, 4]  # chunks 2 and 3 of 0..3
    pd.testing.assert_frame_equal(
        pd.read_parquet(out / "region.parquet"), pd.read_parquet(whole / "region.parquet")
    )


FAKE_SWEEP = textwrap.dedent("""
    import resource, sys
    sys.path.insert(0, sys.argv[1])
    from support import FakeThresholdBatch
    import mjx_balance.runs.batch
    mjx_balance.runs.batch.default_batch = lambda config, **engine: FakeThresholdBatch()
    limit = int(sys.argv[2])
    if limit:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    from mjx_balance.cli import main
    sys.exit(main(["sweep", *sys.argv[4:], "--out", sys.argv[3]]))
""")


def run_fake_sweep(out: Path, file_limit: int) -> subprocess.CompletedProcess:
    return subprocess.run(
        [
            sys.executable,
            "-c",
            FAKE_SWEEP,
            str(REPO / "tests"),
            str(file_limit),
            str(out),
            *CLI_GRID,
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_file_size_limit_leaves_no_damaged_figure(tmp_path, fake_rollout, capsys):
    """A file-size limit that the tables fit under but region.png does not, met while a figure
    that exists is drawn again. The limited run is a process of its own (RLIMIT_FSIZE); the
    runs before and after it run here, on the same fake rollout."""
    out = tmp_path / "limited"
    assert cli_sweep(out) == 0
    (out / "region.parquet").unlink()  # merged again from the chunks, then the figures redrawn
    cut = run_fake_sweep(out, file_limit=40_000)
    assert cut.returncode == 1, cut.stderr
    lines = error_lines(cut.stderr)
    assert len(lines) == 1 and "File too large" in lines[0] and str(out) in lines[0]
    assert "ulimit -f" in lines[0]
    assert (out / "region.parquet").exists()
    assert readable_png(out / "region.png")  # the earlier figure, whole, not a truncated one
    assert not list(out.glob(".*.tmp"))
    capsys.readouterr()
    assert cli_sweep(out) == 0
    again = capsys.readouterr().out
    assert "nothing to do" in again
    for name in ("region.png", "energy.png"):  # older than region.parquet: drawn again
        assert f"wrote {out / name}" in again and readable_png(out / name)


# --- file modes and leftovers ----------------------------------------------------------


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o027, 0o640)])
def test_files_get_the_mode_the_umask_gives(tmp_path, fake_rollout, umask, mode):
    old = os.umask(umask)
    try:
        assert cli_sweep(tmp_path) == 0
    finally:
        os.umask(old)
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    names = {p.name for p in files}
    assert {
        "region.parquet",
        "manifest.json",
        "config.toml",
        "region.png",
        "energy.png",
        "chunk-00000.parquet",
        ".lock",
    } <= names
    wrong = {
        p.name: oct(stat.S_IMODE(p.stat().st_mode))
        for p in files
        if stat.S_IMODE(p.stat().st_mode) != mode
    }
    assert wrong == {}


def test_leftover_temporary_files_are_removed(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        sweep_fake(tmp_path, FakeThresholdBatch(fail_on_call=2))
    leftovers = [
        tmp_path / ".region.parquet.x1y2.tmp",
        tmp_path / "chunks" / ".chunk-00001.parquet.a1b2.tmp",
    ]
    for path in leftovers:
        path.write_bytes(b"half a file")
    sweep_fake(tmp_path, FakeThresholdBatch())
    assert not any(path.exists() for path in leftovers)
    assert not list(tmp_path.rglob("*.tmp"))


# -- atomic outputs; waiting for the folder's holder ----------------------------------------------


def short_config(tmp_path: Path, t_end: float = 0.2) -> Path:
    path = tmp_path / "short.toml"
    path.write_text(f"[scenario]\nt_end = {t_end}\n")
    return path


def half_then_fail(write_partial):
    """A writer that writes half a file at the path it is given, then fails (a full disk)."""

    def fail(path):
        write_partial(path)
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    return fail


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*.tmp"))


def test_outputs_are_whole_or_old_after_a_failed_write(tmp_path, capsys, monkeypatch):
    import matplotlib.figure
    import pandas as pd
    import pyarrow.parquet as pq
    from PIL import Image

    from mjx_balance.report import html
    from mjx_balance.studies import experiments as report_run

    # simulate: a first run, then reruns in which one kind of write fails half-way.
    out = tmp_path / "sim"
    argv = [
        "simulate",
        "--forces",
        "10",
        "--durations",
        "0.1",
        "--config",
        str(short_config(tmp_path)),
        "--out",
        str(out),
    ]
    assert cli.main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"summary.csv", "timeseries.parquet", "config.toml", "energy.png"} <= set(before)
    failing = [  # summary.csv, timeseries.parquet, config.toml, the figures
        (
            pd.DataFrame,
            "to_csv",
            lambda self, path, **kw: half_then_fail(lambda p: open(p, "w").write("force,dura"))(
                path
            ),
        ),
        # parquet files are written by pyarrow (store.files.write_parquet: units in the schema)
        (
            pq,
            "write_table",
            lambda table, path, **kw: half_then_fail(lambda p: open(p, "wb").write(b"PAR1\x00"))(
                path
            ),
        ),
        (
            Path,
            "write_text",
            lambda self, text, **kw: half_then_fail(lambda p: open(p, "w").write(text[:10]))(self),
        ),
        (
            matplotlib.figure.Figure,
            "savefig",
            lambda self, path, **kw: half_then_fail(lambda p: open(p, "wb").write(b"\x89PNG\r\n"))(
                path
            ),
        ),
    ]
    for owner, name, fail in failing:
        with monkeypatch.context() as m:
            m.setattr(owner, name, fail)
            code, err = run_cli(argv, capsys)
        assert code == 1 and "No space left" in err and "Traceback" not in err, name
        # the tables and figures as they were; the manifest records the failed run beside
        # the tables it describes, and the finished push is kept for the next run (pushes/)
        after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
        records = ("manifest.json", ".lock")  # the runs' records (the lock names its holder)
        assert {k: v for k, v in after.items() if k not in records} == {
            k: v for k, v in before.items() if k not in records
        }, name
        manifest = json.loads(after["manifest.json"])
        old = json.loads(before["manifest.json"])
        assert (manifest["config"], manifest["simulate"]) == (old["config"], old["simulate"])
        assert manifest["runs"][-1]["status"] == "failed", name
        assert leftovers(tmp_path) == [], name

    # animate: the GIF is written whole or the old one stays.
    gif = tmp_path / "push.gif"
    gif.write_bytes(b"an older GIF")
    with monkeypatch.context() as m:
        m.setattr(
            Image.Image,
            "save",
            lambda self, fp, *a, **kw: half_then_fail(lambda p: Path(p).write_bytes(b"GIF89a"))(fp),
        )
        code, err = run_cli(
            ["animate", "--force", "10", "--t-end", "0.1", "--fps", "50", "--out", str(gif)], capsys
        )
        assert code == 1 and "Traceback" not in err
    assert gif.read_bytes() == b"an older GIF"
    assert leftovers(tmp_path) == []
    code, _ = run_cli(
        ["animate", "--force", "10", "--t-end", "0.1", "--fps", "50", "--out", str(gif)], capsys
    )
    assert code == 0
    with Image.open(gif) as image:
        assert image.format == "GIF" and image.n_frames == 6

    # report: report.html, its figures and its tables.
    rep = tmp_path / "report"
    rep.mkdir()
    monkeypatch.setattr(
        html,
        "load_results",
        lambda out: {"conventions": {}, "studies": {}, "record": {}, "config": None},
    )
    monkeypatch.setattr(html, "sections", lambda out: [])
    monkeypatch.setattr(
        html,
        "overview_section",
        lambda page: {"id": "overview", "heading": "overview", "blocks": []},
    )
    monkeypatch.setattr(html, "banner", lambda record, config: None)
    page = html.build_report(rep)
    assert "overview" in page.read_text()
    (rep / "figures" / "f.png").write_bytes(b"old figure")
    report_run.write_csv(pd.DataFrame({"a": [1]}), rep / "numbers.csv")
    report_run.write_json(rep / "report.json", {"a": 1})
    before = {p.relative_to(rep): p.read_bytes() for p in rep.rglob("*") if p.is_file()}
    with monkeypatch.context() as m:
        m.setattr(
            Path,
            "write_text",
            lambda self, text, **kw: half_then_fail(lambda p: p.write_bytes(text[:10].encode()))(
                self
            ),
        )
        m.setattr(
            pd.DataFrame,
            "to_csv",
            lambda self, path, **kw: half_then_fail(lambda p: open(p, "w").write("a,"))(path),
        )
        m.setattr(
            matplotlib.figure.Figure,
            "savefig",
            lambda self, path, **kw: half_then_fail(lambda p: open(p, "wb").write(b"\x89PNG"))(
                path
            ),
        )
        with pytest.raises(OSError):
            html.build_report(rep)
        with pytest.raises(OSError):
            report_run.write_json(rep / "report.json", {"b": 2})
        with pytest.raises(OSError):
            report_run.write_csv(pd.DataFrame({"b": [2]}), rep / "numbers.csv")
        import matplotlib.pyplot as plt

        with pytest.raises(OSError):
            html.save_figure(plt.figure(), rep / "figures" / "f.png")
    assert {p.relative_to(rep): p.read_bytes() for p in rep.rglob("*") if p.is_file()} == before
    assert leftovers(tmp_path) == []


# --- --wait --------------------------------------------------------------------------


def test_wait_for_the_run_that_holds_the_folder(tmp_path, fake_rollout, capsys):
    assert build_parser().parse_args(["table", "--wait", "--out", "x"]).wait is True
    assert build_parser().parse_args(["sweep", "--out", "x"]).wait is False
    out = tmp_path / "shared"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD_LOCK, str(out)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    release = threading.Timer(3.0, holder.stdin.close)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert cli_sweep(out) == 2  # by default: refused at once
        assert "in use by another run" in capsys.readouterr().err
        assert not (out / "manifest.json").exists()
        start = time.monotonic()
        release.start()
        assert cli_sweep(out, "--wait") == 0  # waits for the holder, then runs
        assert time.monotonic() - start > 2.5  # it ran only once the holder had let go
    finally:
        release.cancel()
        holder.stdin.close()
        holder.wait(timeout=60)
    lines = capsys.readouterr().err.splitlines()
    assert "Traceback" not in "\n".join(lines) and not [x for x in lines if "error" in x]
    waiting = [line for line in lines if line.startswith("waiting")]
    assert len(waiting) == 1, lines
    assert waiting[0].startswith(
        f"waiting for {out}: in use by another run (PID {holder.pid}, started "
    ), waiting
    assert (out / "region.parquet").exists()


@pytest.mark.parametrize("kind", ["simulate", "cohort"])
def test_a_sweep_refuses_a_folder_of_another_kind(tmp_path, capsys, fake_rollout, kind):
    """A folder holding a simulate or a cohort run is not a sweep's to take over."""
    out = tmp_path / "other"
    out.mkdir()
    manifest = {"package": "mjx_balance", "version": "0", "kind": kind, "config": {}}
    (out / "manifest.json").write_text(json.dumps(manifest))
    assert main(["-q", "sweep", "--forces", "10", "--durations", "0.1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"mjx-balance: error: {out} holds another kind of output (a {kind} run's); "
        "use another --out folder"
    ]
    assert sorted(p.name for p in out.iterdir()) == [".lock", "manifest.json"]
    assert json.loads((out / "manifest.json").read_text()) == manifest


def test_a_failed_write_names_the_file_and_its_cause(tmp_path):
    """Arrow's write errors carry no file and no errno (only "[errno 28]" in their text), and
    Python's name the temporary file: write_atomic raises an OSError naming the file being
    written with the errno's own words (docs/scripts/write_faults.py found chunk writes named
    only by their folder)."""
    from mjx_balance.store.files import write_atomic

    def arrow_like(tmp):
        raise OSError("Error writing bytes to file. Detail: [errno 28] No space left on device")

    target = tmp_path / "chunk-00000.parquet"
    with pytest.raises(OSError) as caught:
        write_atomic(target, arrow_like)
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(target)
    assert caught.value.strerror == os.strerror(errno.ENOSPC)

    def refused(tmp):
        raise PermissionError(errno.EROFS, os.strerror(errno.EROFS), str(tmp))

    with pytest.raises(OSError) as caught:
        write_atomic(target, refused)
    assert caught.value.filename == str(target) and caught.value.errno == errno.EROFS
    assert not list(tmp_path.iterdir())  # no temporary file left


def test_a_copied_folder_cut_short_is_never_read_as_finished(tmp_path, monkeypatch):
    """The report copies a finished sweep or table made earlier in the same report
    (store.files.copy_folder); a disk filling half-way through a file's copy leaves every
    copied file whole, no temporary file and not the file that marks the folder finished
    (table.csv), so the next run copies again. shutil.copytree wrote each file in place and
    table.csv first: a half table.csv was the finished mark."""
    from mjx_balance.store.files import copy_folder

    source, target = tmp_path / "done", tmp_path / "copy"
    (source / "table_runs").mkdir(parents=True)
    files = {
        "table.csv": b"force\n1\n" * 200,
        "config.toml": b"x = 1\n" * 200,
        "table_runs/part-00000.parquet": b"p" * 5000,
        "manifest.json": b"{}" * 300,
    }
    for name, data in files.items():
        (source / name).write_bytes(data)
    (source / ".lock").write_text("held by another run\n")  # a record, not copied
    real, calls = shutil.copyfile, []

    def full_disk_on_the_third(src, dst, **kw):
        calls.append(src)
        if len(calls) == 3:
            Path(dst).write_bytes(Path(src).read_bytes()[:100])  # half, then the disk is full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))
        return real(src, dst, **kw)

    monkeypatch.setattr(shutil, "copyfile", full_disk_on_the_third)
    with pytest.raises(OSError) as caught:
        copy_folder(source, target, "table.csv")
    assert caught.value.errno == errno.ENOSPC and str(target) in caught.value.filename
    assert not (target / "table.csv").exists()
    kept = [p for p in target.rglob("*") if p.is_file()]
    assert len(kept) == 2 and all(p.read_bytes() == files[p.relative_to(target).as_posix()]
                                  for p in kept)  # fmt: skip
    monkeypatch.setattr(shutil, "copyfile", real)
    copy_folder(source, target, "table.csv")
    assert {p.relative_to(target).as_posix(): p.read_bytes()
            for p in target.rglob("*") if p.is_file()} == files  # fmt: skip


def test_a_completed_run_whose_manifest_cannot_be_written_fails(
    tmp_path, fake_rollout, capsys, monkeypatch
):
    """The run's last record (completed, its end) failing to be written is an error, one line
    naming manifest.json, exit 1 (it ended with exit 0 and a manifest saying 'running');
    after a failed run the same failure is not reported again over the first."""
    from mjx_balance.store import provenance

    real = provenance.write_text
    state = {"completed": 0}

    def full_at_the_end(text, path):
        if '"completed"' in text:
            state["completed"] += 1
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        real(text, path)

    monkeypatch.setattr(provenance, "write_text", full_at_the_end)
    out = tmp_path / "out"
    capsys.readouterr()
    assert cli_sweep(out) == 1 and state["completed"] == 1
    lines = error_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "manifest.json" in lines[0] and "No space left" in lines[0]
    monkeypatch.setattr(provenance, "write_text", real)
    assert cli_sweep(out) == 0  # the rerun completes and records it
    runs = json.loads((out / "manifest.json").read_text())["runs"]
    assert runs[-1]["status"] == "completed"
