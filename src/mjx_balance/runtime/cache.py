"""JAX's persistent compilation cache, on by default, in the user's cache directory.

Compiling the batched closed loop takes most of a short run's time (tens of seconds on a
2-core CPU); with JAX's own persistent cache the executable of a run is written to disk and the
next process with the same program loads it instead of compiling. JAX keys each entry on the
program (its HLO, so its shapes and every value compiled into it), the compile options, the
XLA flags (so the deterministic flags and the host device count), the backend and the jax /
jaxlib versions: an entry is only reused where it is the same executable. A configuration
that only changes values passed to the program at run time (body masses, weights, the
convention's matrices) reuses the entry, as it reuses the compiled function within one process
(``rollout.runner``'s in-process cache).

Where (:func:`cache_dir`): ``$MJX_BALANCE_CACHE_DIR`` when set (``off``, ``0``, ``no``,
``false`` or ``none`` turn the cache off), else the user's cache directory:
``$XDG_CACHE_HOME/mjx_balance/jax`` (``~/.cache/mjx_balance/jax`` without XDG_CACHE_HOME) on
Linux, ``~/Library/Caches/mjx_balance/jax`` on macOS, ``%LOCALAPPDATA%\\mjx_balance\\jax`` on
Windows. A ``jax_compilation_cache_dir`` that the user configured (JAX_COMPILATION_CACHE_DIR or
``jax.config.update``) is left alone. ``mjx-balance --no-cache`` turns it off for one run.
Delete the folder to empty it; JAX does not bound its size by default.

The cache heals (:func:`heal`, called by :func:`enable`): JAX writes an entry in place and never
replaces one that exists, so an entry cut short (a full disk, a killed process) or damaged would
make every later run fail to read it and compile again, with at most a warning. Each entry
not yet checked is decompressed once (zlib's checksum, or zstd's frame); one that fails is
removed, with one line in the log, and the next compile writes it anew. The entries found whole
are remembered (name, size, mtime) in ``verified.json`` so that a run checks only new ones.

Importing this module does not import JAX.
"""

from __future__ import annotations

import json
import logging
import os
import sys
import zlib
from pathlib import Path

log = logging.getLogger(__name__)

ENV = "MJX_BALANCE_CACHE_DIR"
OFF = ("off", "0", "no", "false", "none", "")

# What enable() set, so that a second call is a no-op and tests can see it.
_state: dict[str, str | None] = {"dir": None}


def user_cache_root() -> Path:
    """The user's cache directory (the platformdirs convention, without the dependency)."""
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches"
    if os.name == "nt":
        return Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    # The XDG spec: a relative path is invalid and is ignored.
    return Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".cache"


def cache_dir() -> Path | None:
    """The folder of the persistent compilation cache, or None when it is turned off."""
    value = os.environ.get(ENV)
    if value is not None:
        if value.strip().lower() in OFF:
            return None
        return Path(value).expanduser()
    return user_cache_root() / "mjx_balance" / "jax"


def disable() -> None:
    """Turn the cache off for this process (``--no-cache``): as ``MJX_BALANCE_CACHE_DIR=off``,
    so child processes (the benchmark's workers) inherit it."""
    os.environ[ENV] = "off"


def enable() -> str | None:
    """Point JAX's persistent compilation cache at :func:`cache_dir` (created if missing) and
    lower JAX's thresholds so that every executable is kept (JAX keeps only those that took a
    second or more to compile by default). Returns the folder in use, or None when the cache is
    off (:func:`cache_dir` None), the folder cannot be created, or the user configured JAX's
    own cache folder (then that one is used and reported). Safe to call again; it imports JAX.
    """
    import jax

    own = jax.config.jax_compilation_cache_dir  # type: ignore[attr-defined]  # jax.config's flags are set at run time
    if own and own != _state["dir"]:
        return own  # the user's own setting wins
    folder = cache_dir()
    if folder is None:
        if _state["dir"] is not None:  # turned off after being on in this process
            jax.config.update("jax_compilation_cache_dir", None)
            _reset()
            _state["dir"] = None
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        log.warning(
            "note: compilation cache off: cannot create %s (%s)", folder, exc.strerror or exc
        )
        return None
    path = str(folder)
    if _state["dir"] == path:
        return path
    heal(folder)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    # JAX decides once per process whether it uses the cache, at its first compile: make it
    # decide again if something was compiled before this call.
    _reset()
    _state["dir"] = path
    log.debug("persistent compilation cache: %s", path)
    return path


ENTRY_SUFFIX = "-cache"  # JAX's file cache: <key>-cache (and <key>-atime beside it)
VERIFIED = "verified.json"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


def _whole(data: bytes) -> bool | None:
    """Whether a cache entry decompresses completely (None: zstd without the module here)."""
    if data[:4] == ZSTD_MAGIC:
        try:
            import zstandard  # optional: JAX uses it when installed
        except ImportError:
            return None
        try:
            zstandard.ZstdDecompressor().decompressobj().decompress(data)
            return True
        except zstandard.ZstdError:
            return False
    try:
        decompressor = zlib.decompressobj()
        decompressor.decompress(data)
        return decompressor.eof and not decompressor.unused_data
    except zlib.error:
        return False


