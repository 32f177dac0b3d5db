"""Test configuration: float64 is available (jax_enable_x64); library code always names its dtype.

The batched closed loop is compiled once per session (``batch_runner``): compiling it is the
expensive part of the suite (~13 s on 2 cores), running it is not (8 scenarios of 2 s take a
fraction of a second). Its tests run with ``jax_enable_x64`` off, as sweeps do (with x64 on,
MJX does some internal arithmetic in float64 even on a float32 model, which would make the
agreement with the reference look better than what users get); ``float32`` switches it off for
one test, ``jax.enable_x64(False)`` for a module.
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
# wins (``off`` compiles everything anew: the cold run). tests/test_cache.py gives its
# processes their own folders.
TEST_CACHE = Path(__file__).resolve().parents[1] / ".cache" / "jax-tests"
os.environ.setdefault("MJX_BALANCE_CACHE_DIR", str(TEST_CACHE))

from mjx_balance.runtime import cache as _cache  # noqa: E402 - after the folder is chosen

_cache.enable()

# The shared runner's configuration: the defaults with a 2-s run, long enough for the pushes the
# tests use to recover (settle by ~1.2 s) or fall (by ~1.4 s), short enough to run in a moment.
SHARED_T_END = 2.0
SHARED_BATCH = 8  # the smallest padded batch size: every batch of up to 8 scenarios reuses it
# The engine's tests (no trajectories): 8 slots on one device under float32, x64 off. The
# window's length is a traced value (rollout.kernel.Arrays.n_control), so every test of the
# default body that keeps these (any t_end of 1 s or more: a call's block is then 100 periods)
# shares one compiled engine with the certificate and one without (runtime.compiled).
ENGINE_SLOTS = 32


@pytest.fixture
def float32():
    """Run the test with jax_enable_x64 off (as sweeps run)."""
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
        runner = rollout.BatchRunner(Config().replace(scenario={"t_end": SHARED_T_END}),
                                     trajectories=True, devices=jax.local_devices()[:1])
        runner.compiled(SHARED_BATCH)
    return runner


# The margin audit (tests/margins.py): with MJX_BALANCE_MARGIN_AUDIT naming a file, every
# numpy.testing.assert_allclose and pytest.approx comparison is recorded as margins.within's
# are (the ratio of the difference to the tolerance), without editing the tests that use them.
if os.environ.get("MJX_BALANCE_MARGIN_AUDIT"):
    import numpy as np
    import numpy.testing
    from _pytest.approx import ApproxScalar

    import margins

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
        scalar = (isinstance(actual, (int, float, np.integer, np.floating))
                  and isinstance(expected, (int, float, np.integer, np.floating))
                  and not isinstance(actual, (bool, np.bool_))
                  and not isinstance(expected, (bool, np.bool_)))
        if scalar:  # arrays come back here element by element; the tolerance is max(abs, rel |e|)
            tolerance = float(self.tolerance)
            diff = 0.0 if actual == expected else abs(float(actual) - float(expected))
            used = 0.0 if diff == 0 else (diff / tolerance if tolerance > 0 else float("inf"))
            if diff != diff:  # NaN
                used = 0.0 if result else float("inf")
            rel = (self.rel if self.rel is not None
                   else 0.0 if self.abs is not None else self.DEFAULT_RELATIVE_TOLERANCE)
            absolute = self.abs if self.abs is not None else self.DEFAULT_ABSOLUTE_TOLERANCE
            margins.record(kind="approx", rtol=rel, atol=absolute, used=used, why=None)
        return result

    ApproxScalar.__eq__ = _recorded_approx_eq


# -- the compile budget --------------------------------------------------------------------
_CURRENT_TEST = {"id": None}
_BUILT_BY: list = []
_XLA: list = []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    from mjx_balance.runtime import compiled

    from mjx_balance.runtime.cache import CompileCounter

    before = len(compiled.built())
    _CURRENT_TEST["id"] = item.nodeid
    with CompileCounter() as counter:
        yield
    _XLA.append((item.nodeid, counter.compiles, counter.compile_seconds))
    for c in compiled.built()[before:]:
        _BUILT_BY.append((item.nodeid, c.kind, c.seconds, _describe(c.key)))


def _describe(key):
    shape = key[1] if key and isinstance(key[0], str) else key
    try:
        static = shape[3]
        text = (f"n_control={static.n_control} traj={static.trajectories} "
                f"delay={static.delay_steps} comp={static.compensate} of={static.offset_free} "
                f"hip={static.push_at_hip} batch={shape[4]} dev={shape[5]} x64={shape[6]}")
    except Exception:  # noqa: BLE001
        text = "?"
    if key and isinstance(key[0], str):
        text += " rest=" + repr(key[2:])[:80]
    return text


def pytest_terminal_summary(terminalreporter):
    if not _BUILT_BY:
        return
    total = sum(b[2] for b in _BUILT_BY)
    terminalreporter.write_line(f"compiled programs: {len(_BUILT_BY)}, {total:.1f} s")
    path = os.environ.get("MJX_BALANCE_COMPILE_LOG")
    if path:
        with open(path, "w") as fh:
            for nodeid, kind, s, what in _BUILT_BY:
                fh.write(f"{s:8.2f} {kind:8s} {nodeid} {what}\n")
            for nodeid, n, s in sorted(_XLA, key=lambda r: -r[2]):
                if n:
                    fh.write(f"XLA {s:8.2f} {n:4d} {nodeid}\n")
