"""Test configuration: float64 is available (jax_enable_x64); library code always names its dtype.

The batched closed loop is compiled once per session (``batch_runner``): compiling it is the
expensive part of the suite (~13 s on 2 cores), running it is not (8 scenarios of 2 s take a
fraction of a second). Its tests run with ``jax_enable_x64`` off, as sweeps do (with x64 on,
MJX does some internal arithmetic in float64 even on a float32 model, which would make the
agreement with the reference look better than what users get); ``float32`` switches it off for
one test, ``jax.enable_x64(False)`` for a module.
"""

import os

import jax
import pytest

jax.config.update("jax_enable_x64", True)

# The persistent compilation cache (mjx_balance.runtime.cache) is off in the test session and in the
# processes it starts: tests never write into the user's cache folder (tests/test_cache.py
# gives its processes their own folders).
os.environ["MJX_BALANCE_CACHE_DIR"] = "off"

# The shared runner's configuration: the defaults with a 2-s run, long enough for the pushes the
# tests use to recover (settle by ~1.2 s) or fall (by ~1.4 s), short enough to run in a moment.
SHARED_T_END = 2.0
SHARED_BATCH = 8  # the smallest padded batch size: every batch of up to 8 scenarios reuses it


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
