"""What the tests share, without side effects on import (a process the tests start may import
it; conftest.py configures JAX and pytest and is imported by pytest alone): the settings of the
shared compiled programs, the parallel run's groups, and the fakes and helpers that tests of
several floors use. Heavy imports (JAX, the package's floors) happen inside the helpers.

    FakeThresholdBatch   an analytic stand-in for the rollout (recovered iff |F| T < c)
    DEFAULT_BATCH        what to patch to give the command line a stand-in rollout
    sweep_fake, GRID, tiny_config, expected_max_time, expected_area
                         a sweep and a table on the stand-in, and what they must give
    AdmmMPC              the batched path's float32 ADMM in the scalar reference's loop
    synthetic_series     three made-up runs' time series, for figures
    fake_region, grid_cells, push_energy
                         a made-up region frame (one row per cell), for figures and studies
    run_cli, assert_refused
                         a command's exit code and stderr, and the one-line refusal rule
    docs_script          a script of docs/scripts/ as a module (its functions, not its main)
"""

from __future__ import annotations

import gc
import os
import weakref
from pathlib import Path

import numpy as np
import pandas as pd

TESTS = Path(__file__).resolve().parent  # on sys.path for the tests (pyproject.toml)
REPO = TESTS.parent

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
    **dict.fromkeys(
        [
            "test_engine.py",
            "test_basin.py",
            "test_lean.py",
            "test_balance_measures.py",
            "test_input_faults.py",
            "test_notebook.py",
        ],
        "engine",
    ),
    **dict.fromkeys(
        ["test_rollout.py", "test_cpath.py", "test_landscape.py", "test_sweep.py"], "batch"
    ),
    # the tiny report (tiny_report.py) is built once per process: its readers together
    **dict.fromkeys(["test_report.py", "test_report_browser.py"], "report"),
}
# The units that take longest (pytest --durations), started first: the groups, then the files
# with compiled programs of their own or many figures; the rest by their number of tests.
FIRST = [
    "engine",
    "report",
    "batch",
    "test_offset_free.py",
    "test_bench_engine.py",
    "test_hip_servo.py",
    "test_figure_style.py",
    "test_store_faults.py",
]


def unavailable(reason: str, what: str = "the test") -> None:
    """A test's tool or package is missing (``reason``): skip with the reason, except under
    CI=true, where it fails (``what`` must run in CI: .ci/run installs everything)."""
    import pytest

    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason}, and CI=true: {what} must run in CI")
    pytest.skip(reason)


def extra_module(name: str, extra: str):
    """The module ``name`` that the package's extra ``extra`` installs (the test extra leaves
    the notebook kernel and Dask to the slow run: .ci/run installs those extras before it);
    without it, :func:`unavailable`."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        unavailable(f'{name} is not installed (pip install -e ".[{extra}]")')


def docs_script(name: str):
    """``docs/scripts/NAME.py`` loaded as a module (the scripts are not a package): its
    functions and tables, without running its ``main``."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, REPO / "docs" / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- a stand-in rollout ---------------------------------------------------------------------------

DEFAULT_BATCH = "mjx_balance.runs.batch.default_batch"  # what LazyBatch calls


