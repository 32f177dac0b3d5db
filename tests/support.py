"""What the tests share, without side effects on import (a process the tests start may import
a test module; conftest.py configures JAX and pytest and is imported by pytest alone)."""

# The engine's tests (no trajectories): the CPU's default 32 slots on one device under
# float32, x64 off. The window's length is a traced value (rollout.kernel.Arrays.n_control), so
# every test of the default body that keeps these (any t_end of 1 s or more: a call's block is
# then 100 periods) shares one compiled engine with the certificate and one without
# (runtime.compiled), and so do the Python API's and the notebook's runs on one device.
ENGINE_SLOTS = 32

# Parallel runs (conftest.py, "parallel runs"): the files that use the shared compiled programs
# run on one worker together, so each program is compiled once: the shared engine (ENGINE_SLOTS,
# with the certificate and without; the notebook's kernel loads it from the session's cache)
# and the shared padded batch (conftest's batch_runner); and the tests of one tiny report.
GROUPS = {
    **dict.fromkeys(["test_engine.py", "test_basin.py", "test_balance_measures.py",
                     "test_input_faults.py", "test_notebook.py"], "engine"),
    **dict.fromkeys(["test_rollout.py", "test_cpath.py", "test_landscape.py",
                     "test_sweep.py"], "batch"),
    # the tiny report (tiny_report.py) is built once per process: its readers together
    **dict.fromkeys(["test_report.py", "test_report_browser.py"], "report"),
}
# The units that take longest (pytest --durations), started first: the groups, then the files
# with compiled programs of their own or many figures; the rest by their number of tests.
FIRST = ["engine", "report", "batch", "test_offset_free.py", "test_bench_engine.py",
         "test_hip_servo.py", "test_figure_style.py", "test_store_faults.py"]
