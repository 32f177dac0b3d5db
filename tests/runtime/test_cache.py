"""JAX's persistent compilation cache, on by default.

Where it lives (XDG_CACHE_HOME, MJX_BALANCE_CACHE_DIR, off), and that a second *process* with
the same shapes compiles nothing: measured with JAX's own compile events
(``cache.CompileCounter``) in fresh interpreters. The fast test uses a tiny workload that goes
through the package's own code (the batched ADMM solve of a controller's QP, jitted); the slow
one the whole batched rollout through the command line, with another body on the second run.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mjx_balance.runtime import cache

# One jitted batched ADMM solve of the QP of a configuration given by --set-style overrides,
# with the small executables JAX builds on the way (array conversions, broadcasts: under
# JAX's default thresholds, one second of compile time, those would not be cached): prints
# JAX's compile events as JSON (requests, compiles, cache_hits, ...).
TINY = """
import json, sys
import mjx_balance
from mjx_balance.runtime import cache
print(json.dumps({"cache_dir": cache.enable()}))
import jax, jax.numpy as jnp
from mjx_balance.control import admm
from mjx_balance.model.params import Config
from mjx_balance.model.config_files import apply_overrides
from mjx_balance.control.qp import build_qp
config = apply_overrides(Config(), sys.argv[1:])
with cache.CompileCounter() as counter:
    qp = build_qp(config.controller, config.body, config.scenario.control_dt)
    settings = admm.settings_from_controller(config.controller)
    data = admm.build_admm(qp, settings, jnp.float32)
    x0 = jnp.zeros((4, 4), jnp.float32).at[:, 0].set(0.05)
    warm = admm.initial_warm(data)
    warm = jax.tree_util.tree_map(lambda w: jnp.broadcast_to(w, (4, *w.shape)), warm)
    solve = jax.jit(admm.admm_solve_batch, static_argnums=(3,))
    jax.block_until_ready(solve(data, x0, warm, settings))
