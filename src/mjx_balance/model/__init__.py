"""Floor 1, model: the body and its equations.

    params.py        the configuration's records (frozen dataclasses: body, controller,
                     scenario), their checks and the limits that link them
    subject.py       a person: the segment table, Subject, --subject and participant CSV files
    config_files.py  configuration files (TOML) and --set overrides
    mjcf.py          the MuJoCo model generated from the body (MJCF), rest states
    linear.py        the model linearised about upright, discretisation, delay prediction

``params`` stays light (no NumPy at import): ``import mjx_balance`` loads it. ``subject`` is
imported here so that ``Config.replace(subject=...)`` works whichever module is imported first.
"""

from . import subject  # noqa: F401
