"""The process-wide cache of compiled batch functions: one place that compiles and keeps them.

Every compiled program of the batched closed loop (the padded batch of ``rollout.runner``, the
engine's block of ``rollout.engine``, the C path's period call of ``rollout.cpath``) is kept here
under a key of everything baked into it (tree structure, shapes and dtypes, static settings,
batch or slot count, devices, x64), so that runners of equal shapes share one executable. JAX's
persistent cache (``runtime.cache``) keeps them across processes.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable, NamedTuple

# Float32 products in full float32 precision: on NVIDIA GPUs JAX's default is TF32 (a 10-bit
# mantissa), with which the ADMM runs to its iteration cap in every control period and the
# physics drifts (BENCHMARKS.md, "On a GPU"; docs/engine.md).
MATMUL_PRECISION = "highest"

_COMPILED: dict[tuple, Any] = {}
_LOCK = threading.Lock()


class Compiled(NamedTuple):
    """One program built by :func:`get_or_compile`: its kind (the key's first element when
    that is a name, else ``"batch"``), the seconds ``build()`` took (a load from JAX's
    persistent cache included) and the key itself."""

    kind: str
    seconds: float
    key: tuple


_BUILT: list[Compiled] = []


def get_or_compile(key: tuple, build: Callable[[], Any]) -> Any:
    """The function compiled for ``key``, built by ``build()`` on the first request only.

    ``build`` runs under full float32 matmul precision (:data:`MATMUL_PRECISION`)."""
    with _LOCK:
        fn = _COMPILED.get(key)
    if fn is None:
        import jax  # lazy: this floor loads before the XLA flags are set

        t0 = time.perf_counter()
        with jax.default_matmul_precision(MATMUL_PRECISION):
            fn = build()
        seconds = time.perf_counter() - t0
        with _LOCK:
            if key not in _COMPILED:
                kind = key[0] if key and isinstance(key[0], str) else "batch"
                _BUILT.append(Compiled(kind, seconds, key))
            fn = _COMPILED.setdefault(key, fn)
    return fn


def charge(key: tuple, seconds: float) -> None:
    """Add ``seconds`` to the program built for ``key``: for a function that ``build()`` only
    wraps (``jax.jit``) and that compiles at its first call, the caller times that call."""
    with _LOCK:
        for i, c in enumerate(_BUILT):
            if c.key == key:
                _BUILT[i] = c._replace(seconds=c.seconds + seconds)
                return


def built() -> list[Compiled]:
    """Every program this process built through :func:`get_or_compile`, in order (kept after
    :func:`clear`, which only forgets the functions)."""
    with _LOCK:
        return list(_BUILT)


def is_compiled(key: tuple) -> bool:
    """Whether a function for ``key`` is in the cache."""
    with _LOCK:
        return key in _COMPILED


def clear() -> None:
    """Forget every compiled function (tests; the persistent cache is untouched)."""
    with _LOCK:
        _COMPILED.clear()
