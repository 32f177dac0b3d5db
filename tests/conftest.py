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
