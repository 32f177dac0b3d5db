"""The installed versions: the package's (``0.0.0+local`` when running from a source tree), and
the MuJoCo pair the physics needs (:func:`check_mujoco`).

mujoco-mjx ships inside MuJoCo's ``mujoco`` package and must be the same release as mujoco;
pyproject.toml pins both to :data:`MUJOCO` (mujoco-mjx's newest release; MuJoCo 4.0.0 is a
meta-package over mujoco-core and mujoco-studio with no mujoco-mjx of its own). Another package
can still drag mujoco to another release, so the physics refuses a mismatched pair at its first
call (``model.mjcf.build_model``, ``rollout.physics``), not at import: ``import mjx_balance`` and
``mjx-balance --version`` stay light and work.

The same first call turns MuJoCo's own log off (:func:`quiet_mujoco_log`): by default MuJoCo C
appends each warning (``Nan, Inf or huge value in QACC``...) to ``MUJOCO_LOG.TXT`` in the working
folder, outside any ``--out``, and prints it on stdout. A run reads the same fault from its state
instead (the ``diverged`` outcome, docs/outputs.md), so the log adds nothing a run keeps.
"""

from __future__ import annotations

import functools
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("mjx_balance")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+local"

MUJOCO = "3.17.0"  # the release pyproject.toml pins mujoco and mujoco-mjx to
INSTALL = f'pip install "mujoco=={MUJOCO}" "mujoco-mjx=={MUJOCO}"'


class InstallError(RuntimeError):
    """The installed packages cannot run this; the one-line message says what to install.
    The command line prints it as one line and exits with 1."""


def installed(distribution: str) -> str | None:
    """An installed distribution's version, None if it is not installed."""
    try:
        return version(distribution)
    except PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=1)
def mujoco_versions() -> tuple[str | None, str | None]:
    """(mujoco, mujoco-mjx) as installed (None: not installed). MuJoCo 4's ``mujoco`` package
    comes from mujoco-core: its version counts when the ``mujoco`` distribution is missing."""
    return installed("mujoco") or installed("mujoco-core"), installed("mujoco-mjx")


def check_mujoco(*, mjx: bool = False) -> None:
    """Refuse, with :class:`InstallError`, an installed mujoco / mujoco-mjx pair of different
    releases and, with ``mjx`` (the MJX physics and the batched paths), a missing mujoco-mjx.
    MuJoCo's C physics alone (the scalar reference) runs without mujoco-mjx. Then MuJoCo's log
    is turned off (:func:`quiet_mujoco_log`)."""
    mujoco, mujoco_mjx = mujoco_versions()
    found = f"mujoco {mujoco or 'not installed'}, mujoco-mjx {mujoco_mjx or 'not installed'}"
    if mujoco_mjx is None and mjx:
        raise InstallError(
            f"the batched physics needs mujoco-mjx of the same release as mujoco "
            f"(installed: {found}; mjx_balance pins both to {MUJOCO}): {INSTALL}"
        )
    if mujoco_mjx is not None and mujoco != mujoco_mjx:
        raise InstallError(
            f"mujoco and mujoco-mjx must be the same release (installed: {found}; "
            f"mjx_balance pins both to {MUJOCO}): {INSTALL}"
        )
    quiet_mujoco_log()


@functools.lru_cache(maxsize=1)
def quiet_mujoco_log() -> None:
    """MuJoCo C writes no log file and prints no warning, for this process (module docstring):
    every physics path starts at :func:`check_mujoco`, so no path can write MUJOCO_LOG.TXT."""
    import mujoco  # lazy: `import mjx_balance` and --version do not load MuJoCo

    log = mujoco.MjLogConfig.get()
    log.logto_file = False
    log.logto_console = False
    log.set()
