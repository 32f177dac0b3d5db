"""Test configuration: float64 is available (jax_enable_x64); library code always names its dtype.

The batched closed loop is compiled once per session (``batch_runner``): compiling it is the
expensive part of the suite (~13 s on 2 cores), running it is not (8 scenarios of 2 s take a
fraction of a second). Its tests run with ``jax_enable_x64`` off, as sweeps do (with x64 on,
MJX does some internal arithmetic in float64 even on a float32 model, which would make the
agreement with the reference look better than what users get); ``float32`` switches it off for
one test, ``float32_module`` for a module.
"""

import os
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)

# The persistent compilation cache (mjx_balance.runtime.cache) of the test session and of the
# processes it starts: the repository's .cache/jax-tests (ignored by git), so that a program
# compiled once (in this process or a child) is loaded by every later process and run, and
# tests never write into the user's own cache folder. MJX_BALANCE_CACHE_DIR set by the user
# wins (``off`` compiles everything anew: the cold run). tests/runtime/test_cache.py gives its
# processes their own folders.
TEST_CACHE = Path(__file__).resolve().parents[1] / ".cache" / "jax-tests"
os.environ.setdefault("MJX_BALANCE_CACHE_DIR", str(TEST_CACHE))

from mjx_balance.runtime import cache as _cache  # noqa: E402 - after the cache folder is set

_cache.enable()

# The shared runner's configuration: the defaults with a 2-s run, long enough for the pushes the
# tests use to recover (settle by ~1.2 s) or fall (by ~1.4 s), short enough to run in a moment.
SHARED_T_END = 2.0
SHARED_BATCH = 8  # the smallest padded batch size: every batch of up to 8 scenarios reuses it


@pytest.fixture
def fake_rollout(monkeypatch):
    """The command line's rollout replaced by support.FakeThresholdBatch; returns a function
    that swaps in another fake (and returns it)."""
    from support import DEFAULT_BATCH, FakeThresholdBatch

    def use(fake: FakeThresholdBatch) -> FakeThresholdBatch:
        monkeypatch.setattr(DEFAULT_BATCH, lambda config, **engine: fake)
        return fake

    use(FakeThresholdBatch())
    return use


@pytest.fixture
def stand_in(request, monkeypatch):
    """The command line's rollout replaced by a stand-in made per configuration; returns the list
    of the stand-ins made, in order (each counts its calls).

    What differs between modules is how a configuration's stand-in is made: the test module's
    ``stand_in_fake(config)`` (a support.FakeThresholdBatch for that configuration), or a
    function given as ``indirect`` parameter (``parametrize("stand_in", [make], indirect=True)``).
    """
    from support import DEFAULT_BATCH

    fake_for = getattr(request, "param", None) or getattr(request.module, "stand_in_fake", None)
    if fake_for is None:
        raise pytest.UsageError(
            f"{request.module.__name__} uses the stand_in fixture but defines "
            "no stand_in_fake(config)"
        )
    made = []

    def make(config, **_engine):
        made.append(fake_for(config))
        return made[-1]

    monkeypatch.setattr(DEFAULT_BATCH, make)
    return made


@pytest.fixture
def float32():
    """Run the test with jax_enable_x64 off (as sweeps run)."""
    with jax.enable_x64(False):
        yield


@pytest.fixture(scope="module")
def float32_module():
    """Run a whole module with jax_enable_x64 off (as sweeps run), from before its own
    module-scoped fixtures are built (pytest sets up ``usefixtures`` before a test's arguments of
    the same scope) to its end: ``pytestmark = pytest.mark.usefixtures("float32_module")``."""
    with jax.enable_x64(False):
        yield


@pytest.fixture(scope="session")
def batch_runner():
    """One compiled BatchRunner for the session: the default configuration with t_end = 2 s,
    float32 with x64 off, trajectories on, on one device, compiled for batches of 8.

    Every BatchRunner of an equal configuration (another convention, body or weights too, as
    long as the shapes, t_end, thresholds and bounds are equal) reuses its compiled function
    (rollout.runner's process-wide cache), so does a sweep through the command line when it is
    handed ``batch_runner.run_frame``. Call it under ``float32`` (or a module that switches x64
    off), as it was compiled.
    """
    from mjx_balance import rollout
    from mjx_balance.model.params import Config

    with jax.enable_x64(False):
        runner = rollout.BatchRunner(
            Config().replace(scenario={"t_end": SHARED_T_END}),
            trajectories=True,
            devices=jax.local_devices()[:1],
        )
        runner.compiled(SHARED_BATCH)
    return runner