print(json.dumps(counter.as_dict()))
"""


def run_tiny(env_cache: str | None, *overrides: str) -> tuple[str | None, dict]:
    env = {k: v for k, v in os.environ.items() if k != cache.ENV}
    if env_cache is not None:
        env[cache.ENV] = env_cache
    done = subprocess.run(
        [sys.executable, "-c", TINY, *overrides],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    return lines[0]["cache_dir"], lines[-1]


def test_a_second_process_compiles_nothing(tmp_path):
    folder = tmp_path / "jax-cache"
    used, first = run_tiny(str(folder))
    assert used == str(folder)
    assert first["compiles"] >= 1 and first["cache_misses"] >= 1 and first["cache_hits"] == 0
    assert any(folder.iterdir())  # written, small executables included (thresholds lowered)

    _, second = run_tiny(str(folder))
    assert second["requests"] == first["requests"]
    assert second["compiles"] == 0 and second["cache_hits"] == first["requests"]

    # Another configuration of the same shapes (other weights and body): the same executable.
    _, other = run_tiny(
        str(folder), "controller.q_diag=[10.0, 10.0, 1.0, 1.0]", "body.upper_mass=40.0"
    )
    assert other["compiles"] == 0 and other["cache_hits"] == first["requests"]


def test_off_compiles_every_time(tmp_path):
    used, counts = run_tiny("off")
    assert used is None
    assert counts["compiles"] >= 1 and counts["cache_hits"] == 0
    assert counts["cache_misses"] == 0  # the cache was not even asked


def test_cache_dir_follows_the_conventions(tmp_path, monkeypatch):
    monkeypatch.delenv(cache.ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        assert cache.cache_dir() == tmp_path / "xdg" / "mjx_balance" / "jax"
        monkeypatch.setenv("XDG_CACHE_HOME", "relative/path")  # invalid by the XDG spec
        assert cache.cache_dir() == Path.home() / ".cache" / "mjx_balance" / "jax"
        monkeypatch.delenv("XDG_CACHE_HOME")
        assert cache.cache_dir() == Path.home() / ".cache" / "mjx_balance" / "jax"
    monkeypatch.setenv(cache.ENV, str(tmp_path / "mine"))
    assert cache.cache_dir() == tmp_path / "mine"
    for value in ("off", "OFF", "0", "no", "false", "none", ""):
        monkeypatch.setenv(cache.ENV, value)
        assert cache.cache_dir() is None


def test_no_cache_option_turns_it_off(monkeypatch):
    from mjx_balance.cli.main import build_parser

    monkeypatch.setenv(cache.ENV, "/somewhere")
    args = build_parser().parse_args(["sweep", "--no-cache", "--out", "x"])
    assert args.no_cache is True
    assert build_parser().parse_args(["--no-cache", "table", "--out", "x"]).no_cache is True
    assert not hasattr(build_parser().parse_args(["table", "--out", "x"]), "no_cache")
    cache.disable()
    assert os.environ[cache.ENV] == "off" and cache.cache_dir() is None


@pytest.mark.slow
def test_the_rollout_of_another_body_is_loaded_not_compiled(tmp_path):
    """Through the command line: a two-cell sweep, then the same shapes with
    another body in a second process: its rollout (the engine's ``call``) is loaded from the
    cache. Only the engine's initial slot state (``_vacant``, a fraction of a second), which
    bakes the configuration's arrays in as constants, is compiled again."""
    env = {**os.environ, cache.ENV: str(tmp_path / "jax-cache")}
    script = (
        "import sys, json\n"
        "from mjx_balance.cli.main import main, use_host_cores\n"
        "use_host_cores()  # as the command does, before JAX starts\n"
        "from mjx_balance.runtime import cache\n"
        "with cache.CompileCounter() as c:\n"
        "    code = main(sys.argv[1:])\n"
        "print(json.dumps(c.as_dict()))\n"
        "sys.exit(code)\n"
    )
    counts = []
    for k, mass in enumerate(("35.0", "40.0")):
        done = subprocess.run(
            [
                sys.executable,
                "-c",
                script,
                "-q",
                "sweep",
                "--forces",
                "10,200",
                "--durations",
                "0.1",
                "--set",
                "scenario.t_end=1",
                "--set",
                f"body.upper_mass={mass}",
                "--out",
                str(tmp_path / f"run{k}"),
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
        )
        assert done.returncode == 0, done.stderr
        counts.append(json.loads(done.stdout.strip().splitlines()[-1]))
    first, second = counts
    assert "jit(call)" in [name for name, _ in first["compiled"]]
    assert "jit(call)" in second["loaded"]
    assert {name for name, _ in second["compiled"]} <= {"jit(_vacant)"}
    assert sum(seconds for _, seconds in second["compiled"]) < 5.0


# A tiny jitted function, for the cache's healing: compiled, cached, and counted.
HEAL = """
import json, logging, sys
import mjx_balance
from mjx_balance.runtime import cache
logging.basicConfig(level=logging.WARNING, stream=sys.stderr, format="%(message)s")
print(json.dumps({"cache_dir": cache.enable()}))
import jax, jax.numpy as jnp
with cache.CompileCounter() as counter:
    jax.block_until_ready(jax.jit(lambda x: jnp.sin(x) * 2.0 + 1.0)(jnp.arange(3.0)))
print(json.dumps(counter.as_dict()))
"""


def run_heal(folder: Path) -> tuple[dict, str]:
    env = {**os.environ, cache.ENV: str(folder)}
    done = subprocess.run(
        [sys.executable, "-c", HEAL], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


@pytest.mark.parametrize("damage", ["cut short", "corrupt"])
def test_a_damaged_cache_entry_is_removed_and_compiled_once_again(tmp_path, damage):
    folder = tmp_path / "jax-cache"
    first, _ = run_heal(folder)
    assert first["compiles"] >= 1
    entries = sorted(folder.glob(f"*{cache.ENTRY_SUFFIX}"))
    assert entries
    for entry in entries:  # as a full disk or a killed writer leaves it, or a bad sector
        data = entry.read_bytes()
        if damage == "cut short":
            entry.write_bytes(data[: len(data) // 2])
        else:
            middle = len(data) // 2
            entry.write_bytes(data[:middle] + bytes([data[middle] ^ 0xFF]) + data[middle + 1 :])
    second, said = run_heal(folder)
    assert f"removed {len(entries)} damaged entr" in said  # one line
    assert said.count("compilation cache:") == 1
    assert second["compiles"] == first["compiles"]  # compiled again, once, and written anew
    third, said = run_heal(folder)
    assert third["compiles"] == 0 and third["cache_hits"] == first["requests"]
    assert "damaged" not in said


def test_healing_checks_each_entry_once_and_leaves_other_files(tmp_path):
    import zlib

    (tmp_path / "a-cache").write_bytes(zlib.compress(b"x" * 1000))
    (tmp_path / "b-cache").write_bytes(zlib.compress(b"y" * 1000)[:-3])
    (tmp_path / "b-atime").write_bytes(b"12345678")
    (tmp_path / "notes.txt").write_text("not an entry")
    assert cache.heal(tmp_path) == ["b-cache"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-cache", "notes.txt", cache.VERIFIED]
    assert json.loads((tmp_path / cache.VERIFIED).read_text()).keys() == {"a-cache"}
    assert cache.heal(tmp_path) == []
