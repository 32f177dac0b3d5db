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
# and the shared padded batch (conftest's batch_runner).
GROUPS = {
    **dict.fromkeys(["test_engine.py", "test_basin.py", "test_balance_measures.py",
                     "test_input_faults.py", "test_notebook.py"], "engine"),
    **dict.fromkeys(["test_rollout.py", "test_cpath.py", "test_landscape.py",
                     "test_sweep.py"], "batch"),
}
# The units that take longest, started first (measured on 2 cores: the engine's group ~110 s,
# the report's tiny report and its rebuild ~85 s, the padded batch's group ~60 s; then the
# files with their own compiled programs or many figures); the rest by their number of tests.
FIRST = ["engine", "test_report.py", "batch", "test_offset_free.py", "test_bench_engine.py",
         "test_hip_servo.py", "test_figure_style.py", "test_store_faults.py"]