def heal(folder: str | Path) -> list[str]:
    """Remove the persistent cache's entries in ``folder`` that are cut short or damaged (they
    do not decompress); returns their file names and logs one line when there are any. Entries
    checked before and unchanged since (``verified.json``: name, size, mtime) are not read
    again. Never raises: a cache it cannot read or clean is left to JAX."""
    folder = Path(folder)
    try:
        known = json.loads((folder / VERIFIED).read_text())
        known = known if isinstance(known, dict) else {}
    except (OSError, ValueError):
        known = {}
    checked, removed = {}, []
    try:
        entries = sorted(folder.glob(f"*{ENTRY_SUFFIX}"))
    except OSError:
        return []
    for entry in entries:
        try:
            stat = entry.stat()
            stamp = [stat.st_size, stat.st_mtime_ns]
            if known.get(entry.name) == stamp:
                checked[entry.name] = stamp
                continue
            whole = _whole(entry.read_bytes())
            if whole is False:
                entry.unlink()
                (folder / (entry.name[: -len(ENTRY_SUFFIX)] + "-atime")).unlink(missing_ok=True)
                removed.append(entry.name)
            elif whole:
                checked[entry.name] = stamp
        except OSError:
            continue
    if removed:
        log.warning(
            "compilation cache: removed %d damaged entr%s from %s (cut short or "
            "corrupt); %s compiled again once",
            len(removed),
            "y" if len(removed) == 1 else "ies",
            folder,
            "it is" if len(removed) == 1 else "they are",
        )
    if checked != known or removed:
        try:
            tmp = folder / f".{VERIFIED}.{os.getpid()}.tmp"
            tmp.write_text(json.dumps(checked))
            os.replace(tmp, folder / VERIFIED)
        except OSError:
            pass
    return removed


def _reset() -> None:
    try:
        from jax.experimental.compilation_cache import compilation_cache

        compilation_cache.reset_cache()
    except Exception:
        pass


class CompileCounter:
    """Counts JAX's compile events while it is registered (``with CompileCounter() as c``):
    ``requests`` (executables JAX needed: XLA compilations or persistent-cache loads),
    ``cache_hits`` and ``cache_misses`` (of the persistent cache), ``compiles`` (executables
    XLA built: requests less cache hits), ``compile_seconds`` (time in those requests, loads
    included) and ``retrieval_seconds`` (time spent loading cache entries); ``compiled`` and
    ``loaded``: the names of the functions XLA compiled (with seconds) and of those loaded
    from the persistent cache, in order (JAX reports a cache hit just before the request's
    duration, in the same thread)."""

    BACKEND_COMPILE = "/jax/core/compile/backend_compile_duration"
    HITS = "/jax/compilation_cache/cache_hits"
    MISSES = "/jax/compilation_cache/cache_misses"
    RETRIEVAL = "/jax/compilation_cache/cache_retrieval_time_sec"

    def __init__(self) -> None:
        self.requests = 0
        self.cache_hits = 0
        self.cache_misses = 0
        self.compile_seconds = 0.0
        self.retrieval_seconds = 0.0
        self.compiled: list[tuple[str, float]] = []
        self.loaded: list[str] = []
        self._hit = False
        self._active = False

    def _event(self, name: str, **_kwargs) -> None:
        if not self._active:
            return
        if name == self.HITS:
            self.cache_hits += 1
            self._hit = True
        elif name == self.MISSES:
            self.cache_misses += 1

    def _duration(self, name: str, seconds: float, **kwargs) -> None:
        if not self._active:
            return
        if name == self.BACKEND_COMPILE:
            self.requests += 1
            self.compile_seconds += float(seconds)
            fun = str(kwargs.get("fun_name", "?"))
            if self._hit:
                self.loaded.append(fun)
            else:
                self.compiled.append((fun, float(seconds)))
            self._hit = False
        elif name == self.RETRIEVAL:
            self.retrieval_seconds += float(seconds)

    def __enter__(self) -> "CompileCounter":
        from jax import monitoring

        self._active = True
        monitoring.register_event_listener(self._event)  # type: ignore[arg-type]  # JAX calls it by position: its protocol's parameter names differ
        monitoring.register_event_duration_secs_listener(self._duration)  # type: ignore[arg-type]  # (as above)
        return self

    def __exit__(self, *exc) -> None:
        self._active = False
        try:
            from jax._src import monitoring as _monitoring

            _monitoring.unregister_event_listener(self._event)  # type: ignore[arg-type]  # (as in __enter__)
            _monitoring.unregister_event_duration_listener(self._duration)  # type: ignore[arg-type]  # (as in __enter__)
        except Exception:
            pass

    @property
    def compiles(self) -> int:
        return self.requests - self.cache_hits

    def as_dict(self) -> dict[str, float | int | list[object]]:
        return {
            "requests": self.requests,
            "compiles": self.compiles,
            "cache_hits": self.cache_hits,
            "cache_misses": self.cache_misses,
            "compile_seconds": round(self.compile_seconds, 3),
            "retrieval_seconds": round(self.retrieval_seconds, 3),
            "compiled": [[fun, round(sec, 3)] for fun, sec in self.compiled],
            "loaded": list(self.loaded),
        }
