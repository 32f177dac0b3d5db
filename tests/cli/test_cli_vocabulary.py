"""One vocabulary for every command: the same flag for the same thing
(plural where a list is accepted), --config / --set / --convention on every command that runs
the model, no old names nor prefixes of names, defaults and the default
grid in --help, an honest planned-work line and progress bars with a fixed total.

Parse-level tests (``build_parser``) and a few stand-in runs: nothing compiles or simulates.
"""

import io
import sys

import numpy as np
import pandas as pd
import pytest
from support import DEFAULT_BATCH, FakeThresholdBatch

from mjx_balance.cli import main
from mjx_balance.cli.common import load_run_config
from mjx_balance.cli.main import build_parser
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.runs import DEFAULT_SWEEP
from mjx_balance.runs.acting_time import bracket_cost, max_acting_time
from mjx_balance.runs.chunks import planned_work, wall_span
from mjx_balance.runs.progress import wanted
from mjx_balance.studies import defaults

# Every command that runs the model, with the least it needs besides the configuration.
MODEL_COMMANDS = {
    "simulate": ["--out", "OUT"],
    "bench": ["--out", "OUT"],
    "sweep": ["--out", "OUT"],
    "table": ["--out", "OUT"],
    "compare": ["A", "--out", "OUT"],
    "landscape": ["--out", "OUT"],
    "basin": ["--out", "OUT"],
    "lean": ["--out", "OUT"],
    "pull": ["--out", "OUT"],
    "cohort": ["--heights", "1.7", "--masses", "70", "--out", "OUT"],
    "sensitivity": ["--out", "OUT"],
    "animate": ["--force", "10", "--out", "OUT.gif"],
    "report": ["--out", "OUT"],
    "model": ["--out", "OUT.xml"],
    "view": ["--force", "10"],
}
NOTICE = "is now"
# Commands that run the model in a folder's own configuration (no --config, --set, --convention).
FOLDER_COMMANDS = {"explore"}
# Commands that run the shipped human bodies only (the people scorecard: its rows are measured
# with those bodies, so it takes no configuration of the user's).
SHIPPED_BODY_COMMANDS = {"people"}


@pytest.fixture
def files(tmp_path):
    """Two variants and a base configuration."""
    a, b, base = tmp_path / "a.toml", tmp_path / "b.toml", tmp_path / "base.toml"
    a.write_text("[controller]\nhorizon = 25\n")
    b.write_text('[controller]\nconvention = "joint"\n')
    base.write_text("[scenario]\nt_end = 6.0\n[controller]\nhorizon = 40\n")
    return {"A": str(a), "B": str(b), "BASE": str(base), "OUT": str(tmp_path / "out")}


def argv(name, files, *extra):
    return [
        name,
        *[files.get(w, w.replace("OUT", files["OUT"])) for w in MODEL_COMMANDS[name]],
        *extra,
    ]


def test_every_command_is_listed():
    commands = build_parser()._subparsers._group_actions[0].choices
    assert set(commands) == set(MODEL_COMMANDS) | FOLDER_COMMANDS | SHIPPED_BODY_COMMANDS


@pytest.mark.parametrize("name", sorted(MODEL_COMMANDS))
def test_every_model_command_takes_config_set_and_convention(name, files):
    args = build_parser().parse_args(
        argv(
            name,
            files,
            "--config",
            files["BASE"],
            "--set",
            "controller.horizon=30",
            "--convention",
            "joint",
        )
    )
    assert args.convention == "joint" and args.set == ["controller.horizon=30"]
    assert args.config in (files["BASE"], [files["BASE"]])  # compare: a list (refused past one)
    if name != "compare":  # compare's base goes under each variant (test below)
        config = load_run_config(args)
        assert (config.controller.horizon, config.scenario.t_end, config.controller.convention) == (
            30,
            6.0,
            "joint",
        )


@pytest.mark.parametrize(
    "name,old,new,dest,value",
    [
        ("simulate", "--force", "--forces", "forces", "10,20"),
        ("simulate", "--duration", "--durations", "durations", "0.1"),
        ("landscape", "--delay", "--delays", "delays", "0,100c"),
        ("bench", "--reference", "--reference-runs", "reference", "4"),
    ],
)
def test_old_names_and_prefixes_are_refused(name, old, new, dest, value, files, capsys):
    """The names of an unreleased version, which are also prefixes of today's, are not taken
    as abbreviations (one spelling per option: the parser has allow_abbrev off)."""
    with pytest.raises(SystemExit):
        build_parser().parse_args(argv(name, files, old, value))
    err = capsys.readouterr().err  # bench's positional sub-command takes the value, then says so
    assert f"unrecognized arguments: {old}" in err or "invalid choice: '4'" in err
    args = build_parser().parse_args(argv(name, files, new, value))
    assert str(getattr(args, dest)) == value


