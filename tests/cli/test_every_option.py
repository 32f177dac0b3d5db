"""Every option of every command that runs work, given each of a set of hostile values, holds
the command line's contract: refused with exit 2 and one error line naming the option (after
argparse's usage lines, when argparse refuses it), no traceback, nothing written; or taken as
a value the command means to accept (:data:`ACCEPTED`, each with its reason), in which case
the command reaches its work with nothing written before it.

The test is generated from the parser itself: an option added later is tried too, and one
that takes a hostile value without a check fails here until it refuses it (or is listed in
ACCEPTED, with a reason). The work itself is replaced by a stand-in that stops the command
where it would take its folder's lock or run its first push, so the whole matrix runs in
seconds. Not covered: ``bench`` (benchmarks, every option a typed count) and ``view`` (opens
a window); options with fixed choices (argparse checks them)."""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import shutil
import sys
from pathlib import Path

import pytest

from mjx_balance import api
from mjx_balance.cli import main
from mjx_balance.cli.main import build_parser
from mjx_balance.reference import loop
from mjx_balance.store import folder as store_folder

# A valid, small form of each command: the option under test replaces its value or is added.
BASE = {
    "simulate": ["simulate", "--forces", "10", "--durations", "0.1"],
    "sweep": ["sweep", "--forces", "10", "--durations", "0.1"],
    "table": ["table", "--forces", "10"],
    "compare": ["compare", "{tmp}/a.toml", "{tmp}/b.toml", "--forces", "10", "--durations", "0.1"],
    "cohort": [
        "cohort",
        "--heights",
        "1.7",
        "--masses",
        "70",
        "--forces",
        "10",
        "--durations",
        "0.1",
    ],
    "landscape": [
        "landscape",
        "--q-scales",
        "1",
        "--r-scales",
        "1",
        "--delays",
        "0",
        "--forces",
        "10",
        "--durations",
        "0.1",
    ],
    "basin": ["basin", "--x-com", "0", "--v-com", "0", "--push-forces", "none"],
    "sensitivity": ["sensitivity", "--forces", "10"],
    "lean": ["lean"],
    "people": ["people"],
    "pull": ["pull"],
    "animate": ["animate", "--force", "10"],
    "report": ["report", "--scale", "tiny"],
    "model": ["model"],
}
OUT_FILE = {"animate": "x.gif", "model": "x.xml"}  # commands whose --out is a file
NUMBERS = ["", "nan", "inf", "-1", "0", "1e308", "abc"]
PATHS = ["file", "dir", "missing", "under-a-file"]

# Hostile-looking values that are meant: (command or "*", option) -> values, with the reason.
ACCEPTED = {
    # --out names a folder to make: any name is one, an existing or a missing folder too
    ("*", "--out"): {"nan", "inf", "-1", "0", "1e308", "abc", "dir", "missing"},
    # a file --out (an MJCF) may replace a file
    ("model", "--out"): {"nan", "inf", "-1", "0", "1e308", "abc", "file", "missing"},
    # a force of 0 is no push and a negative force a pull (the backward study)
    ("*", "--forces"): {"0", "-1"},
    ("*", "--force"): {"0", "-1"},
    ("*", "--table-forces"): {"0", "-1"},
    ("basin", "--v-com"): {"0", "-1"},  # at rest, and moving backward
    ("basin", "--x-com"): {"0"},  # the CoM over the ankle
    # the scalar reference runs in float64: 1e308 N diverges at once, which is its outcome
    # row ("diverged", docs/reliability.md), not an error
    ("simulate", "--forces"): {"0", "-1", "1e308"},
    ("simulate", "--force"): {"0", "-1", "1e308"},
    ("animate", "--force"): {"0", "-1", "1e308"},
    ("basin", "--push-forces"): {"0", "-1", "1e308"},  # its push cells run the reference
    # a push of 0 s is no push; a delay of 0 ms is the study's controller
    ("*", "--durations"): {"0"},
    ("*", "--duration"): {"0"},
    ("basin", "--push-durations"): {"0"},
    ("landscape", "--delays"): {"0"},
    ("landscape", "--delay"): {"0"},
    ("pull", "--ramp"): {"0"},  # a pull of 0-s rise is applied at once (a step)
    # empty: the default (a strength of 1, no age, every study)
    ("cohort", "--ankle-strengths"): {""},
    ("cohort", "--hip-strengths"): {""},
    ("cohort", "--ages"): {""},
    ("report", "--studies"): {""},
    ("report", "--sweeps"): {"dir"},  # a folder of sweep files
}


