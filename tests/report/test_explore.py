"""The explore page's server without a browser: what a folder holds (sweep, compare, cohort,
one being written), every endpoint's answers, the path rules (nothing served from outside
the folder), the checks of a cell's request, and a cell's run computed by the scalar
reference, kept in the folder and served from there the second time.

The folders are made on the stand-in rollout (tests/explore_folders.py: no engine is
compiled); one real run of the scalar reference (20 N for 0.1 s in a 1-s window, about a
second) is computed."""

from __future__ import annotations

import http.client
import json
import os
import shutil
import time

import pandas as pd
import pytest
import tomllib
from explore_folders import shaped_like, sweep_folder
from support import REPO

import mjx_balance as mb
from mjx_balance.model.params import ParameterError
from mjx_balance.report.explore import Explorer, folder as explore_folder, open_folder, runs
from mjx_balance.report.explore.server import HttpError, folder_file


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    return sweep_folder(tmp_path_factory.mktemp("explore") / "sweep")


@pytest.fixture(scope="module")
def secret(tmp_path_factory):
    """A file outside every explored folder."""
    path = tmp_path_factory.mktemp("outside") / "secret.txt"
    path.write_text("not to be served\n")
    return path


@pytest.fixture
def server(sweep, secret):
    (sweep / "escape.txt").unlink(missing_ok=True)
    (sweep / "escape.txt").symlink_to(secret)
    with Explorer(sweep) as running:
        yield running
    (sweep / "escape.txt").unlink()


def get(server: Explorer, path: str, *, method: str = "GET", host: str | None = None):
    """(status, JSON or bytes) of one request, the path sent exactly as written."""
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=120)
    conn.putrequest(method, path, skip_host=True)
    conn.putheader("Host", host or f"127.0.0.1:{server.port}")
    conn.endheaders()
    response = conn.getresponse()
    body = response.read()
    conn.close()
    if body and response.getheader("Content-Type", "").startswith("application/json"):
        return response.status, json.loads(body)
    return response.status, body


# -- what a folder holds -------------------------------------------------------------------------


def test_a_sweep_folder_is_one_map_with_its_table_and_boundary(sweep):
    folder = open_folder(sweep)
    assert folder.kind == "sweep" and [m.key for m in folder.maps] == [""]
    data = explore_folder.map_json(folder, folder.maps[0])
    assert (data["done"], data["total"], data["complete"]) == (15, 15, True)
    assert data["forces"] == [0.0, 10.0, 20.0, 30.0, 40.0]
    assert data["durations"] == [0.1, 0.5, 1.0] and data["t_end"] == 1.0
    # force-major: cell 3 * 3 + 1 is 30 N for 0.5 s; the stand-in recovers iff F T < 30 N s
    assert data["cells"]["outcome"][3 * 3 + 1] == "recovered"
    assert data["cells"]["outcome"][3 * 3 + 2] == "fell"
    assert data["counts"]["recovered"] + data["counts"]["fell"] == 15
    assert [p["force"] for p in data["table"]] == [20.0, 40.0]
    # the boundary's top at 40 N is the edge between 0.5 s (recovered) and 1 s (fell)
    assert data["boundary"] and data["boundary"][0][-1][1] == pytest.approx(0.75)
    assert "region.png" in data["files"]
    # capturability: one step saves 30 N for 1 s (F T = 30), not 40 N for 1 s (40 >= 35)
    need = data["cells"]["steps_needed"]
    assert need[3 * 3 + 2] == 1 and need[4 * 3 + 2] == explore_folder.NOT_WITHIN
    one, two = data["step_boundaries"]
    # at 30 N: the grid's top edge (1 s), where the boundary in place is at 0.75 s
    assert one[0][-3][1] == pytest.approx(1.0) and data["boundary"][0][-3][1] == pytest.approx(0.75)
    assert one[0][-1][1] == pytest.approx(0.75) and two == one  # at 40 N: as in place


