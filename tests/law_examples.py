"""Controllers a user would write (control/law.py's interface), for the tests: importable as
``law_examples:FACTORY`` because tests/ is on sys.path (pyproject.toml)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mjx_balance.control import law
from mjx_balance.model.params import Config


def init_integral(params):
    """The integral of the convention's positions, zero at every scenario's start."""
    return jnp.zeros(2, params["gain"].dtype)


def act_integral(params, x, state):
    """LQR plus a slow integral of the positions: a law that carries state."""
    integral = state + params["dt"] * x[:2]
    u = -(params["gain"] @ x) - params["ki"] * integral
    return u, integral, law.solved(jnp, x.dtype)


INTEGRAL = law.Law("integral", init_integral, act_integral)


def integral_lqr(config: Config, ki: float = 5.0) -> law.Controller:
    """The built-in LQR with an integral term of gain ``ki`` [N m / (rad s)]."""
    base = law.lqr(config)
    params = {
        "gain": base.params["gain"],
        "ki": np.float64(ki),
        "dt": np.float64(config.scenario.control_dt),
    }
    return law.Controller(INTEGRAL, params)


def broken(config: Config) -> law.Controller:
    """A factory that fails (its message must reach the user in one line)."""
    raise RuntimeError("no weights here")


def not_a_controller(config: Config):
    """A factory that returns the wrong thing."""
    return {"gain": 1.0}


def act_nan(params, x, state):
    return x[:2] * jnp.nan, state, law.solved(jnp, x.dtype)


def diverging(config: Config) -> law.Controller:
    """A law whose input is NaN: every scenario is a diverged status, never an exception."""
    return law.Controller(law.Law("nan", law.no_state, act_nan), {})


def act_three(params, x, state):
    return jnp.zeros(3, x.dtype), state, law.solved(jnp, x.dtype)


def three_inputs(config: Config) -> law.Controller:
    """A law whose input has 3 entries (refused before any run)."""
    return law.Controller(law.Law("three", law.no_state, act_three), {})


def act_branching(params, x, state):
    if x[0] > 0:  # Python control flow on a traced value: JAX cannot trace it
        return -x[:2], state, law.solved(jnp, x.dtype)
    return x[:2], state, law.solved(jnp, x.dtype)


def branching(config: Config) -> law.Controller:
    """A law that branches in Python on the state (refused before any run)."""
    return law.Controller(law.Law("branching", law.no_state, act_branching), {})


def act_growing(params, x, state):
    return -x[:2], jnp.concatenate([state, x[:1]]), law.solved(jnp, x.dtype)


def growing_state(config: Config) -> law.Controller:
    """A law whose state grows every period (the loop cannot carry it; refused)."""
    return law.Controller(law.Law("growing", init_integral, act_growing), {"gain": np.zeros(2)})