class FakeThresholdBatch:
    """FAKE batch function for bookkeeping tests only: recovered iff |F| * T < c (else fell);
    optionally also recovered for T in ``window`` (a non-monotone fake). Returns a dict of summary
    columns with integer outcome codes, like BatchRunner.run. Counts calls; can raise on call k."""

    def __init__(
        self,
        c: float = 30.0,
        window: tuple[float, float] | None = None,
        fail_on_call: int | None = None,
        one_step: float | None = None,
    ):
        self.c, self.window, self.fail_on_call = c, window, fail_on_call
        self.one_step = one_step  # a fall with |F| T < one_step needs one step, else none do
        self.calls: list[int] = []
        self.cells: list[set[tuple[float, float]]] = []  # each call's (force, duration) cells

    def all_cells(self) -> set[tuple[float, float]]:
        """Every cell any call ran."""
        return set().union(*self.cells)

    def recovered(self, forces, durations):
        ok = np.abs(forces) * durations < self.c
        if self.window is not None:
            ok |= (durations >= self.window[0]) & (durations <= self.window[1])
        return ok

    def __call__(self, forces, durations):
        if self.fail_on_call is not None and len(self.calls) + 1 == self.fail_on_call:
            self.calls.append(-1)
            raise KeyboardInterrupt("fake interruption")
        self.calls.append(len(forces))
        self.cells.append(
            {(round(float(f), 6), round(float(d), 6)) for f, d in zip(forces, durations)}
        )
        forces = np.asarray(forces, dtype=np.float32)  # like a float32 rollout
        durations = np.asarray(durations, dtype=np.float32)
        ok = self.recovered(forces.astype(np.float64), durations.astype(np.float64))
        out = {c: np.zeros(forces.size) for c in summary_columns() if c != "convention"}
        out["force"], out["duration"] = forces, durations
        out["outcome"] = np.where(ok, 0, 2).astype(np.int32)
        out["settle_time"] = np.where(ok, 1.0 + durations, np.nan)
        out["fall_time"] = np.where(ok, np.nan, durations)
        out["energy_ankle"] = np.abs(forces) * durations
        out["energy_hip"] = 2 * np.abs(forces) * durations
        out["energy_total"] = 3 * np.abs(forces) * durations
        impulse = np.abs(forces.astype(np.float64)) * durations.astype(np.float64)
        one = self.one_step is not None and impulse < (self.one_step or 0.0)
        out["steps_needed"] = np.where(ok, 0.0, np.where(one, 1.0, np.inf))
        return out


def summary_columns() -> list[str]:
    """The summary columns (outcomes.SUMMARY_COLUMNS), imported when a stand-in runs."""
    from mjx_balance.measures.outcomes import SUMMARY_COLUMNS

    return SUMMARY_COLUMNS


def tiny_config(**scenario):
    """The defaults with a 2-s window (and ``scenario`` overrides)."""
    from mjx_balance.model.params import Config

    return Config().replace(scenario={"t_end": 2.0, **scenario})


GRID = ("-20:100:20", "0.1,0.5,1,1.5,2")  # 7 forces x 5 durations = 35 cells


def held_sweep(out, config, grid, **options):
    """``runs.run_sweep`` under the folder's lock, taken once as a run's entry takes it."""
    from mjx_balance.runs import run_sweep
    from mjx_balance.store.folder import folder_lock

    with folder_lock(out):
        return run_sweep(out, config, grid, **options)


def held_table(out, config, forces, **options):
    """``runs.run_table`` under the folder's lock, as :func:`held_sweep`."""
    from mjx_balance.runs import run_table
    from mjx_balance.store.folder import folder_lock

    with folder_lock(out):
        return run_table(out, config, forces, **options)


def sweep_fake(out, fake, chunk=8, config=None):
    from mjx_balance.runs.grid import Grid

    config = config or tiny_config()
    return held_sweep(
        out, config, Grid.of(*GRID, config), run_batch=fake, chunk=chunk, progress=False, say=None
    )


def expected_max_time(force, c, t_end, resolution=0.01):
    """The stand-in's max acting time of ``force``: the longest multiple of ``resolution``
    below c / |F| (0 if none), within t_end."""
    steps = np.arange(1, int(round(t_end / resolution)) + 1)
    ok = abs(force) * np.round(steps * resolution, 12) < c
    return (
        0.0
        if not ok[0]
        else float(np.round(steps[np.argmin(ok) - 1 if not ok.all() else -1] * resolution, 12))
    )


def expected_area(c: float) -> float:
    """The stand-in's recovered cells' area on the grid forces 0:40:10 x durations 0.5, 1, 2 s
    (cell bounds half-way, outer bounds on the ends)."""
    forces, durations = np.arange(0, 41, 10.0), np.array([0.5, 1.0, 2.0])
    wf = np.diff(np.concatenate([[0], (forces[1:] + forces[:-1]) / 2, [40]]))
    wd = np.diff(np.concatenate([[0.5], (durations[1:] + durations[:-1]) / 2, [2.0]]))
    ok = forces[:, None] * durations[None, :] < c
    return float((wf[:, None] * wd[None, :] * ok).sum())


CLI_GRID = ["--forces", "0:40:10", "--durations", "0.1,0.5,1.0", "--chunk", "4"]  # 15 cells


