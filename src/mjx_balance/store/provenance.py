"""Provenance: what ran, where and when, recorded in a folder's manifest (``runs``): one record
per run that worked in the folder (versions, physics path, device, git commit, command line,
start and end times, how it ended). The records differ between runs by design and are never
compared when a run resumes a folder.
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import subprocess
import sys
import uuid
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterator

from ..runtime.version import __version__
from .files import MANIFEST, write_text


def now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


# This process's run: one record per output folder it works in, updated at every manifest
# write and when the folder's lock is let go (end time, status).
_RUN: dict[str, Any] = {
    "run_id": uuid.uuid4().hex[:12],
    "started": now(),
    "command": None,
    "physics": "mjx",
}


@contextmanager
def run_context(*, command: str | None = None, physics: str | None = None) -> Iterator[None]:
    """The command line (or API call) and the physics path that this process's manifest
    records name, while in the block (an outer context's command is kept: the command line
    that called the API is what ran)."""
    saved = dict(_RUN)
    if command is not None and _RUN["command"] is None:
        _RUN["command"] = command
    if physics is not None:
        _RUN["physics"] = physics
    try:
        yield
    finally:
        _RUN["command"], _RUN["physics"] = saved["command"], saved["physics"]


def note_physics(physics: str) -> None:
    """The physics this process's work in the current run context uses (the rollout, once
    built, says which path it runs: "mjx", or "mujoco" for MuJoCo C)."""
    _RUN["physics"] = physics


def _distribution_version(name: str) -> str | None:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return None


def versions() -> dict[str, str | None]:
    """The versions of the package and of what computes its results (no import of JAX)."""
    return {
        "package": __version__,
        "python": platform.python_version(),
        "jax": _distribution_version("jax"),
        "jaxlib": _distribution_version("jaxlib"),
        "mujoco": _distribution_version("mujoco"),
        "mujoco_mjx": _distribution_version("mujoco-mjx"),
    }


# The numerical libraries a result's numbers pass through, beside JAX and MuJoCo (versions()).
NUMERICAL_PACKAGES = ("numpy", "scipy", "osqp", "pandas", "pyarrow", "matplotlib")


def environment() -> dict[str, Any]:
    """Everything a result depends on, for a methods section or a bug report.

    The versions (the package, Python, JAX, jaxlib, MuJoCo and the numerical libraries), the
    numerics fingerprint (x64, the XLA flags that change numbers, the matmul precision, the CPU's
    vector ISA as XLA targets it), every XLA flag, the devices JAX runs on (this starts JAX:
    call it where a run would), the operating system and the git commit of a checkout.
    ``mjx-balance --version --verbose`` prints it.

    Returns:
        A dict of plain values.
    """
    import jax  # lazy: started here to list the devices a run would use

    from ..runtime.fingerprint import numerics  # lazy: light, but only for this report

    jax.devices()
    found = numerics()
    return {
        **versions(),
        **{name: _distribution_version(name) for name in NUMERICAL_PACKAGES},
        "x64": found["x64"],
        "matmul_precision": found["matmul_precision"],
        "cpu_isa": found["cpu_isa"],
        "xla_flags": os.environ.get("XLA_FLAGS", "").split(),
        "result_xla_flags": found["xla_flags"],
        "device": device_record(),
        "os": platform.platform(),
        "git": git_record(),
    }


def environment_text(env: dict[str, Any]) -> str:
    """:func:`environment` as lines of ``name: value``."""

    def shown(value: Any) -> str:
        if isinstance(value, dict):
            return ", ".join(f"{k} {v}" for k, v in value.items()) or "-"
        if isinstance(value, list):
            return " ".join(str(v) for v in value) or "-"
        return "-" if value is None else str(value)

    width = max(len(name) for name in env)
    return "\n".join(f"{name + ':':{width + 1}} {shown(value)}" for name, value in env.items())


def device_record() -> dict[str, Any]:
    """JAX's devices when JAX has started in this process (platform, device kind, count); else
    the host's CPU (the scalar reference runs there, or JAX has not started yet)."""
    if "jax" in sys.modules:
        try:
            from jax._src import xla_bridge

            if xla_bridge._backends:
                import jax

                devices = jax.local_devices()
                return {
                    "platform": devices[0].platform,
                    "kind": devices[0].device_kind,
                    "count": len(devices),
                }
        except Exception:
            pass
    return {
        "platform": "cpu",
        "kind": platform.processor() or platform.machine(),
        "count": os.cpu_count() or 1,
    }


