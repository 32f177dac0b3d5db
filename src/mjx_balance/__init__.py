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
import sys
import types

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
    "simulate": "api",
    "sweep": "api",
    "table": "api",
    "compare": "api",
    "basin": "api",
    "cohort": "api",
    "scorecard": "api",
    "explore": "api",
    "landscape": "api",
    "lean_release": "api",
    "waist_pull": "api",
    "people": "api",
    "sensitivity": "api",
    "report": "api",
    "references": "studies.references",
    "environment": "store.provenance",
    "strategy_map": "figures.strategy",
    "load_report": "report.results:load_results",
    "region_map": "figures.region",
    "energy_map": "figures.region",
    "table_figure": "figures.region",
    "timeseries_figure": "figures.timeseries",
    "weight_figure": "figures.report",
    "conventions_figure": "figures.report",
    "region_numbers": "studies.catalog",
    "study": "studies.catalog",
    "study_reading": "studies.catalog:reading",
    "figure_style": "figures.style",
    "save_figure": "figures.style:save",
}

__all__ = [
    "Config",
    "ParameterError",
    "Subject",
    "__version__",
    "basin",
    "cohort",
    "compare",
    "landscape",
    "lean_release",
    "waist_pull",
    "people",
    "report",
    "sensitivity",
    "conventions_figure",
    "explore",
    "energy_map",
    "environment",
    "load_config",
    "load_report",
    "region_map",
    "region_numbers",
    "references",
    "scorecard",
    "simulate",
    "strategy_map",
    "study",
    "study_reading",
    "sweep",
    "table",
    "table_figure",
    "timeseries_figure",
    "weight_figure",
    "figure_style",
    "save_figure",
]


def __getattr__(name: str):
    if name in _LAZY:
        module, _, attribute = _LAZY[name].partition(":")
        return getattr(importlib.import_module("." + module, __name__), attribute or name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


class _Package(types.ModuleType):
    """The package's module: its ``report`` is the API function (``mjx_balance.api.report``),
    also once the ``mjx_balance.report`` subpackage is imported, which makes the import system
    set the package's attribute of that name to the subpackage (it stays in ``sys.modules``:
    ``from mjx_balance.report import ...`` reaches it)."""

    @property
    def report(self):
        return importlib.import_module(".api", __name__).report

    @report.setter
    def report(self, _subpackage) -> None:  # the import system's setattr: the module is kept
        pass


sys.modules[__name__].__class__ = _Package