def cli_sweep(out: Path, *extra: str) -> int:
    """``mjx-balance sweep`` of CLI_GRID into ``out`` in this process (its exit code)."""
    from mjx_balance.cli import main

    return main(["sweep", *CLI_GRID, "--out", str(out), *extra])


# -- the batched path's controller in the reference's loop ----------------------------------------


class AdmmMPC:
    """The batched path's controller (the float32 ADMM, warm-started as in kernel.period) in
    the reference's closed loop: the reference then differs from the batched path only in its
    physics (MuJoCo C in float64)."""

    def __init__(self, runner):
        import jax

        from mjx_balance.control import admm as admm_mod

        self.qp, self._data, settings = runner.qp, runner.arrays.qp, runner.static.settings
        self._step = np.asarray(runner.arrays.rate_step)  # float32, as the kernel holds it
        self._solve = jax.jit(
            lambda x, w, o, f: admm_mod.admm_solve(self._data, x, w, settings, o, f)
        )
        self.reset()

    def reset(self) -> None:
        from mjx_balance.control import admm as admm_mod

        self._warm = admm_mod.initial_warm(self._data)
        self._last = np.zeros(2, np.float32)  # the input applied last (the kernel's u_last)

    def solve(self, x0, offset=None, first=None):
        import jax.numpy as jnp

        from mjx_balance.control import admm as admm_mod
        from mjx_balance.control.qp import rate_bounds

        offset = np.zeros(self.qp.m) if offset is None else offset  # zero: the plain QP
        # the rate limit's bounds as the kernel forms them, in float32 from its own last input
        # and step (the reference's float64 `first` can round an ulp apart); no limit: the
        # kernel's [-inf, inf] (the plain QP's numbers, bit for bit)
        if first is None:
            first = np.array([[-np.inf] * 2, [np.inf] * 2])
        else:
            first = rate_bounds(np, self._last, self._step)
        res = self._solve(
            jnp.asarray(x0, jnp.float32),
            self._warm,
            jnp.asarray(offset, jnp.float32),
            jnp.asarray(first, jnp.float32),
        )
        self._warm = admm_mod.ADMMWarm(*(w.astype(jnp.float32) for w in res.warm_next))
        u0 = np.asarray(res.u0, np.float32)
        self._last = np.where(np.isfinite(u0), u0, 0).astype(np.float32)
        return (
            np.asarray(res.u0, float),
            np.asarray(res.z, float),
            bool(res.status == admm_mod.SOLVED),
            float(res.prim_res),
        )


# -- figures' input -------------------------------------------------------------------------------


def assert_cells_like_the_reference(config, frame: pd.DataFrame, cells, mpc) -> list[str]:
    """Each batched cell of ``frame`` (one row per (force, duration) of ``cells``) against the
    reference run with the same MPC (``mpc``, e.g. :class:`AdmmMPC`): the same outcome, the
    same fall sample, and the energies within ``margins.closed_loop_rounding`` (the float32
    controls' rounding through the loop's gain, grown after an infeasible QP when it falls).
    Returns the reference's outcomes."""
    import margins  # the tolerances' module (tests/margins.py)

    from mjx_balance.reference import loop as reference

    outcomes = []
    for b, (force, duration) in enumerate(cells):
        ref = reference.simulate_scenario(config, force, duration, record=False, mpc=mpc)[0]
        mine = frame.iloc[b]
        outcomes.append(ref["outcome"])
        assert mine.outcome == ref["outcome"], (force, duration)
        margins.within(
            mine.fall_time,
            ref["fall_time"],
            atol=1e-12,
            msg=(force, duration),
            why="the same fall sample (both compute its time as k dt)",
        )
        tol = margins.closed_loop_rounding(config, ref, force, duration)
        for key in ("energy_ankle", "energy_hip", "energy_u1", "energy_u2"):
            margins.within(
                mine[key],
                ref[key],
                rtol=tol[key],
                atol=1e-9,
                msg=(key, force),
                why="float32 ADMM rounding x the loop's gain, grown after an "
                "infeasible QP when it falls (margins.closed_loop_rounding)",
            )
    return outcomes


# -- certified early stops against full-length runs -----------------------------------------------