def test_help_uses_the_plural_names_only():
    commands = build_parser()._subparsers._group_actions[0].choices
    for name in ("simulate", "sweep", "compare", "landscape"):
        text = commands[name].format_help()
        assert "--forces" in text and "--durations" in text
        assert "--force " not in text and "--duration " not in text
    assert "--delays" in commands["landscape"].format_help()
    assert "--delay " not in commands["landscape"].format_help()
    # one push: the singular is right
    for name in ("animate", "view"):
        assert "--force FORCE" in commands[name].format_help()


def test_simulate_pairs_conflict_names_the_new_flags(tmp_path, capsys):
    code = main(["simulate", "--pairs", "20:0.1", "--forces", "20", "--out", str(tmp_path / "out")])
    assert code == 2 and "leave out --forces and --durations" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_sweep_help_shows_the_default_grid():
    commands = build_parser()._subparsers._group_actions[0].choices
    text = " ".join(commands["sweep"].format_help().split())
    for key in ("forces", "durations", "table_forces"):
        assert DEFAULT_SWEEP[key] in text, key
    assert "(default: the --sweep file's, else the default sweep's 0:150:10)" in text
    # the light copy --help is built from is the runs floor's grid
    assert (
        defaults.DEFAULT_SWEEP_FORCES,
        defaults.DEFAULT_SWEEP_DURATIONS,
        defaults.DEFAULT_SWEEP_TABLE_FORCES,
    ) == (DEFAULT_SWEEP["forces"], DEFAULT_SWEEP["durations"], DEFAULT_SWEEP["table_forces"])
    for name in ("compare", "landscape"):
        assert DEFAULT_SWEEP["durations"] in " ".join(commands[name].format_help().split())


def test_report_conventions_and_convention(files, capsys):
    commands = build_parser()._subparsers._group_actions[0].choices
    text = " ".join(commands["report"].format_help().split())
    assert "--conventions (a list): the study's experiments" in text
    assert "--convention (one, as in every other command): the studies" in text
    args = build_parser().parse_args(["report", "--out", files["OUT"]])
    assert args.conventions == "paper,joint" and args.convention is None
    args = build_parser().parse_args(
        ["report", "--conventions", "joint", "--convention", "paper", "--out", files["OUT"]]
    )
    assert (args.conventions, args.convention) == ("joint", "paper")
    with pytest.raises(SystemExit):
        build_parser().parse_args(["report", "--conventions", "paper,sideways", "--out", "x"])
    assert "--conventions: unknown sideways" in capsys.readouterr().err


# --- compare: variants and base --------------------------------------------------------------


@pytest.fixture
def ran(monkeypatch):
    """run_compare (as the API calls it) replaced: records the configurations it was handed."""
    seen = {}

    def record(out, configs, *_args, **_kwargs):
        seen.update(configs)

    monkeypatch.setattr("mjx_balance.api.run_compare", record)  # what mb.compare calls
    return seen


def test_compare_variants_go_on_top_of_the_base(files, ran, capsys):
    code = main(
        [
            "-q",
            "compare",
            files["A"],
            "--variant",
            f"other={files['B']}",
            "--config",
            files["BASE"],
            "--set",
            "scenario.t_end=8",
            "--out",
            files["OUT"],
        ]
    )
    assert code == 0 and capsys.readouterr().err == ""
    assert list(ran) == ["a", "other"]
    # a: its horizon over the base's; both: the base's other values, then --set on top
    assert ran["a"].controller.horizon == 25 and ran["other"].controller.horizon == 40
    assert ran["other"].controller.convention == "joint"
    assert {c.scenario.t_end for c in ran.values()} == {8.0}
    ran.clear()
    assert (
        main(
            [
                "-q",
                "compare",
                files["A"],
                files["B"],
                "--convention",
                "joint",
                "--out",
                files["OUT"],
            ]
        )
        == 0
    )
    assert [c.controller.convention for c in ran.values()] == ["joint", "joint"]
    assert (
        ran["a"].controller.horizon == 25
        and ran["b"].controller.horizon == Config().controller.horizon
    )


def test_compare_without_a_variant_is_refused(files, ran, capsys):
    """--config names the base; the configurations to compare are FILEs or --variant."""
    code = main(
        ["-q", "compare", "--config", files["A"], "--config", files["B"], "--out", files["OUT"]]
    )
    assert code == 2 and not ran
    assert "compare FILE ... or --variant NAME=FILE" in capsys.readouterr().err


