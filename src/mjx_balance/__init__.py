"""mjx_balance: standing-balance recovery under constrained MPC, batched with JAX and MuJoCo MJX."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("mjx_balance")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+local"
