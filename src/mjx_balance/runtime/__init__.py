"""Floor 0, runtime: what every run needs before any model exists.

    xla.py       the XLA flags that make results schedule-independent (set before JAX starts)
    cache.py     JAX's persistent compilation cache (folder, on/off)
    compiled.py  the process-wide cache of compiled batch functions: the one compile path
    version.py   the installed versions: the package's, and the mujoco / mujoco-mjx pair that
                 the physics checks at its first call (check_mujoco, InstallError)

Nothing here imports JAX or MuJoCo at import time.
"""