def accepted(command: str, option: str) -> set[str]:
    return ACCEPTED.get((command, option), ACCEPTED.get(("*", option), set()))


class Reached(Exception):
    """The command got past its checks to its work."""


@pytest.fixture
def stand_in_work(monkeypatch):
    def reached(*_args, **_kwargs):
        raise Reached()

    # every folder's lock, wherever a module imported it (the store, the API, the studies)
    lock = store_folder.folder_lock
    for name, module in list(sys.modules.items()):
        if name.startswith("mjx_balance") and getattr(module, "folder_lock", None) is lock:
            monkeypatch.setattr(module, "folder_lock", reached)
    assert api.folder_lock is reached
    monkeypatch.setattr(loop, "simulate_scenario", reached)  # every reference push


def options() -> list[tuple[str, str]]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    found = []
    for command in BASE:
        for action in sub.choices[command]._actions:
            if (
                action.option_strings
                and action.nargs != 0
                and not action.choices
                and not isinstance(action, argparse._HelpAction)
            ):
                found.append((command, action.option_strings[-1]))
    return found


def values(tmp: Path) -> dict[str, str]:
    (tmp / "file.txt").write_text("not a configuration\n")
    return {
        **{v: v for v in NUMBERS},
        "file": str(tmp / "file.txt"),
        "dir": str(tmp),
        "missing": str(tmp / "missing" / "x"),
        "under-a-file": str(tmp / "file.txt" / "x"),
    }  # no one can write there


def argv_for(command: str, option: str, value: str, tmp: Path, out: Path) -> list[str]:
    argv = [a.format(tmp=tmp) for a in BASE[command]]
    if option in argv:
        i = argv.index(option)
        del argv[i : i + 2]
    if option == "--out":
        return [*argv, "--out", value]
    return [*argv, option, value, "--out", str(out)]


@pytest.mark.parametrize("command", sorted(BASE))
def test_every_option_refuses_a_hostile_value_or_means_it(
    command, tmp_path, monkeypatch, stand_in_work
):
    monkeypatch.chdir(tmp_path)  # a relative --out lands here
    (tmp_path / "a.toml").write_text("[scenario]\nt_end = 1.0\n")
    (tmp_path / "b.toml").write_text(
        "[scenario]\nt_end = 1.0\n[controller]\nr_diag = [2e-3, 2e-3]\n"
    )
    given = values(tmp_path)
    problems, tried = [], 0
    for cmd, option in options():
        if cmd != command:
            continue
        for label in (*NUMBERS, *PATHS):
            tried += 1
            out = tmp_path / "runs" / f"{tried}" / OUT_FILE.get(command, "")
            before = sorted(p.name for p in tmp_path.iterdir())
            argv = argv_for(command, option, given[label], tmp_path, out)
            err = io.StringIO()
            try:
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                    code = main(argv)
            except SystemExit as exc:  # argparse: usage, then its one error line
                code = exc.code
            except Reached:
                code = "reached"
            text = err.getvalue()
            lines = text.strip().splitlines()
            case = f"{command} {option} {label!r}"
            if "Traceback" in text:
                problems.append(f"{case}: a traceback")
            elif code == "reached":
                if label not in accepted(command, option):
                    problems.append(f"{case}: taken without a check")
            elif code in (1, 2):
                if not (lines and lines[-1].startswith("mjx-balance") and "error:" in lines[-1]):
                    problems.append(f"{case}: exit {code} without an error line: {lines[-1:]}")
                if (tmp_path / "runs" / f"{tried}").exists():
                    problems.append(f"{case}: refused, but wrote its --out")
            elif not (code == 0 and command == "model"):  # model writes at once (its work)
                problems.append(f"{case}: exit {code}")
            after = sorted(p.name for p in tmp_path.iterdir())
            written = set(after) - set(before) - {"runs"}
            if written and command != "model":
                problems.append(f"{case}: wrote {sorted(written)} in the working folder")
            for name in written:  # model's --out: its file (and folder), removed for the next
                path = tmp_path / name
                shutil.rmtree(path) if path.is_dir() else path.unlink()
    assert tried > 0
    assert not problems, "\n".join(problems)


def test_the_stand_in_is_reached_by_a_valid_command(tmp_path, stand_in_work):
    """The check above can tell: a valid command reaches the stand-in, a bad one does not."""
    with pytest.raises(Reached):
        main([*BASE["sweep"], "--out", str(tmp_path / "ok")])
    assert main([*BASE["sweep"][:-1], "nan", "--out", str(tmp_path / "bad")]) == 2
    assert not (tmp_path / "ok").exists() and not (tmp_path / "bad").exists()
    assert os.path.isdir(tmp_path)