def test_compare_and_cohort_folders_are_one_map_per_variant_or_subject(sweep, tmp_path):
    compare = open_folder(shaped_like("compare", sweep, tmp_path / "cmp", ["b", "a"]))
    assert compare.kind == "compare" and [m.key for m in compare.maps] == ["b", "a"]
    cohort = open_folder(shaped_like("cohort", sweep, tmp_path / "coh", ["s02", "s01"]))
    assert cohort.kind == "cohort"
    assert [m.key for m in cohort.maps] == ["subjects/s02", "subjects/s01"]
    answer = explore_folder.folder_json(cohort, explore_folder.MapCache())
    share = answer["probability"]
    assert share["subjects"] == 2 and set(share["share"]) == {0.0, 1.0}  # two equal maps
    assert all(m["boundary"] for m in answer["maps"])
    # the 95 % Wilson interval per cell (as cohort_probability.csv), the 95/50/5 % boundaries
    # (with two equal maps, each the maps' own) and no base boundary (no base/ folder)
    from mjx_balance.studies.probability import wilson

    for p, low, high in zip(share["share"], share["low"], share["high"]):
        assert (low, high) == tuple(float(v) for v in wilson(round(2 * p), 2))
    assert share["levels"] == {level: answer["maps"][0]["boundary"] for level in ("95", "50", "5")}
    assert share["base"] == []
    shutil.copytree(sweep, tmp_path / "coh" / "base", ignore=shutil.ignore_patterns(".lock"))
    based = explore_folder.folder_json(open_folder(tmp_path / "coh"), explore_folder.MapCache())
    assert based["probability"]["base"] == answer["maps"][0]["boundary"]


def test_a_folder_without_a_map_is_refused(tmp_path):
    with pytest.raises(ParameterError, match="holds no region map"):
        open_folder(tmp_path)
    with pytest.raises(ParameterError, match="is not a folder"):
        open_folder(tmp_path / "missing")


def test_a_folder_being_written_shows_what_is_there_and_refreshes(sweep, tmp_path):
    """A sweep under way has no region.parquet yet: its cells come from the chunks written so
    far, on the manifest's grid; the stamp changes when a chunk arrives."""
    live = tmp_path / "live"
    shutil.copytree(sweep, live, ignore=shutil.ignore_patterns(".lock"))
    (live / "region.parquet").unlink()
    last = sorted((live / "chunks").glob("chunk-*.parquet"))[-1]
    kept = last.read_bytes()
    last.unlink()
    folder = open_folder(live)
    cache = explore_folder.MapCache()
    first = explore_folder.folder_json(folder, cache)
    data = cache.get(folder, folder.maps[0])
    assert data["total"] == 15 and data["done"] == 12 and not data["complete"]
    assert data["cells"]["outcome"][-1] is None  # 40 N for 1 s: not computed yet
    assert len(data["boundary"][0]) == 8  # the forces whose every cell is there: 0-30 N
    time.sleep(0.01)
    last.write_bytes(kept)
    again = explore_folder.folder_json(folder, cache)
    assert again["stamp"] != first["stamp"] and again["maps"][0]["done"] == 15


# -- the server: endpoints, methods, hosts -------------------------------------------------------


def test_the_endpoints_answer_and_anything_else_is_refused(server):
    status, page = get(server, "/")
    assert status == 200 and b"/static/explore.js" in page
    assert get(server, "/static/explore.js")[0] == 200
    status, folder = get(server, "/api/folder")
    assert status == 200 and folder["kind"] == "sweep"
    assert get(server, f"/api/folder?stamp={folder['stamp']}")[1] == {
        "stamp": folder["stamp"],
        "unchanged": True,
    }
    assert get(server, "/api/map?map=")[1]["total"] == 15
    assert get(server, "/files/region.png")[0] == 200
    for path, status in (
        ("/api/nothing", 404),
        ("/static/server.py", 404),
        ("/static/..%2Fserver.py", 404),
        ("/files/chunks", 404),
    ):
        assert get(server, path)[0] == status, path
    for method in ("POST", "PUT", "DELETE", "HEAD", "OPTIONS"):
        status, _ = get(server, "/api/folder", method=method)
        assert status == 405, method
    status, body = get(server, "/api/folder", host="evil.example:80")
    assert status == 403 and "served as http://127.0.0.1" in body["error"]
    assert get(server, "/api/folder", host=f"localhost:{server.port}")[0] == 200


