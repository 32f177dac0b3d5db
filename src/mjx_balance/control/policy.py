"""A learned controller through the interface of ``law.py``: a small multilayer perceptron
from the state to the inputs, its weights read from a file (docs/model.md, "Bring your own
controller", "A learned policy").

The shipped weights (``data/policies/mlp_mpc.npz``) imitate the study's MPC on the study's
body in the paper convention; ``docs/scripts/fit_policy.py`` fits them (the MPC's first input
at states sampled from its own closed-loop runs and around upright). Nothing here trains: the
policy is loaded and run as any controller is, ``--controller mjx_balance.control.policy:mlp``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..model.params import Config, ParameterError
from . import law

SHIPPED = "mlp_mpc.npz"  # in data/policies/


def shipped_weights() -> Path:
    """The shipped weights file's path."""
    return Path(str(resources.files("mjx_balance") / "data" / "policies" / SHIPPED))


def forward(params: Any, x: Any) -> Any:
    """The network's input u [2] at state x [4]: x scaled by ``x_scale``, tanh hidden layers,
    a linear output scaled by ``u_scale``."""
    import jax.numpy as jnp

    h = x / params["x_scale"]
    layers = params["layers"]
    for weight, bias in layers[:-1]:
        h = jnp.tanh(weight @ h + bias)
    weight, bias = layers[-1]
    return (weight @ h + bias) * params["u_scale"]


def act(params: Any, x: Any, state: Any) -> tuple[Any, Any, law.Status]:
    """The policy's input at x (no state)."""
    import jax.numpy as jnp

    return forward(params, x), state, law.solved(jnp, x.dtype)


MLP = law.Law("mlp", law.no_state, act)


def read_weights(path: Path) -> dict[str, Any]:
    """The weights file's parameters: ``x_scale`` [4], ``u_scale`` [2], layers ``w0, b0, w1,
    b1, ...`` and the ``convention`` the policy was fitted in. ParameterError in one line when
    the file is missing or not such a file."""
    try:
        with np.load(path, allow_pickle=False) as data:
            files = dict(data)
    except (OSError, ValueError) as exc:
        raise ParameterError(f"policy weights {path}: cannot be read ({exc})") from None
    count = sum(1 for name in files if name.startswith("w"))
    needed = {"x_scale", "u_scale", "convention"} | {f"{k}{i}" for i in range(count) for k in "wb"}
    if count == 0 or not needed <= set(files):
        raise ParameterError(
            f"policy weights {path}: expected x_scale, u_scale, convention and w0, b0, ... "
            f"(got {', '.join(sorted(files))})"
        )
    layers = [(files[f"w{i}"], files[f"b{i}"]) for i in range(count)]
    return {
        "x_scale": files["x_scale"],
        "u_scale": files["u_scale"],
        "layers": layers,
        "convention": str(files["convention"]),
    }


def mlp(config: Config, weights: str = "") -> law.Controller:
    """The MLP policy of ``weights`` (a .npz file; "": the shipped one, fitted to the study's
    MPC). Refused in one line when the configuration's convention is not the policy's."""
    path = Path(weights) if weights else shipped_weights()
    read = read_weights(path)
    convention = read.pop("convention")
    if convention != config.controller.convention:
        raise ParameterError(
            f"policy weights {path}: fitted in the {convention} convention, the "
            f"configuration's is {config.controller.convention}"
        )
    return law.Controller(MLP, read)
