"""The notebook executes on a tiny report's saved results, with this interpreter's kernel, only
reads them, and shows the numbers of the saved tables; without saved results it computes a small
one through the public API. Both executions are in the slow run (a kernel compiles the batched
closed loop anew); the default run checks the notebook's calls against the public API."""

import ast
import inspect
import json
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support import REPO, extra_module
from tiny_report import tiny_report

from mjx_balance.studies import catalog as studies

NOTEBOOK = REPO / "notebooks" / "reproduce_study.ipynb"
KERNEL = "mjx_balance_test"


@pytest.mark.slow  # 140 s on a 2-core Zen 1 EPYC: .ci/run runs it after the default suite
def test_notebook_executes(tmp_path_factory, tmp_path, monkeypatch):
    out = tiny_report(tmp_path_factory)
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    code = _execute(out, tmp_path, monkeypatch)

    errors = [o for c in code for o in c.outputs if o.output_type == "error"]
    assert not errors
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before  # only reads
    images = [o for c in code for o in c.outputs if "image/png" in o.get("data", {})]
    # per convention: time series, weight chart, region map; and the conventions' table curves
    assert len(images) == 7

    # What the cells print and display, against the saved tables read back here.
    assert _text(code[0]) == (
        f"results in {out}: plan tiny, batch backend reference, "
        "conventions paper, joint, t_end = 2 s\n"
    )
    tables = {c: pd.read_csv(out / c / "table" / "table.csv") for c in ("paper", "joint")}
    shown = _html_rows(code[3])
    expected = np.column_stack(
        [tables["paper"].force]
        + [
            tables[c][k]
            for c in ("paper", "joint")
            for k in ("max_acting_time", "energy_total_01", "energy_total_max")
        ]
    )
    np.testing.assert_allclose(np.array(shown, dtype=float), expected, rtol=1e-5, atol=1e-6)

    lines = []
    for convention in ("paper", "joint"):
        n = studies.region_numbers(pd.read_parquet(out / convention / "region" / "region.parquet"))
        lines.append(
            f"{convention}: recovered area {n['area']:.3g} N s ({n['fraction']:.0%} of the grid)\n"
        )
    assert _text(code[4]) == "".join(lines)

    record = json.loads((out / "report.json").read_text())
    markdown = [
        o["data"]["text/markdown"] for o in code[5].outputs if "text/markdown" in o.get("data", {})
    ]
    expected = []
    for entry in record["studies"]:
        st = studies.study(entry["key"])
        folder = out / "studies" / st.key
        first = pd.read_parquet(folder / entry["variants"][0]["key"] / "region.parquet")
        expected += [
            f"### {st.title}\n{st.question}",
            "> " + studies.reading(st, pd.read_csv(folder / "numbers.csv"), first),
        ]
    assert markdown == expected


def test_the_notebooks_calls_fit_the_public_api():
    """Every ``mb.NAME`` the notebook's code uses exists, and every call ``mb.NAME(...)`` binds
    to that function's signature (its positional count and keyword names): the same calls
    test_notebook_computes_a_small_result_without_a_saved_report executes in the slow run."""
    import mjx_balance as mb

    # the .ipynb file is JSON (nbformat 4): its code cells' sources without Jupyter installed
    cells = [
        "".join(c["source"])
        for c in json.loads(NOTEBOOK.read_text())["cells"]
        if c["cell_type"] == "code"
    ]
    used, calls = set(), []
    for source in cells:
        code = "\n".join(line for line in source.splitlines() if not line.startswith("%"))
        for node in ast.walk(ast.parse(code)):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id == "mb"
            ):
                used.add(node.attr)
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and isinstance(node.func.value, ast.Name)
                and node.func.value.id == "mb"
            ):
                calls.append(node)
    assert {"simulate", "sweep", "table", "load_report", "region_map"} <= used
    for name in used:
        assert hasattr(mb, name), name
    for call in calls:
        signature = inspect.signature(getattr(mb, call.func.attr))
        signature.bind(*[None] * len(call.args), **{k.arg: None for k in call.keywords})


@pytest.mark.slow  # about 55 s cold on 2 cores: test_the_notebooks_calls_fit_the_public_api
def test_notebook_computes_a_small_result_without_a_saved_report(tmp_path, monkeypatch):
    """No report in MJX_BALANCE_RESULTS: the notebook says so and computes a small result with
    the public API (simulate, sweep, table), drawing what it can without the studies."""
    code = _execute(tmp_path / "nothing_here", tmp_path, monkeypatch)
    assert not [o for c in code for o in c.outputs if o.output_type == "error"]
    assert _text(code[0]).startswith(f"no saved report in {tmp_path / 'nothing_here'}")
    assert "needs a saved report" in _text(code[2])
    images = [o for c in code for o in c.outputs if "image/png" in o.get("data", {})]
    assert len(images) == 3  # time series, table curve, region map
    assert [len(r) for r in _html_rows(code[3])] == [4] * 4  # the four table forces
    assert not (tmp_path / "nothing_here").exists()  # nothing written


def _execute(results: Path, tmp_path: Path, monkeypatch) -> list:
    """Run the notebook with MJX_BALANCE_RESULTS = ``results`` on this interpreter's kernel;
    its code cells with their outputs."""
    nbformat, nbclient = (extra_module(m, "notebooks") for m in ("nbformat", "nbclient"))
    extra_module("ipykernel", "notebooks")
    # A kernel spec for this interpreter (the venv the tests run in), found first on JUPYTER_PATH.
    spec = tmp_path / "jupyter" / "kernels" / KERNEL
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(
        json.dumps(
            {
                "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
                "display_name": "mjx_balance tests",
                "language": "python",
            }
        )
    )
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("MJX_BALANCE_RESULTS", str(results))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(
        nb, kernel_name=KERNEL, timeout=600, resources={"metadata": {"path": str(tmp_path)}}
    ).execute()
    return [c for c in nb.cells if c.cell_type == "code"]


def _text(cell) -> str:
    """What a cell printed."""
    return "".join(o["text"] for o in cell.outputs if o.output_type == "stream")


def _html_rows(cell) -> list[list[str]]:
    """The body rows (index column dropped) of the one table a cell displayed."""
    (table,) = [o["data"]["text/html"] for o in cell.outputs if "text/html" in o.get("data", {})]
    body = table.split("<tbody>", 1)[1]
    return [
        re.findall(r"<td>(.*?)</td>", row, re.S)
        for row in re.findall(r"<tr>(.*?)</tr>", body, re.S)
    ]