def test_every_refusal_is_one_short_json_answer(server, caplog):
    """Also the answers the standard library writes itself: a method it has no handler for
    (501 as HTML: 405 here, like any method but GET), a request line over 64 kB (414), and
    a query of more fields than the endpoints take (a 500 and an 8-kB log line: 400)."""
    for method in ("TRACE", "CONNECT", "BREW"):
        status, body = get(server, "/api/folder", method=method)
        assert status == 405 and "answers GET only" in body["error"], method
    status, body = get(server, "/api/map?" + "&".join(f"x{i}=1" for i in range(1000)))
    assert status == 400 and "too many query fields" in body["error"]
    status, body = get(server, "/api/map?map=" + "x" * 70_000)
    assert status == 414 and body["error"]
    with caplog.at_level("DEBUG", logger="mjx_balance"):
        get(server, "/api/run?map=&force=20&duration=0.1&" + "y" * 8000)
    assert all(len(r.getMessage()) < 600 for r in caplog.records)


@pytest.mark.parametrize(
    "path",
    [
        "../secret.txt",
        "..%2F..%2Fsecret.txt",
        "%2e%2e/%2e%2e/secret.txt",
        "chunks/../../x",
        ".lock",
        "chunks/%2E%2E/.lock",
        "a%00b",
        "..%5Csecret.txt",
        "%ff%fe",
        "",
    ],
)
def test_no_path_leads_outside_the_folder_or_to_a_hidden_file(server, path):
    status, body = get(server, "/files/" + path)
    assert status in (400, 403) and "error" in body


def test_a_symbolic_link_out_of_the_folder_is_refused(server, sweep, secret, tmp_path):
    status, body = get(server, "/files/escape.txt")
    assert status == 403 and "leads outside the folder" in body["error"]
    assert b"not to be served" not in json.dumps(body).encode()
    with pytest.raises(HttpError, match="outside"):
        folder_file(sweep.resolve(), "escape.txt")
    outside_dir = tmp_path / "dir"
    outside_dir.mkdir()
    (outside_dir / "x.png").write_bytes(b"png")
    (sweep / "linked").symlink_to(outside_dir)
    try:
        assert get(server, "/files/linked/x.png")[0] == 403
    finally:
        (sweep / "linked").unlink()


# -- a cell's request ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "query, words",
    [
        ("force=abc&duration=0.1", "force: 'abc' is not a number"),
        ("force=2_0&duration=0.1", "force: '2_0' is not a number"),  # float() reads 20
        ("force=%D9%A2%D9%A0&duration=0.1", "is not a number"),  # Arabic-Indic digits: 20
        ("force=nan&duration=0.1", "force: must be a finite number"),
        ("force=inf&duration=0.1", "force: must be a finite number"),
        ("force=20&force=30&duration=0.1", "force: give one value (got 2)"),
        ("duration=0.1", "force: give one value (got 0)"),
        ("force=20&duration=-0.1", "push durations must be >= 0"),
        ("force=20&duration=5", "must not exceed scenario.t_end = 1 s"),
        ("force=20&duration=0.101", "not a whole number of physics steps"),
        ("force=25&duration=0.1", "not a cell of this map"),
        ("force=40&duration=0.75", "not a cell of this map"),
    ],
)
def test_a_bad_cell_is_answered_with_its_message(server, query, words):
    status, body = get(server, "/api/run?map=&" + query)
    assert status == 400 and words in body["error"], body


def test_an_unknown_map_is_named(server):
    status, body = get(server, "/api/run?map=nope&force=20&duration=0.1")
    assert status == 400 and "no map 'nope'" in body["error"]