_GIT: dict[str, Any] = {}


def git_record() -> dict[str, Any]:
    """The git commit of the package's checkout (and whether it has uncommitted changes), when
    it runs from one; empty when it does not or git is missing (computed once per process)."""
    if _GIT:
        return dict(_GIT.get("record", {}))
    record: dict[str, Any] = {}
    here = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=10
        )
        if commit.returncode == 0 and commit.stdout.strip():
            record["git_commit"] = commit.stdout.strip()
            dirty = subprocess.run(
                ["git", "status", "--porcelain", "--untracked-files=no"],
                cwd=here,
                capture_output=True,
                text=True,
                timeout=30,
            )
            if dirty.returncode == 0:
                record["git_dirty"] = bool(dirty.stdout.strip())
    except (OSError, subprocess.SubprocessError):
        pass
    _GIT["record"] = record
    return dict(record)


def default_command() -> str:
    """The command line of this process, as a shell would take it back."""
    argv = list(sys.argv) or ["python"]
    if argv and argv[0].endswith(("/mjx-balance", "mjx_balance/__main__.py")):
        argv[0] = "mjx-balance" if argv[0].endswith("mjx-balance") else "python -m mjx_balance"
    return " ".join(shlex.quote(a) for a in argv)


def provenance() -> dict[str, Any]:
    """This run's provenance record (see the module docstring; docs/outputs.md, ``runs``)."""
    return {
        "run_id": _RUN["run_id"],
        "command": _RUN["command"] or default_command(),
        "started": _RUN["started"],
        "ended": None,
        "status": "running",
        **versions(),
        "physics": _RUN["physics"],
        "device": device_record(),
        **git_record(),
    }


def with_run(manifest: dict[str, Any], **changes: Any) -> dict[str, Any]:
    """``manifest`` with this run's record in its ``runs`` (added, or refreshed)."""
    runs = manifest.get("runs")
    runs = [r for r in runs if isinstance(r, dict)] if isinstance(runs, list) else []
    mine = next((r for r in runs if r.get("run_id") == _RUN["run_id"]), None)
    if mine is None:
        # This run writes the manifest under the folder's lock, so no other run is working in
        # it: a run still recorded as running ended without saying how (kill -9, a power loss).
        for other in runs:
            if other.get("status") == "running":
                other["status"] = "killed"
        mine = provenance()
        runs.append(mine)
    else:
        mine["device"] = device_record()
        mine["physics"] = _RUN["physics"]
    mine.update(changes)
    manifest["runs"] = runs
    return manifest


def finish_run(folder: Path, status: str) -> None:
    """Record the end time and how the run ended in the folder's manifest, if this run wrote
    one. A write that fails here is raised when the run completed (its results are whole but
    the manifest would still say it is running); after a failed or interrupted run it is not
    reported again (the disk that just failed the run)."""
    path = folder / MANIFEST
    try:
        manifest = json.loads(path.read_text())
        runs = manifest.get("runs") if isinstance(manifest, dict) else None
        if not isinstance(runs, list) or not any(
            isinstance(r, dict) and r.get("run_id") == _RUN["run_id"] for r in runs
        ):
            return
        text = json.dumps(with_run(manifest, ended=now(), status=status), indent=2) + "\n"
    except Exception:  # no manifest of this run's: nothing to record
        return
    try:
        write_text(text, path)
    except OSError:
        if status == "completed":
            raise