# The margin audit (tests/margins.py): with MJX_BALANCE_MARGIN_AUDIT naming a file, every
# numpy.testing.assert_allclose and pytest.approx comparison is recorded as margins.within's
# are (the ratio of the difference to the tolerance), without editing the tests that use them.
if os.environ.get("MJX_BALANCE_MARGIN_AUDIT"):
    import margins
    import numpy as np
    import numpy.testing
    from _pytest.approx import ApproxScalar

    _assert_allclose = numpy.testing.assert_allclose

    def _recorded_assert_allclose(actual, desired, rtol=1e-7, atol=0, *args, **kwargs):
        try:
            used = margins.ratio(actual, desired, rtol, atol)
        except (TypeError, ValueError):  # not real numbers: nothing to measure
            used = None
        if used is not None:
            margins.record(kind="assert_allclose", rtol=rtol, atol=atol, used=used, why=None)
        return _assert_allclose(actual, desired, rtol, atol, *args, **kwargs)

    numpy.testing.assert_allclose = _recorded_assert_allclose
    np.testing.assert_allclose = _recorded_assert_allclose

    _approx_eq = ApproxScalar.__eq__

    def _recorded_approx_eq(self, actual):
        result = _approx_eq(self, actual)
        expected = self.expected
        scalar = (
            isinstance(actual, (int, float, np.integer, np.floating))
            and isinstance(expected, (int, float, np.integer, np.floating))
            and not isinstance(actual, (bool, np.bool_))
            and not isinstance(expected, (bool, np.bool_))
        )
        if scalar:  # arrays come back here element by element; the tolerance is max(abs, rel |e|)
            tolerance = float(self.tolerance)
            diff = 0.0 if actual == expected else abs(float(actual) - float(expected))
            used = 0.0 if diff == 0 else (diff / tolerance if tolerance > 0 else float("inf"))
            if diff != diff:  # NaN
                used = 0.0 if result else float("inf")
            rel = (
                self.rel
                if self.rel is not None
                else 0.0
                if self.abs is not None
                else self.DEFAULT_RELATIVE_TOLERANCE
            )
            absolute = self.abs if self.abs is not None else self.DEFAULT_ABSOLUTE_TOLERANCE
            margins.record(kind="approx", rtol=rel, atol=absolute, used=used, why=None)
        return result

    ApproxScalar.__eq__ = _recorded_approx_eq


# -- parallel runs (pytest-xdist) -----------------------------------------------------------------
# The default run uses one worker per core (``-n auto --dist loadfile`` in pyproject.toml).
# Each test file runs whole on one worker (its module fixtures are built once), and the files
# that use the shared compiled programs run on one worker together (support.GROUPS), so that
# each program is compiled once, then loaded from the session's cache by any process that needs
# it later. The groups and the files that take longest start first (support.FIRST), so that no
# worker is left with a long file at the end.


def pytest_xdist_make_scheduler(config, log):
    """--dist loadfile with the files of support.GROUPS as one unit each, the longest first."""
    if config.getvalue("dist") != "loadfile":
        return None
    from support import FIRST, GROUPS
    from xdist.scheduler import LoadScopeScheduling

    class ByProgram(LoadScopeScheduling):
        def _split_scope(self, nodeid):
            file = nodeid.split("::")[0]
            return GROUPS.get(Path(file).name, file)

        def _assign_work_unit(self, node):
            rank = {scope: i for i, scope in enumerate(FIRST)}
            first = min(
                self.workqueue,
                key=lambda scope: (
                    rank.get(Path(scope).name, len(rank)),
                    -len(self.workqueue[scope]),
                ),
            )
            self.workqueue.move_to_end(first, last=False)
            super()._assign_work_unit(node)

    return ByProgram(config, log)


