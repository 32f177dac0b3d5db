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

from importlib.metadata import PackageNotFoundError, version

from ._xla import deterministic_flags

# XLA options that make every scenario's result independent of its slot and batch (see
# rollout/engine.py); they only take effect if set before JAX starts its CPU backend.
deterministic_flags()

try:
    __version__ = version("mjx_balance")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+local"

from .params import Config, ParameterError, load_config  # noqa: E402 - after the flags

# Figures and saved reports, for notebooks: each figure function draws on the matplotlib Axes
# it is given (or a new figure) and returns the Figure.
_LAZY = {
    "simulate": "api", "table": "api", "compare": "api", "basin": "api",
    "load_report": "report.html:load_results",
    "region_map": "region_plots", "energy_map": "region_plots", "table_figure": "region_plots",
    "timeseries_figure": "plots", "weight_figure": "report.html",
    "conventions_figure": "report.html", "region_numbers": "studies", "study": "studies",
    "study_reading": "studies:reading",
}

__all__ = ["Config", "ParameterError", "__version__", "basin", "compare", "conventions_figure",
           "energy_map",
           "load_config", "load_report", "region_map", "region_numbers", "simulate", "study",
           "study_reading", "sweep", "table", "table_figure", "timeseries_figure",
           "weight_figure"]

_API = tuple(_LAZY) + ("sweep",)


def __getattr__(name: str):
    # The API functions live in mjx_balance.api, imported on first use (JAX, MuJoCo and pandas
    # with it). ``mjx_balance.sweep`` is also the subpackage of the sweep machinery, which
    # Python binds to this name whenever it is imported: that subpackage is callable and its
    # call is ``api.sweep`` (sweep/__init__.py), so ``mjx_balance.sweep(...)`` runs the sweep
    # and ``from mjx_balance import sweep`` still gives the subpackage.
    if name == "sweep":
        import importlib

        return importlib.import_module(".sweep", __name__)
    if name in _LAZY:
        import importlib

        module, _, attribute = _LAZY[name].partition(":")
        return getattr(importlib.import_module("." + module, __name__), attribute or name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
