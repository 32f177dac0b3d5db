"""How far the batched float32 ADMM's action is from OSQP's as the QP's conditioning grows: the
measurement behind the rule cond(H) x eps_float32 < 1 (``runs.folders.check_batched``,
docs/reliability.md).

    python -m mjx_balance.bench.conditioning

For each horizon and control period: cond(H) x eps_float32 (``qp.float32_conditioning``), and
the largest difference between the ADMM's first input (float32, the package's settings) and
OSQP's (float64, eps 1e-7) over a few states near rest, relative to the input's range.
"""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import osqp
import scipy.sparse as sp

from ..control import admm
from ..control.osqp_mpc import solved
from ..control.qp import build_qp, float32_conditioning
from ..model.params import Config

SETTINGS = [{"controller": {"horizon": n}} for n in (20, 40, 60, 80, 100)] + [
    {"scenario": {"control_dt": dt}} for dt in (0.02, 0.03, 0.05)
]


def osqp_first_input(qp, x0: np.ndarray) -> np.ndarray | None:
    """OSQP's first input at ``x0`` (eps 1e-7, no polishing), None if it does not solve."""
    lower, upper = qp.bounds(x0)
    solver = osqp.OSQP()
    solver.setup(
        sp.csc_matrix(np.triu(qp.H)),
        qp.linear_term(x0),
        sp.csc_matrix(qp.C),
        lower,
        upper,
        eps_abs=1e-7,
        eps_rel=1e-7,
        verbose=False,
        polishing=False,
        max_iter=20000,
    )
    result = solved(solver)
    return np.asarray(result.x[:2]) if result.info.status == "solved" else None


def measure(changes: dict, states: int = 4, seed: int = 0) -> dict:
    """cond(H) x eps and the ADMM's worst first-input error for one configuration change."""
    config = Config().replace(**changes)
    qp = build_qp(config.controller, config.body, config.scenario.control_dt)
    settings = admm.settings_from_controller(config.controller)
    data = admm.build_admm(qp, settings, jnp.float32)
    rng = np.random.default_rng(seed)
    x0 = np.zeros((states, 4))
    x0[:, 0] = rng.uniform(-0.03, 0.03, states)
    x0[:, 2] = rng.uniform(-0.2, 0.2, states)
    warm = jax.tree_util.tree_map(
        lambda w: jnp.broadcast_to(w, (states, *w.shape)), admm.initial_warm(data)
    )
    solve = jax.jit(admm.admm_solve_batch, static_argnums=(3,))
    out = solve(data, jnp.asarray(x0, jnp.float32), warm, settings)
    z = np.asarray(out[0] if isinstance(out, tuple) else out.z)
    span = float(np.min(np.asarray(qp.input_upper) - np.asarray(qp.input_lower)))
    errors, failed = [], 0
    for i in range(states):
        truth = osqp_first_input(qp, x0[i])
        if truth is None:
            failed += 1
        else:
            errors.append(float(np.abs(z[i][:2] - truth).max()) / span)
    return {
        "changes": changes,
        "cond_x_eps": float32_conditioning(qp),
        "worst_error_of_range": max(errors) if errors else None,
        "osqp_failed": failed,
    }


if __name__ == "__main__":
    with jax.enable_x64(False):
        for changes in SETTINGS:
            print(json.dumps(measure(changes)), flush=True)
