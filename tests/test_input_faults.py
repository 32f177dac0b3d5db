"""Issue 11, the leftover items: nonsense is refused, work is never lost.

1. ``simulate`` and ``animate`` refuse push durations that are not whole physics steps (the
   message of ``sweep.grid.check_whole_steps``); ``simulate`` reads grids as ``sweep`` does.
2. ``simulate --out`` into a sweep folder is refused (its config.toml is left alone).
3. ``simulate``, ``animate`` and ``report`` write their files atomically: a write that fails
   half-way leaves the old file (or none), never a truncated one.
4. ``sweep --wait`` (and ``table --wait``) waits for the run that holds the folder.
5. The batched MJX path calls a push that sends MuJoCo beyond its bound (mjMAXVAL, which the
   scalar reference sees as a "huge value" warning) ``diverged``, as the reference does.

Apart from 5 (one small compile), nothing here runs a long simulation: the simulations are
replaced by stand-ins that record what they were asked, or last 0.1-0.2 s.
"""

from __future__ import annotations

import errno
import subprocess
import sys
import threading
import time
from pathlib import Path

import jax
import numpy as np
import pytest

from mjx_balance import cli
from mjx_balance.cli.main import build_parser
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.runs.grid import check_whole_steps

from test_bad_input import assert_refused, run
from test_store_faults import HOLD_LOCK, cli_sweep, fake_rollout  # noqa: F401 (a fixture)
from support import ENGINE_SLOTS


PHYSICS_DT = Config().scenario.physics_dt


class Called(Exception):
    """Raised by a stand-in simulation: the command got as far as simulating."""


def whole_steps_message(duration: float, name: str = "--duration") -> str:
    with pytest.raises(ParameterError) as exc:
        check_whole_steps([duration], PHYSICS_DT, name)
    return str(exc.value)


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


# --- item 1: durations of whole physics steps; simulate reads grids as sweep does -------------


@pytest.mark.parametrize("name", ["simulate", "animate"])
def test_durations_off_the_physics_steps_are_refused(tmp_path, capsys, monkeypatch, name):
    def refuse(*args, **kwargs):
        raise Called
    monkeypatch.setattr("mjx_balance.reference.loop.simulate_many", refuse)
    monkeypatch.setattr("mjx_balance.reference.loop.simulate_scenario", refuse)
    out = tmp_path / ("push.gif" if name == "animate" else "out")
    # simulate takes lists (--forces, --durations), animate one push (--force, --duration)
    force, duration = ("--force", "--duration") if name == "animate" else ("--forces",
                                                                           "--durations")
    code, err = run([name, force, "10", duration, "0.1005", "--out", str(out)], capsys)
    assert_refused(code, err, whole_steps_message(0.1005, duration))
    assert list(tmp_path.iterdir()) == []

    # Float error is not an offence: the value is snapped to its whole steps.
    with pytest.raises(Called):
        cli.main([name, force, "10", duration, "0.10000000001", "--out", str(out)])


def test_simulate_reads_forces_and_durations_as_sweep_does(tmp_path, capsys, monkeypatch):
    asked = {}

    def record(config, pairs, **_options):  # the cross product, every force per duration
        asked.update(forces=list(dict.fromkeys(f for f, _ in pairs)),
                     durations=list(dict.fromkeys(d for _, d in pairs)))
        raise Called
    monkeypatch.setattr("mjx_balance.reference.loop.simulate_pairs", record)
    with pytest.raises(Called):
        cli.main(["simulate", "--forces", "0:40:20", "--durations", "0.05:0.1:0.05",
                  "--out", str(tmp_path / "out")])
    assert asked == {"forces": [0.0, 20.0, 40.0], "durations": [0.05, 0.1]}
    with pytest.raises(Called):
        cli.main(["simulate", "--forces=-20,10", "--durations", "0,0.1",
                  "--out", str(tmp_path / "out")])
    assert asked == {"forces": [-20.0, 10.0], "durations": [0.0, 0.1]}
    for bad, words in [("0:1:0", ["--durations", "step must be > 0"]),
                       ("0.1,0.1", ["--durations", "more than once"]),
                       ("0:0.101:0.0505", ["--durations", "not a whole number of physics steps"])]:
        code, err = run(["simulate", "--durations", bad, "--out", str(tmp_path / "bad")], capsys)
        assert_refused(code, err, *words)
        assert not (tmp_path / "bad").exists()


# --- item 2: simulate does not write into a sweep folder --------------------------------------


@pytest.mark.parametrize("holds", [["manifest.json", "config.toml"], ["config.toml", "chunks/"],
                                   ["config.toml", "region.parquet"],
                                   ["config.toml", "report.json"]])
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
    code, err = run(["simulate", "--forces", "10", "--out", str(out)], capsys)
    assert_refused(code, err, str(out), "sweep")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in out.iterdir()) == sorted(n.rstrip("/") for n in holds)


# --- item 3: atomic outputs -------------------------------------------------------------------