def test_a_cell_is_computed_once_kept_in_the_folder_and_served_from_it(server, sweep):
    path = sweep / "explore" / "20.0_0.1.parquet"
    path.unlink(missing_ok=True)
    started = time.perf_counter()
    status, run = get(server, "/api/run?map=&force=20&duration=0.1")
    first = time.perf_counter() - started
    assert status == 200 and not run["cached"] and run["note"] is None
    assert path.is_file() and run["file"].endswith(os.path.join("explore", "20.0_0.1.parquet"))
    kept = pd.read_parquet(path)
    assert kept.attrs["summary"]["outcome"] == run["summary"]["outcome"]
    assert kept.attrs["summary"]["force"] == 20.0 and kept["time"].iloc[-1] <= 1.0 + 1e-9
    assert {p["title"] for p in run["panels"]} >= {"Joint angles", "Margin of stability"}
    assert len(run["series"]["time"]) == len(run["series"]["mos"]) > 100
    assert "--pairs 20.0:0.1" in run["commands"]["simulate"]
    assert run["commands"]["view"].startswith("mjx-balance view --config ")
    started = time.perf_counter()
    status, again = get(server, "/api/run?map=&force=20.0&duration=0.10000000001")
    assert status == 200 and again["cached"] and again["summary"] == run["summary"]
    assert time.perf_counter() - started < first
    assert [20.0, 0.1] in get(server, "/api/map?map=")[1]["explored"]
    # another spelling of the cell's force is the same cell: served from the same file, no
    # file of its own (each spelling was a new run and a new file)
    for spelling in ("20.00000000001", "2e1", "19.99999999999"):
        status, again = get(server, f"/api/run?map=&force={spelling}&duration=0.1")
        assert status == 200 and again["cached"] and again["summary"]["force"] == 20.0
    assert sorted(p.name for p in path.parent.glob("20*")) == [path.name]


def test_a_table_point_opens_its_run_and_a_stale_run_is_computed_again(server, sweep):
    """The max acting time at 40 N (the stand-in: 0.74 s) is not a grid cell but a point the
    page shows; a kept run of another configuration is not served."""
    calls = []

    def stand_in(config, force, duration, record=True):
        calls.append((force, duration))
        frame = pd.read_parquet(sweep / "explore" / "20.0_0.1.parquet")
        summary = {**frame.attrs["summary"], "force": force, "duration": duration}
        frame.attrs = {}
        return summary, frame.assign(force=force, duration=duration)

    get(server, "/api/run?map=&force=20&duration=0.1")  # the real run is kept
    server.runs.simulate = stand_in
    status, run = get(server, "/api/run?map=&force=40&duration=0.74")
    assert status == 200 and calls == [(40.0, 0.74)] and not run["cached"]
    kept = sweep / "explore" / "40.0_0.74.parquet"
    frame = pd.read_parquet(kept)
    frame.attrs["config"]["scenario"]["t_end"] = 2.0  # as if the folder's configuration changed
    from mjx_balance.store.files import write_parquet

    write_parquet(frame, kept)
    get(server, "/api/run?map=&force=40.00000000001&duration=0.74")
    assert calls == [(40.0, 0.74)] * 2  # the table point's own values, not the spelling's
    assert not list(kept.parent.glob("40.00000000001*"))


def test_a_refused_write_still_answers_and_a_stopped_server_writes_nothing(sweep, monkeypatch):
    def refused(frame, path):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(runs, "write_parquet", refused)
    explorer = Explorer(sweep)
    explorer.runs.simulate = lambda config, f, d, record=True: (
        {"force": f, "duration": d, "outcome": "recovered"},
        pd.read_parquet(sweep / "explore" / "20.0_0.1.parquet").assign(force=f, duration=d),
    )
    found = explorer.folder.maps[0]
    config = explore_folder.map_config(found)
    frame, note = explorer.runs._compute(found, config, 30.0, 0.5)
    kept = sweep / "explore" / "30.0_0.5.parquet"
    assert note == f"not kept in the folder: Permission denied ({kept})" and len(frame)
    explorer.stop()
    monkeypatch.undo()
    frame, note = explorer.runs._compute(found, config, 30.0, 0.5)
    assert "not kept" in note and not (sweep / "explore" / "30.0_0.5.parquet").exists()
    assert not list((sweep / "explore").glob(".*.tmp"))


def test_the_api_serves_in_the_background_until_stopped(sweep):
    explorer = mb.explore(sweep)
    try:
        assert explorer.url.startswith("http://127.0.0.1:") and explorer.thread.is_alive()
        assert get(explorer, "/api/folder")[0] == 200
        assert str(sweep) in explorer._repr_html_()
    finally:
        explorer.stop()
    assert explorer.thread is None
    with pytest.raises(ParameterError, match="port"):
        mb.explore(sweep, port=70000)


