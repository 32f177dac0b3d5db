"""mjx_balance: standing-balance recovery under constrained MPC, batched with JAX and MuJoCo MJX."""

from importlib.metadata import PackageNotFoundError, version

from ._xla import deterministic_flags

# XLA options that make every scenario's result independent of its slot and batch (see
# rollout/engine.py); they only take effect if set before JAX starts its CPU backend.
deterministic_flags()

try:
    __version__ = version("mjx_balance")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+local"
