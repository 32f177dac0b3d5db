"""The table resumes and a bad manifest is refused in one message.

Every scenario the table evaluates is kept in ``DIR/table_runs/`` as its batch call returns:
a table interrupted (an exception on the k-th call, a real SIGKILL) runs only the cells it had
not kept and writes a table.csv and table_runs.parquet byte-identical to an uninterrupted run's;
a table over an overlapping force list reuses the cells it shares. The rollout is replaced by
FakeThresholdBatch (tests/support.py), which records the cells of every call.
"""

from __future__ import annotations

import fcntl
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import jax
import pytest
from support import REPO, FakeThresholdBatch, held_table, sweep_fake

from mjx_balance import runs as sweep
from mjx_balance.store import files as store_files
from mjx_balance.store.folder import TableCells
from mjx_balance.model.params import Config, ParameterError

FORCES = "0:120:10"  # 13 forces
BATCH = 16  # every call has exactly this many scenarios


def table(out: Path, fake, forces: str = FORCES):
    return held_table(out, Config(), forces, run_batch=fake, batch=BATCH, progress=False, say=None)


def same_files(a: Path, b: Path) -> None:
    for name in (store_files.TABLE, store_files.TABLE_RUNS):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """An uninterrupted table and the cells it ran."""
    out = tmp_path_factory.mktemp("whole")
    fake = FakeThresholdBatch()
    table(out, fake)
    return out, fake


@pytest.mark.parametrize("k", [9, 11])  # the coarse scan is calls 1-8 (13 forces x 9 durations)
def test_table_interrupted_after_its_coarse_scan_resumes(tmp_path, whole, k):
    whole_out, whole_fake = whole
    assert len(whole_fake.calls) > k
    cut = FakeThresholdBatch(fail_on_call=k)
    with pytest.raises(KeyboardInterrupt):
        table(tmp_path, cut)
    assert not (tmp_path / store_files.TABLE).exists()
    assert len(list((tmp_path / store_files.TABLE_CELLS).glob("part-*.parquet"))) == k - 1
    kept = cut.all_cells()
    resumed = FakeThresholdBatch()
    table(tmp_path, resumed)
    assert set(resumed.calls) == {BATCH}  # the fixed padded size
    assert not resumed.all_cells() & kept  # nothing kept is run again
    assert resumed.all_cells() | kept == whole_fake.all_cells()
    same_files(tmp_path, whole_out)


KILLED_TABLE = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    sys.path.insert(0, sys.argv[1])
    from support import FakeThresholdBatch, held_table
    from mjx_balance.model.params import Config

    log = Path(sys.argv[3])

    class Slow(FakeThresholdBatch):
        def __call__(self, forces, durations):
            time.sleep(0.1)
            with open(log, "a") as fh:
                fh.write(f"{len(forces)}\\n")
            return super().__call__(forces, durations)

    held_table(sys.argv[2], Config(), sys.argv[4], run_batch=Slow(), batch=int(sys.argv[5]),
                    progress=False, say=None)
""")


def test_table_killed_by_sigkill_resumes(tmp_path, whole):
    whole_out, whole_fake = whole
    out, calls = tmp_path / "out", tmp_path / "calls.log"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            KILLED_TABLE,
            str(REPO / "tests"),
            str(out),
            str(calls),
            FORCES,
            str(BATCH),
        ]
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if calls.exists() and len(calls.read_text().splitlines()) >= 10:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the table ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    assert not (out / store_files.TABLE).exists()
    kept = TableCells(out, "paper").rows
    assert len(kept) >= 13 * sweep.coarse_steps(12.0, 0.01).size  # the coarse scan at least
    (out / store_files.TABLE_CELLS / ".part-00099.parquet.x.tmp").write_text("left by a kill")
    resumed = FakeThresholdBatch()
    with jax.enable_x64(False):  # the numerics the killed process ran under (its default)
        table(out, resumed)
    assert set(resumed.calls) == {BATCH}
    assert len(resumed.calls) < len(whole_fake.calls)
    assert not {(round(f, 6), round(d, 6)) for f, d in kept} & resumed.all_cells()
    same_files(out, whole_out)
    assert not list((out / store_files.TABLE_CELLS).glob(".*.tmp"))


def test_overlapping_force_list_reuses_the_cells(tmp_path):
    """Bisection (no fixed batch): a force's cells do not depend on the other forces, so a
    table over more forces runs only the new force's cells."""

    def bisect(out, fake, forces):
        held_table(out, Config(), forces, run_batch=fake, progress=False, say=None)

    fresh = tmp_path / "fresh"
    bisect(fresh, FakeThresholdBatch(), "20,50,80")
    out = tmp_path / "out"
    bisect(out, FakeThresholdBatch(), "20,50")
    second = FakeThresholdBatch()
    bisect(out, second, "20,50,80")
    assert second.calls and {f for f, _d in second.all_cells()} == {80.0}
    same_files(out, fresh)
    third = FakeThresholdBatch()
    bisect(out, third, "50")  # every cell of 50 N is kept: no call at all
    assert third.calls == []