def test_a_signal_during_a_run_stops_the_server_once_the_run_has_ended(sweep):
    """SIGTERM while a clicked cell's run computes: the run ends at its next checkpoint, its
    client gets 503, and the server returns only after that (the process then exits; were
    the request's thread still inside MuJoCo's C++ code, the exit would abort with 134). The
    stand-in run spends 0.3 s between checkpoints, as a long call into C would."""
    import signal
    import threading

    from mjx_balance.runtime import signals

    (sweep / "explore" / "20.0_0.1.parquet").unlink(missing_ok=True)
    started, events, answers = threading.Event(), [], []

    def stand_in(config, force, duration, record=True):
        started.set()
        try:
            for _ in range(100):
                time.sleep(0.3)
                signals.check()
        finally:
            events.append("run ended")

    def click():
        answers.append(get(explorer, "/api/run?map=&force=20&duration=0.1")[0])

    def signal_once_the_run_started():
        if started.wait(30):
            os.kill(os.getpid(), signal.SIGTERM)

    explorer = Explorer(sweep)
    explorer.runs.simulate = stand_in
    watchdog = threading.Timer(60, explorer.server.shutdown)  # the test ends either way
    watchdog.start()
    client = threading.Thread(target=click)
    client.start()
    threading.Thread(target=signal_once_the_run_started).start()
    try:
        with pytest.raises(signals.Terminated):
            with signals.honoured():
                explorer.serve_forever()
        events.append("server returned")
    finally:
        watchdog.cancel()
        explorer.stop()
    client.join(30)
    assert events == ["run ended", "server returned"] and answers == [503]
    assert not (sweep / "explore" / "20.0_0.1.parquet").exists()


def test_runs_of_different_cells_are_computed_side_by_side(server, sweep, monkeypatch):
    """Up to RUN_SLOTS cells' runs at once (a click waited for every run before it: the last
    of 16 clicks 46 s); two clicks on one cell compute it once."""
    import threading

    get(server, "/api/run?map=&force=20&duration=0.1")  # a real run, kept: the stand-in's
    frame = pd.read_parquet(sweep / "explore" / "20.0_0.1.parquet")
    summary, frame.attrs = frame.attrs["summary"], {}
    for kept in (sweep / "explore").glob("*.parquet"):
        kept.unlink()
    monkeypatch.setattr(server.runs, "slots", threading.BoundedSemaphore(2))
    calls, running, most = [], [0], [0]
    lock = threading.Lock()

    def stand_in(config, force, duration, record=True):
        with lock:
            calls.append((force, duration))
            running[0] += 1
            most[0] = max(most[0], running[0])
        time.sleep(0.5)
        with lock:
            running[0] -= 1
        return {**summary, "force": force, "duration": duration}, frame.assign(force=force)

    monkeypatch.setattr(server.runs, "simulate", stand_in)
    cells = ["force=0&duration=0.1", "force=20&duration=0.1", "force=20&duration=0.1"]
    answers = []
    clicks = [
        threading.Thread(target=lambda c=c: answers.append(get(server, f"/api/run?map=&{c}")[0]))
        for c in cells
    ]
    for click in clicks:
        click.start()
    for click in clicks:
        click.join(60)
    assert answers == [200] * 3 and sorted(calls) == [(0.0, 0.1), (20.0, 0.1)] and most[0] == 2


def test_the_page_ships_as_package_data():
    """Every file of the page matches a package-data glob of pyproject.toml (so the wheel and
    `pip install .` carry it; tests/package/test_packaging.py builds them)."""
    import fnmatch

    globs = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"
    ]["mjx_balance"]
    static = REPO / "src" / "mjx_balance" / "report" / "explore" / "static"
    names = sorted(p.relative_to(static.parents[2]).as_posix() for p in static.iterdir())
    assert names == [
        "report/explore/static/explore.css",
        "report/explore/static/explore.js",
        "report/explore/static/index.html",
    ]
    assert all(any(fnmatch.fnmatch(n, g) for g in globs) for n in names), (names, globs)


def test_the_browser_is_opened_only_where_a_window_can_open(sweep, monkeypatch):
    """On Linux without DISPLAY or WAYLAND_DISPLAY, webbrowser would start a text browser in
    the terminal the server prints to: the address is printed instead."""
    import sys
    import webbrowser

    opened = []
    monkeypatch.setattr(webbrowser, "open", lambda url: opened.append(url))
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    mb.explore(sweep, browser=True).stop()
    assert opened == []
    monkeypatch.setenv("DISPLAY", ":0")
    explorer = mb.explore(sweep, browser=True)
    explorer.stop()
    assert opened == [explorer.url]