def test_outputs_are_whole_or_old_after_a_failed_write(tmp_path, capsys, monkeypatch):
    import matplotlib.figure
    import pandas as pd
    import pyarrow.parquet as pq
    from PIL import Image

    from mjx_balance.report import html
    from mjx_balance.studies import experiments as report_run

    # simulate: a first run, then reruns in which one kind of write fails half-way.
    out = tmp_path / "sim"
    argv = ["simulate", "--forces", "10", "--durations", "0.1", "--config",
            str(short_config(tmp_path)), "--out", str(out)]
    assert cli.main(argv) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {"summary.csv", "timeseries.parquet", "config.toml", "energy.png"} <= set(before)
    failing = [  # summary.csv, timeseries.parquet, config.toml, the figures
        (pd.DataFrame, "to_csv", lambda self, path, **kw: half_then_fail(
            lambda p: open(p, "w").write("force,dura"))(path)),
        # parquet files are written by pyarrow (store.files.write_parquet: units in the schema)
        (pq, "write_table", lambda table, path, **kw: half_then_fail(
            lambda p: open(p, "wb").write(b"PAR1\x00"))(path)),
        (Path, "write_text", lambda self, text, **kw: half_then_fail(
            lambda p: open(p, "w").write(text[:10]))(self)),
        (matplotlib.figure.Figure, "savefig", lambda self, path, **kw: half_then_fail(
            lambda p: open(p, "wb").write(b"\x89PNG\r\n"))(path)),
    ]
    for owner, name, fail in failing:
        with monkeypatch.context() as m:
            m.setattr(owner, name, fail)
            code, err = run(argv, capsys)
        assert code == 1 and "No space left" in err and "Traceback" not in err, name
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before, name
        assert leftovers(tmp_path) == [], name

    # animate: the GIF is written whole or the old one stays.
    gif = tmp_path / "push.gif"
    gif.write_bytes(b"an older GIF")
    with monkeypatch.context() as m:
        m.setattr(Image.Image, "save", lambda self, fp, *a, **kw: half_then_fail(
            lambda p: Path(p).write_bytes(b"GIF89a"))(fp))
        code, err = run(["animate", "--force", "10", "--t-end", "0.1", "--fps", "50",
                         "--out", str(gif)], capsys)
        assert code == 1 and "Traceback" not in err
    assert gif.read_bytes() == b"an older GIF"
    assert leftovers(tmp_path) == []
    code, _ = run(["animate", "--force", "10", "--t-end", "0.1", "--fps", "50",
                   "--out", str(gif)], capsys)
    assert code == 0
    with Image.open(gif) as image:
        assert image.format == "GIF" and image.n_frames == 6

    # report: report.html, its figures and its tables.
    rep = tmp_path / "report"
    rep.mkdir()
    monkeypatch.setattr(html, "load_results", lambda out: {"conventions": {}, "studies": {},
                                                          "record": {}, "config": None})
    monkeypatch.setattr(html, "sections", lambda out: [])
    monkeypatch.setattr(html, "overview_section", lambda page: {
        "id": "overview", "heading": "overview", "blocks": []})
    monkeypatch.setattr(html, "banner", lambda record, config: None)
    page = html.build_report(rep)
    assert "overview" in page.read_text()
    (rep / "figures" / "f.png").write_bytes(b"old figure")
    report_run.write_csv(pd.DataFrame({"a": [1]}), rep / "numbers.csv")
    report_run.write_json(rep / "report.json", {"a": 1})
    before = {p.relative_to(rep): p.read_bytes() for p in rep.rglob("*") if p.is_file()}
    with monkeypatch.context() as m:
        m.setattr(Path, "write_text", lambda self, text, **kw: half_then_fail(
            lambda p: p.write_bytes(text[:10].encode()))(self))
        m.setattr(pd.DataFrame, "to_csv", lambda self, path, **kw: half_then_fail(
            lambda p: open(p, "w").write("a,"))(path))
        m.setattr(matplotlib.figure.Figure, "savefig", lambda self, path, **kw: half_then_fail(
            lambda p: open(p, "wb").write(b"\x89PNG"))(path))
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


# --- item 4: --wait --------------------------------------------------------------------------


def test_wait_for_the_run_that_holds_the_folder(tmp_path, fake_rollout, capsys):  # noqa: F811
    assert build_parser().parse_args(["table", "--wait", "--out", "x"]).wait is True
    assert build_parser().parse_args(["sweep", "--out", "x"]).wait is False
    out = tmp_path / "shared"
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(out)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
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
        f"waiting for {out}: in use by another run (PID {holder.pid}, started "), waiting
    assert (out / "region.parquet").exists()


# --- item 5: huge values diverge the batched path ---------------------------------------------


def test_batched_path_calls_huge_values_diverged():
    from mjx_balance.measures.outcomes import OUTCOMES
    from mjx_balance.reference.loop import simulate_scenario
    from mjx_balance.rollout import BatchRunner

    # a 1-s window: the engine's calls run 100 periods, as for every test of conftest's
    # ENGINE_SLOTS (one compiled engine); 50 N x 0.1 s has not settled by then (~1.2 s)
    config = Config().replace(scenario={"t_end": 1.0})
    with jax.enable_x64(False):
        result = BatchRunner(config, slots=ENGINE_SLOTS, devices=jax.local_devices()[:1]).run(
            np.array([1e12, 50.0]), np.array([0.1, 0.1]))
    outcomes = [OUTCOMES[int(code)] for code in result["outcome"]]
    reference, _ = simulate_scenario(config, 1e12, 0.1, record=False)
    assert reference["outcome"] == "diverged"
    assert outcomes == ["diverged", "not_settled"], result
    assert np.isnan(result["fall_time"][0])