# Columns a certified stop leaves exactly as the full-length run has them (docs/engine.md,
# "Certified recovery").
CERTIFIED_EXACT = (
    "outcome",
    "fall_time",
    "settle_time",
    "nonconverged_solves",
    "ankle_saturation_fraction",
    "hip_saturation_fraction",
    "max_bound_violation",
)
CERTIFIED_INTEGRALS = (
    "energy_ankle",
    "energy_hip",
    "energy_total",
    "work_ankle",
    "work_hip",
    "energy_u1",
    "energy_u2",
    "work_u1",
    "work_u2",
    "study_energy_u1",
    "study_energy_u2",
    "study_energy_total",
)
# Energies and work of a certified scenario: the linear prediction covers 2 s after the
# certificate, what comes later (a state decayed by e^-2 or more in its slowest mode) is left
# out; measured largest relative difference 1.1e-3 (work_hip, mjx-balance bench, 256 scenarios).
ENERGY_RTOL = 5e-3


def peak_floors() -> dict[str, float]:
    """The noise floor of each peak column (certificate.py, rule 5): below it a certified peak
    may lie under the full run's, by less than the floor."""
    from mjx_balance.control import certificate as cert

    pitch = cert.PITCH_FLOOR + cert.PITCH_PER_COP * cert.COP_FLOOR
    return {
        "peak_ankle": cert.ANGLE_FLOOR,
        "peak_hip": cert.ANGLE_FLOOR,
        "peak_tau_ankle": cert.TORQUE_FLOOR,
        "peak_tau_hip": cert.TORQUE_FLOOR,
        "peak_foot_pitch": pitch,
    }


def assert_certified_like_full_length(early, full, certified, config, jitter) -> None:
    """The summaries of scenarios stopped by the certificate (``certified``, bool) against
    their full-length runs, by the documented rule (docs/engine.md, "Certified recovery"):
    CERTIFIED_EXACT identical; a peak identical where the certified one reaches its noise floor,
    and below it no lower than the certified one and below the floor; max_residual identical or
    below the ADMM's tolerance near rest; energies and work within ENERGY_RTOL plus the energy
    of the rest jitter over the skipped seconds (``jitter``: per column, what a 0-N run spends
    over the whole window in the full-length run). ``early``/``full``: summary columns."""
    import margins  # the tolerances' module (tests/margins.py)

    c = np.asarray(certified, bool)
    for column in CERTIFIED_EXACT:
        assert np.array_equal(early[column][c], full[column][c], equal_nan=True), column
    for column, floor in peak_floors().items():
        e, f = np.asarray(early[column])[c], np.asarray(full[column])[c]
        above = e >= floor
        assert np.array_equal(e[above], f[above]), column
        assert ((e[~above] <= f[~above]) & (f[~above] < floor)).all(), (column, e, f)
    # near rest every QP row (inputs in N m, angles in rad, CoP and CoM in m) is far below 1,
    # so a converged solve there (nonconverged_solves is exact) has a primal residual of at most
    # eps_abs + eps_rel * 1 (admm.py's stopping rule)
    ctrl = config.controller
    tol = ctrl.admm_eps_abs + ctrl.admm_eps_rel
    e, f = np.asarray(early["max_residual"])[c], np.asarray(full["max_residual"])[c]
    assert ((e == f) | ((e < f) & (f <= tol))).all(), (e, f)
    for column in CERTIFIED_INTEGRALS:
        margins.within(
            np.asarray(early[column])[c],
            np.asarray(full[column])[c],
            rtol=ENERGY_RTOL,
            atol=2 * abs(jitter[column]) + 1e-9,
            msg=column,
            why="the linear prediction's 2 s, the decayed state left out "
            "(ENERGY_RTOL), and the rest jitter's energy over the skipped "
            "seconds: at most a 0-N run's over the window, measured in the same "
            "run, twice for the jitter's variation from run to run",
        )