KILLED_WRITER = """
import os, signal, sys
from pathlib import Path
import pandas as pd
from mjx_balance.report.explore import Explorer, runs
from mjx_balance.store.files import write_atomic

def half_then_killed(frame, path):  # the kept run's atomic write, killed half-way
    def write(tmp):
        Path(tmp).write_bytes(b"PAR1" + b"half a parquet file")
        os.kill(os.getpid(), signal.SIGKILL)
    write_atomic(path, write)

runs.write_parquet = half_then_killed
explorer = Explorer(Path(sys.argv[1]))
frame = pd.read_parquet(Path(sys.argv[1]) / "explore" / "20.0_0.1.parquet")
explorer.runs.simulate = lambda config, f, d, record=True: (
    {**frame.attrs["summary"], "force": f, "duration": d}, frame.assign(force=f, duration=d)
)
explorer.run_json({"map": [""], "force": ["30"], "duration": ["0.5"]})
"""


def test_a_server_killed_while_keeping_a_run_serves_no_half_file(server, sweep, tmp_path):
    """SIGKILL in the middle of writing a cell's kept run: the run's file is
    written beside its name and renamed whole, so the kill leaves only a hidden temporary file:
    the next server computes the cell again, never reads or serves the half file (/files/
    refuses hidden names), and keeps the run whole."""
    import signal
    import subprocess
    import sys

    get(server, "/api/run?map=&force=20&duration=0.1")  # the real run, kept (the stand-in's)
    folder = tmp_path / "killed"
    shutil.copytree(sweep, folder, ignore=shutil.ignore_patterns(".lock", "escape.txt"))
    proc = subprocess.run(
        [sys.executable, "-c", KILLED_WRITER, str(folder)], capture_output=True, text=True
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    kept = folder / "explore" / "30.0_0.5.parquet"
    left = list(kept.parent.glob(".30.0_0.5.parquet.*.tmp"))
    assert not kept.exists() and len(left) == 1 and left[0].read_bytes().startswith(b"PAR1half")
    with Explorer(folder) as again:
        status, _ = get(again, f"/files/explore/{left[0].name}")
        assert status == 403  # a hidden name is never served
        calls = []
        frame = pd.read_parquet(folder / "explore" / "20.0_0.1.parquet")

        def stand_in(config, force, duration, record=True):
            calls.append((force, duration))
            return {**frame.attrs["summary"], "force": force, "duration": duration}, frame.assign(
                force=force, duration=duration
            )

        again.runs.simulate = stand_in
        status, run = get(again, "/api/run?map=&force=30&duration=0.5")
        assert status == 200 and not run["cached"] and calls == [(30.0, 0.5)]
    assert pd.read_parquet(kept).attrs["summary"]["force"] == 30.0  # whole, read back


def test_a_click_runs_the_folders_own_controller(tmp_path):
    """A map of another controller (docs/model.md, "Bring your own controller") opens its
    cells with that controller: the run is the scalar reference of the folder's configuration,
    here the LQR's, not the MPC's."""
    from explore_folders import T_END
    from support import DEFAULT_BATCH, FakeThresholdBatch, cli_sweep

    from mjx_balance.reference import loop as reference

    folder = tmp_path / "lqr"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(DEFAULT_BATCH, lambda config, **_: FakeThresholdBatch())
        assert cli_sweep(folder, "-q", *T_END, "--controller", "lqr") == 0
    config = mb.load_config(folder / "config.toml")
    assert config.controller.kind == "lqr"
    with Explorer(folder) as server:
        status, run = get(server, "/api/run?map=&force=30&duration=0.1")
    assert status == 200
    lqr = reference.simulate_scenario(config, 30.0, 0.1, record=False)[0]
    mpc = reference.simulate_scenario(config.replace(controller={"kind": "mpc"}), 30.0, 0.1)[0]
    assert lqr["energy_total"] != mpc["energy_total"]  # the two controllers' runs differ
    assert run["summary"]["energy_total"] == lqr["energy_total"]
