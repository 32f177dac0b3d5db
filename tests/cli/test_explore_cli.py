"""``mjx-balance explore DIR``: bad input in one line with exit code 2 before anything is
served, the address printed, Ctrl-C ends it with exit code 130 and one line, no traceback,
nothing left half-written in the folder."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import pytest
from explore_folders import sweep_folder
from support import TESTS, assert_refused, run_cli


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    return sweep_folder(tmp_path_factory.mktemp("explore") / "sweep")


def test_a_missing_folder_or_one_without_a_map_is_refused(tmp_path, capsys):
    code, err = run_cli(["explore", str(tmp_path / "missing")], capsys)
    assert_refused(code, err, "DIR", "is not a folder")
    code, err = run_cli(["explore", str(tmp_path), "--no-browser"], capsys)
    assert_refused(code, err, "holds no region map")


@pytest.mark.parametrize(
    "port, words",
    [
        ("70000", "must be in [0, 65535]"),
        ("-1", "must be in [0, 65535]"),
        ("http", "is not a whole number"),
    ],
)
def test_a_bad_port_is_refused(sweep, capsys, port, words):
    code, err = run_cli(["explore", str(sweep), "--port", port, "--no-browser"], capsys)
    assert_refused(code, err, "--port", words)


def test_a_port_in_use_is_refused_in_one_line(sweep, capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code, err = run_cli(["explore", str(sweep), "--port", str(port), "--no-browser"], capsys)
    assert_refused(code, err, f"port {port}", "leave the port out for a free one")


def test_ctrl_c_stops_the_server_with_exit_130_and_nothing_half_written(sweep):
    env = {**os.environ, "PYTHONPATH": str(TESTS)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjx_balance", "explore", str(sweep), "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        line = proc.stdout.readline()  # the address, once the port is bound
        url = re.search(r"http://127\.0\.0\.1:\d+/", line)
        assert url, line
        with urllib.request.urlopen(url.group(0) + "api/folder", timeout=60) as answer:
            assert json.loads(answer.read())["kind"] == "sweep"
        time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "Traceback" not in out
    assert "explore: stopped" in out
    assert not list(sweep.rglob("*.tmp"))