# -- the compile budget ------------------------------------------------------------------------
# Compiling the batched closed loop is what the suite spends most of its time on (tens of
# seconds a program on 2 cores, a few to load one from the cache), so the number of distinct
# programs a run builds (runtime.compiled's ledger: padded batches, engines, C-path calls) is
# kept to a stated budget: a run that builds more fails at its end, naming the programs and the
# tests that built them. Every program is listed, with the seconds it took, at the end of a
# session (``MJX_BALANCE_COMPILE_LOG=FILE``: one line per program and per test's XLA compiles).
# Distinct programs of the default run (``-m "not slow"``), one line each:
#   the padded batch with trajectories (conftest batch_runner: defaults, t_end 2 s)
#   the engine with the certificate and without (support.ENGINE_SLOTS, one device, float32)
#   the hip servo's padded batch (test_hip_servo: its MJX flags differ)
#   the C path's calls: plain, offset-free, delay-compensated (test_cpath, test_offset_free,
#     test_delay_compensation), each compiled at its first call
#   the C path's call with the certificate (test_cpath's near-zero pushes; about 5 s)
BUDGETS = {"not slow": 8}
_BUILT: list[dict] = []  # the programs this process built, with the test that built them
_XLA: list[tuple[str, int, int, float]] = []  # per test: XLA compiles, cache loads, seconds


def program_id(key: tuple) -> str:
    """A program's key as text that is the same in every process (addresses left out)."""
    import hashlib
    import re

    text = re.sub(r" at 0x[0-9a-f]+", "", repr(key))
    return hashlib.sha1(text.encode()).hexdigest()[:12]


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    from mjx_balance.runtime import compiled
    from mjx_balance.runtime.cache import CompileCounter

    before = len(compiled.built())
    with CompileCounter() as counter:
        yield
    _XLA.append((item.nodeid, counter.compiles, counter.cache_hits, counter.compile_seconds))
    _BUILT.extend(
        {"test": item.nodeid, "kind": c.kind, "seconds": c.seconds, "id": program_id(c.key)}
        for c in compiled.built()[before:]
    )


def pytest_testnodedown(node, error):
    """(pytest-xdist, controller) A worker's ledger joins this process's."""
    import json

    output = getattr(node, "workeroutput", {})
    _BUILT.extend(json.loads(output.get("compiled", "[]")))
    _XLA.extend(tuple(x) for x in json.loads(output.get("xla", "[]")))


def pytest_sessionfinish(session, exitstatus):
    import json

    if hasattr(session.config, "workeroutput"):  # an xdist worker: the controller reports
        session.config.workeroutput["compiled"] = json.dumps(_BUILT)
        session.config.workeroutput["xla"] = json.dumps(_XLA)
        return
    budget = BUDGETS.get(session.config.option.markexpr)
    distinct = {b["id"] for b in _BUILT}
    if budget is not None and len(distinct) > budget and session.exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
        session.config._compile_budget_exceeded = budget


def pytest_terminal_summary(terminalreporter, config):
    if not _BUILT and not _XLA:
        return
    write = terminalreporter.write_line
    distinct = {b["id"] for b in _BUILT}
    seconds = sum(b["seconds"] for b in _BUILT)
    xla = sum(x[1] for x in _XLA), sum(x[2] for x in _XLA), sum(x[3] for x in _XLA)
    write(
        f"compiled programs: {len(distinct)} distinct, {len(_BUILT)} built, {seconds:.1f} s "
        f"(all XLA executables: {xla[0]} compiled, {xla[1]} loaded from the cache, "
        f"{xla[2]:.1f} s)"
    )
    budget = getattr(config, "_compile_budget_exceeded", None)
    if budget is not None:
        write(
            f"FAILED: the compile budget: {len(distinct)} distinct programs, more than the "
            f"{budget} of conftest.BUDGETS; built:",
            red=True,
        )
        for b in _BUILT:
            write(f"  {b['id']} {b['kind']:6s} {b['seconds']:6.1f} s  {b['test']}", red=True)
    path = os.environ.get("MJX_BALANCE_COMPILE_LOG")
    if path:
        with open(path, "w") as fh:
            for b in _BUILT:
                fh.write(f"{b['seconds']:8.2f} {b['kind']:6s} {b['id']} {b['test']}\n")
            for test, compiles, loads, secs in sorted(_XLA, key=lambda r: -r[3]):
                if compiles or loads:
                    fh.write(f"XLA {secs:8.2f} {compiles:4d} {loads:4d} {test}\n")
