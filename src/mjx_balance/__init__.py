"""mjx_balance: standing-balance recovery under constrained MPC, batched with JAX and MuJoCo MJX.

The public API (``mjx_balance.api``, documented in the README)::

    import mjx_balance as mb
    summary, series = mb.simulate([20, 80], [0.1])            # scalar reference runs
    region = mb.sweep("0:150:10", [0.1, 0.2], mb.Config())     # batched MJX + ADMM region map
    table = mb.table([20, 50, 80], "my_body.toml")             # max acting time per force
    mb.region_map(region, ax=ax); mb.table_figure(table)        # figures (matplotlib)
    results = mb.load_report("out/report")                      # a saved report's tables

``import mjx_balance`` stays light: it sets XLA's flags before JAX starts and imports neither
JAX nor MuJoCo; the API functions import them when called.
"""

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

from .runtime.xla import deterministic_flags

# XLA options that make every scenario's result independent of its slot and batch (see
# rollout/engine.py); they only take effect if set before JAX starts its CPU backend.
deterministic_flags()

from .runtime.version import __version__  # noqa: E402 - after the flags
from .model.params import Config, ParameterError  # noqa: E402
from .model.config_files import load_config  # noqa: E402
from .model.subject import Subject  # noqa: E402

# The public functions, imported on first use (JAX, MuJoCo and pandas with them). Figures and
# saved reports, for notebooks: each figure function draws on the matplotlib Axes it is given
# (or a new figure) and returns the Figure.
_LAZY = {
    "simulate": "api", "sweep": "api", "table": "api", "compare": "api", "basin": "api",
    "cohort": "api", "scorecard": "api", "explore": "api", "references": "studies.references",
    "strategy_map": "figures.strategy",
    "load_report": "report.html:load_results",
    "region_map": "figures.region", "energy_map": "figures.region",
    "table_figure": "figures.region", "timeseries_figure": "figures.timeseries",
    "weight_figure": "figures.report", "conventions_figure": "figures.report",
    "region_numbers": "studies.catalog", "study": "studies.catalog",
    "study_reading": "studies.catalog:reading",
    "figure_style": "figures.style", "save_figure": "figures.style:save",
}

__all__ = ["Config", "ParameterError", "Subject", "__version__", "basin", "cohort", "compare",
           "conventions_figure", "explore", "energy_map", "load_config", "load_report", "region_map", "region_numbers",
           "references", "scorecard", "simulate", "strategy_map", "study", "study_reading", "sweep", "table",
           "table_figure",
           "timeseries_figure", "weight_figure", "figure_style", "save_figure"]


def __getattr__(name: str):
    if name in _LAZY:
        module, _, attribute = _LAZY[name].partition(":")
        return getattr(importlib.import_module("." + module, __name__), attribute or name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


# -- the modules' old names, for one release (0.1 -> 0.2: docs/architecture.md) ----------------
# ``from mjx_balance.params import Config`` or ``mjx_balance.sweep.definitions`` still import,
# with a DeprecationWarning naming the new module; the old module is the new one (one object).

LEGACY = {
    "_xla": "runtime.xla", "cache": "runtime.cache", "params": "model.params",
    "linear": "model.linear", "outcomes": "measures.outcomes", "metrics": "measures.metrics",
    "qp": "control.qp", "admm": "control.admm", "osqp_mpc": "control.osqp_mpc",
    "offset_free": "control.offset_free", "certificate": "control.certificate",
    "sweep": "runs", "sweep.store": "store.folder", "sweep.grid": "runs.grid",
    "sweep.chunks": "runs.chunks", "sweep.batch": "runs.batch",
    "sweep.progress": "runs.progress", "sweep.region": "runs.region",
    "sweep.acting_time": "runs.acting_time", "sweep.definitions": "runs.definitions",
    "sweep.cluster": "runs.cluster", "plots": "figures.timeseries",
    "region_plots": "figures.region", "animate": "figures.animation",
    "comparison": "studies.compare",
    "landscape": "studies.landscape", "sensitivity": "studies.sensitivity",
    "recovery_basin": "studies.basin", "report.run": "studies.experiments",
}


class _Legacy(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``mjx_balance.<old name>`` and hands out the module at its new name."""

    def find_spec(self, fullname, path=None, target=None):
        old = fullname[len(__name__) + 1:] if fullname.startswith(__name__ + ".") else None
        if old not in LEGACY:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = f"{__name__}.{LEGACY[spec.name[len(__name__) + 1:]]}"
        warnings.warn(f"{spec.name} is now {new} (the old name goes in the next release)",
                      DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module):
        pass  # the new module is already executed


class _Package(types.ModuleType):
    """This package: the name ``sweep`` stays the function (``help(mjx_balance.sweep)``) when
    the legacy subpackage ``mjx_balance.sweep`` is imported (Python binds a subpackage to its
    parent's attribute)."""

    def __setattr__(self, name, value):
        if name == "sweep" and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.meta_path.insert(0, _Legacy())
sys.modules[__name__].__class__ = _Package
