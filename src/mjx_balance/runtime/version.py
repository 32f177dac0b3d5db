"""The installed package's version (``0.0.0+local`` when running from a source tree)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("mjx_balance")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+local"
