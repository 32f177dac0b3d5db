"""Floor 10, report: the study's experiments and the studies beyond it, as saved tables and one
HTML report drawn from them, and the explore page. docs/architecture.md, "The modules", maps its
modules; docs/outputs.md, "mjx-balance report", describes the folder.

:func:`run_report` (``studies/experiments.py``) runs, for both conventions, every experiment of
the study (docs/study.md, "The study's figures and tables, one by one") and then the studies
of ``studies/catalog.py``, saving each result table in DIR before any figure is drawn:

    DIR/report.json                    what was run: plan, base configuration, studies, timings
    DIR/config.toml                    the base configuration
    DIR/<convention>/summary.csv       experiment 1: one summary row per force (T = 0.1 s)
    DIR/<convention>/timeseries.parquet            and the long time series (reference loop)
    DIR/<convention>/weights.csv       experiment 2: summary rows of the Q and R settings
    DIR/<convention>/table/table.csv   experiment 3: max acting time (a run_table folder)
    DIR/<convention>/region/region.parquet   experiment 4: region map (a run_sweep folder)
    DIR/studies/<study>/<variant>/region.parquet   one region map per study variant
    DIR/studies/<study>/numbers.csv    areas and changes (catalog.compare)
    DIR/figures/*.png, DIR/report.html figures and the report, drawn from the saved tables

:func:`build_report` (``report/html.py``) redraws figures and HTML from the saved tables alone.
The time series and the weight study use the scalar reference loop (``reference/loop.py``); the
table and the region maps use a batch function: the MJX rollout (backend ``mjx``) or the
reference loop run scenario by scenario (backend ``reference``, what the ``tiny`` plan uses). A
finished stage is not rerun (sweeps resume chunk by chunk; see the runs floor).
"""

from ..figures.report import conventions_figure, save_figure, weight_figure
from .html import HTML, build_report, sections
from .results import key_numbers, load_results
from ..runs.batch import ReferenceBatch
from ..runs.folders import batch_function
from ..studies.experiments import (
    PLANS,
    Q_SCALES,
    R_SCALES,
    REPORT_JSON,
    Plan,
    plan_config,
    run_report,
    run_weights,
    selected_studies,
    weight_settings,
)

__all__ = [
    "HTML",
    "PLANS",
    "Plan",
    "Q_SCALES",
    "REPORT_JSON",
    "R_SCALES",
    "ReferenceBatch",
    "batch_function",
    "build_report",
    "conventions_figure",
    "key_numbers",
    "load_results",
    "plan_config",
    "run_report",
    "run_weights",
    "save_figure",
    "sections",
    "selected_studies",
    "weight_figure",
    "weight_settings",
]