def test_overlapping_force_list_in_fixed_batches_reuses_the_coarse_scan(tmp_path):
    """In batches of a fixed size the points per round depend on the force count, so only the
    coarse scan is sure to be shared; what is shared is not run again."""
    fresh = tmp_path / "fresh"
    table(fresh, FakeThresholdBatch(), "20,50,80")
    out = tmp_path / "out"
    first = FakeThresholdBatch()
    table(out, first, "20,50")
    second = FakeThresholdBatch()
    table(out, second, "20,50,80")
    assert set(second.calls) == {BATCH}
    assert not first.all_cells() & second.all_cells()
    coarse = {(20.0, round(s * 0.01, 6)) for s in sweep.coarse_steps(12.0, 0.01)}
    assert coarse <= first.all_cells()
    same_files(out, fresh)


def test_damaged_part_file_is_run_again(tmp_path, whole):
    whole_out, _ = whole
    table(tmp_path, FakeThresholdBatch())
    part = sorted((tmp_path / store_files.TABLE_CELLS).glob("part-*.parquet"))[3]
    part.write_bytes(part.read_bytes()[:100])
    (tmp_path / store_files.TABLE).unlink()
    again = FakeThresholdBatch()
    table(tmp_path, again)
    assert again.calls == [BATCH]  # only the damaged call's cells
    same_files(tmp_path, whole_out)


def test_run_table_holds_the_folder_lock(tmp_path):
    seen = []

    class Probe(FakeThresholdBatch):
        def __call__(self, forces, durations):
            fd = os.open(tmp_path / ".lock", os.O_RDWR)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                seen.append("free")
            except BlockingIOError:
                seen.append("held")
            finally:
                os.close(fd)
            return super().__call__(forces, durations)

    held_table(tmp_path, Config(), "20", run_batch=Probe(), progress=False, say=None)
    assert seen and set(seen) == {"held"}


def no_run(forces, durations):
    raise AssertionError("a refused folder must run nothing")


# --- the manifest ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, problem",
    [
        ("[1, 2]", "a JSON list, not an object"),
        ('{"config": {}, "region": {"forces": [0], "durations": [1]}}', "lacks 'chunk_size'"),
        ('{"config": {}, "region": [1]}', "'region' is not an object"),
        ('{"config": {}, "table": {}}', "'table' lacks 'forces'"),
        ('{"config": {}, "table": {"forces": "1,2"}}', "'table.forces' is not a list of numbers"),
        ('{"config": [], "table": {"forces": [1]}}', "'config' is not an object"),
        (
            '{"config": {}, "region": {"forces": [0], "durations": [1], "chunk_size": 0}}',
            "'region.chunk_size' is not a whole number",
        ),
    ],
)
@pytest.mark.parametrize("run", ["table", "sweep"])
def test_bad_manifest_is_one_clear_error(tmp_path, text, problem, run):
    (tmp_path / store_files.MANIFEST).write_text(text)
    with pytest.raises(ParameterError) as error:
        if run == "table":
            held_table(tmp_path, Config(), "20", run_batch=no_run, progress=False, say=None)
        else:
            sweep_fake(tmp_path, no_run)
    message = str(error.value)
    assert str(tmp_path / store_files.MANIFEST) in message and problem in message
    assert "\n" not in message


def test_rebuilt_manifest_keeps_the_table(tmp_path, capsys):
    table(tmp_path, FakeThresholdBatch(), "20,50")
    before = json.loads((tmp_path / store_files.MANIFEST).read_text())
    (tmp_path / store_files.MANIFEST).unlink()
    idle = FakeThresholdBatch(fail_on_call=1)
    assert (
        held_table(tmp_path, Config(), "20,50", run_batch=idle, batch=BATCH, progress=False) is None
    )
    assert idle.calls == []
    assert "nothing to do" in capsys.readouterr().out
    after = json.loads((tmp_path / store_files.MANIFEST).read_text())
    assert after["table"]["forces"] == before["table"]["forces"] == [20.0, 50.0]
    assert after["config"] == before["config"]


def test_rebuilt_manifest_without_a_table_resumes_from_the_kept_cells(tmp_path, whole):
    whole_out, _ = whole
    with pytest.raises(KeyboardInterrupt):
        table(tmp_path, FakeThresholdBatch(fail_on_call=10))
    (tmp_path / store_files.MANIFEST).unlink()
    resumed = FakeThresholdBatch()
    table(tmp_path, resumed)
    assert len(resumed.calls) == len(whole[1].calls) - 9  # the 9 kept calls are not rerun
    assert "table" in json.loads((tmp_path / store_files.MANIFEST).read_text())
    same_files(tmp_path, whole_out)


def test_lost_manifest_with_kept_cells_of_another_configuration_is_refused(tmp_path):
    """Cells kept in table_runs/ (no table yet, no manifest) are results: they are reused only
    when config.toml matches this run's configuration."""
    with pytest.raises(KeyboardInterrupt):
        table(tmp_path, FakeThresholdBatch(fail_on_call=3))
    (tmp_path / store_files.MANIFEST).unlink()
    other = Config().replace(scenario={"t_end": 6.0})
    with pytest.raises(ParameterError, match="config.toml differs"):
        held_table(tmp_path, other, FORCES, run_batch=no_run, progress=False, say=None)
