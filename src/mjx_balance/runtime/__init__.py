"""Floor 0, runtime: what every run needs before any model exists (the XLA flags, the
compilation caches, versions, signals, the numerics fingerprint). docs/architecture.md, "The
modules", maps its modules.

Nothing here imports JAX or MuJoCo at import time.
"""