@pytest.mark.parametrize(
    "extra,message",
    [
        ([], "needs at least one configuration"),
        (["A", "--config", "A", "--config", "B"], "give one base configuration"),
        (["--variant", "x=A", "--variant", "x=B"], "'x' is given twice"),
    ],
)
def test_compare_refuses_unclear_variants(files, ran, capsys, extra, message):
    words = [files.get(w, w) for w in extra]
    words = [w.replace("=A", "=" + files["A"]).replace("=B", "=" + files["B"]) for w in words]
    assert main(["compare", *words, "--out", files["OUT"]]) == 2
    assert message in capsys.readouterr().err and not ran


def test_compare_variant_must_be_name_equals_file(files, capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["compare", "--variant", files["A"], "--out", "x"])
    assert "give NAME=FILE" in capsys.readouterr().err


# --- planned work and progress ----------------------------------------------------------------


def test_planned_work_of_a_tiny_run_is_honest():
    line = planned_work(2, 2.0, 64)
    assert "0 s to 0 s" not in line and "under 1 s" in line and "1 chunk of 64" in line
    assert wall_span(0.2, 0.4) == "under 1 s"
    assert wall_span(0.6, 1.2) == "about 1 s"
    assert wall_span(8.2, 11.4) == "about 8 to 11 s"
    assert wall_span(100, 300) == "about 100 s to 5 min"
    assert "about 0 s" not in planned_work(60, 12.0, 64)


class Recorder:
    """A stand-in tqdm: records (n, total) after every update."""

    bars: list = []

    def __init__(self, total, initial, **_kwargs):
        self.total, self.n, self.log = total, initial, [(initial, total)]
        Recorder.bars.append(self)

    def update(self, k):
        self.n += k
        self.log.append((self.n, self.total))

    def close(self):
        pass


@pytest.mark.parametrize("batch", [None, 16])
def test_the_table_bar_keeps_its_total(monkeypatch, batch):
    monkeypatch.setattr("tqdm.auto.tqdm", Recorder)
    Recorder.bars = []
    config = Config().replace(scenario={"t_end": 2.0})
    result = max_acting_time(
        "20,50,80", config, run_batch=FakeThresholdBatch(), batch=batch, progress=True, say=None
    )
    (bar,) = Recorder.bars
    assert len({total for _, total in bar.log}) == 1  # fixed
    counts = [n for n, _ in bar.log]
    assert counts == sorted(counts) and counts[-1] == bar.total  # forward, and it ends full
    assert len(result.runs) <= bar.total  # an upper bound of the scenarios


def test_bracket_cost_bounds_the_k_section():
    def worst(width, k):  # the most a k-section of a bracket this wide can take
        if width <= 1:
            return 0
        split = np.unique([width * j // (k + 1) for j in range(1, k + 1)])
        split = split[(split > 0) & (split < width)]
        gaps = np.diff(np.concatenate([[0], split, [width]]))
        return split.size + max(worst(int(g), k) for g in gaps)

    for k in (1, 3, 7):
        for width in range(1, 80):
            assert worst(width, k) <= bracket_cost(width, k)


def test_api_progress_default_is_on_where_someone_watches(monkeypatch):
    class Stream:
        closed = False

        def __init__(self, tty):
            self.tty = tty

        def isatty(self):
            return self.tty

        def write(self, text):
            return len(text)

    monkeypatch.setattr(sys, "stderr", Stream(True))
    assert wanted(None) and wanted(True) and not wanted(False)
    monkeypatch.setattr(sys, "stderr", Stream(False))  # redirected: a file, a pipe, pytest
    assert not wanted(None) and wanted(True)

    class Kernel:
        kernel = object()

    class IPython:
        @staticmethod
        def get_ipython():
            return Kernel()

    monkeypatch.setitem(sys.modules, "IPython", IPython)  # a notebook: no TTY, still shown
    assert wanted(None)
    closed = Stream(True)
    closed.closed = True
    monkeypatch.setattr(sys, "stderr", closed)
    assert not wanted(None) and not wanted(True)


def test_the_api_draws_no_bar_in_pytest(monkeypatch, tmp_path):
    import mjx_balance as mb

    monkeypatch.setattr(DEFAULT_BATCH, lambda config, **_engine: FakeThresholdBatch())
    monkeypatch.setattr("tqdm.auto.tqdm", Recorder)
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # as pytest's capture: no terminal
    Recorder.bars = []
    region = mb.sweep("0,10", "0.5,1", out=tmp_path / "s")  # progress: the default
    assert isinstance(region, pd.DataFrame) and Recorder.bars == []
    mb.sweep("0,10,20", "0.5,1", out=tmp_path / "t", progress=True)
    assert len(Recorder.bars) == 1


def test_compare_loader_refuses_a_name_twice(tmp_path):
    from mjx_balance.studies.compare import load_configs

    a = tmp_path / "a.toml"
    a.write_text("")
    b = tmp_path / "b.toml"
    b.write_text("")
    with pytest.raises(ParameterError, match="given twice"):
        load_configs([a, b], names=[None, "a"])  # b named as a's stem
