"""Floor 1, model: the body and its equations — the configuration and its checks, subjects,
configuration files, the MJCF and the linearisation (docs/architecture.md, "The modules").

``params`` stays light (no NumPy at import): ``import mjx_balance`` loads it.
"""