def synthetic_series(t_end=4.0, dt=0.01, duration=0.1) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Three synthetic runs: 0 N (still), 50 N (recovers, settles by ~1.1 s), 120 N (falls at
    0.9 s, its angle growing far beyond the others)."""
    frames, summary = [], []
    t = np.arange(1, int(round(t_end / dt)) + 1) * dt
    for i, (force, outcome) in enumerate(
        ((0.0, "recovered"), (50.0, "recovered"), (120.0, "fell"))
    ):
        if outcome == "fell":
            tt = t[t <= 0.9]
            q = 0.05 * np.exp(4 * tt)
        else:
            tt = t
            q = force * 1e-3 * tt * np.exp(-6 * tt)
        frame = pd.DataFrame(
            {
                "scenario": i,
                "force": force,
                "duration": duration,
                "convention": "paper",
                "time": tt,
                "q_a": q,
                "q_h": -q,
                "dq_a": np.gradient(q, dt),
                "dq_h": -np.gradient(q, dt),
                "x1": q,
                "x2": 0.5 * q,
                "x3": 0.0,
                "x4": 0.0,
                "foot_x": 0.0,
                "foot_z": 0.0,
                "foot_pitch": 0.0,
                "u1": -400 * q,
                "u2": 50 * q,
                "tau_ankle": -600 * q,
                "tau_hip": 50 * q,
                "cop": 0.5 * q,
                "com": 0.3 * q,
                "energy_ankle": np.cumsum(np.abs(q)),
                "energy_hip": 0.0,
                "energy_total": np.cumsum(np.abs(q)),
            }
        )
        frames.append(frame)
        summary.append(
            {"force": force, "duration": duration, "convention": "paper", "outcome": outcome}
        )
    return pd.concat(frames, ignore_index=True), pd.DataFrame(summary)


def push_energy(force, duration):
    """A made-up energy of a push [J]: 1 + F T, growing with the impulse."""
    return 1.0 + force * duration


def grid_cells(forces, durations, rule) -> dict:
    """Every (force, duration) pair of a grid (forces outer) as floats, with its outcome
    ``rule(force, duration)``: the ``cells`` of :func:`fake_region`."""
    return {(float(f), float(d)): rule(f, d) for f in forces for d in durations}


def fake_region(
    cells: dict, *, convention="paper", energy_total=push_energy, **columns
) -> pd.DataFrame:
    """FAKE region frame (a sweep's summary rows) for figures and studies: one row per cell of
    ``cells`` ({(force, duration): outcome}, in its order; :func:`grid_cells` for a grid) with
    force, duration, outcome, then ``convention`` and ``energy_total`` (None: no such column)
    and the further ``columns``: each a function of (force, duration) or one value per cell."""
    keys = list(cells)
    frame = pd.DataFrame(
        {
            "force": [float(f) for f, _ in keys],
            "duration": [float(d) for _, d in keys],
            "outcome": list(cells.values()),
        }
    )
    if convention is not None:
        frame["convention"] = convention
    for name, column in {"energy_total": energy_total, **columns}.items():
        if column is not None:
            frame[name] = [column(f, d) for f, d in keys] if callable(column) else list(column)
    return frame


# -- the command line's refusals ------------------------------------------------------------------


def run_cli(argv: list[str], capsys) -> tuple[int, str]:
    """(exit code, stderr) of cli.main(argv); argparse's errors exit through SystemExit."""
    from mjx_balance import cli

    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def assert_refused(code: int, err: str, *words: str, exit_code: int = 2) -> None:
    """Exit 2 (1 for a failure during the work) and a single error line naming ``words``, last
    on stderr; with no usage before it, stderr is that one line."""
    assert code == exit_code, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    errors = [line for line in lines if "error:" in line]
    assert len(errors) == 1 and errors[0] == lines[-1], err
    assert lines[-1].startswith("mjx-balance") and "error: " in lines[-1]
    if not lines[0].startswith("usage:"):
        assert len(lines) == 1, err
    for word in words:
        assert word in lines[-1], err


def signal_where_exceptions_are_dropped(where: str, signum: int) -> None:
    """Send ``signum`` to this process from inside a GC callback, a ``__del__`` or a weakref
    callback, and run bytecode there, so that Python runs the handler in that callback."""

    def deliver(*_):
        os.kill(os.getpid(), signum)
        for _ in range(1000):  # the handler runs at one of these bytecodes, in the callback
            pass

    if where == "gc":

        def once(phase, _info):
            if phase == "start":
                gc.callbacks.remove(once)
                deliver()

        gc.callbacks.append(once)
        gc.collect()
    elif where == "del":

        class Dying:
            def __del__(self):
                deliver()

        Dying()
    else:

        class Target:
            pass

        target = Target()
        ref = weakref.ref(target, deliver)
        del target
        assert ref() is None
