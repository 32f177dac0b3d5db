"""Floor 1, model: the body and its equations.

    params.py   the configuration (frozen dataclasses: body, controller, scenario), TOML I/O
    mjcf.py     the MuJoCo model generated from the body (MJCF), rest states
    linear.py   the model linearised about upright, discretisation, delay prediction

``params`` stays light (no NumPy at import): ``import mjx_balance`` loads it.
"""
