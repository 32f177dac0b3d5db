"""The notebook executes on a tiny report's saved results, with this interpreter's kernel."""

import json
import sys
from pathlib import Path

import pytest

from tiny_report import tiny_report

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "reproduce_study.ipynb"
KERNEL = "mjx_balance_test"


def test_notebook_executes(tmp_path_factory, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    out = tiny_report(tmp_path_factory)
    # A kernel spec for this interpreter (the venv the tests run in), found first on JUPYTER_PATH.
    spec = tmp_path / "jupyter" / "kernels" / KERNEL
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "mjx_balance tests", "language": "python"}))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("MJX_BALANCE_RESULTS", str(out))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    before = sorted(p.relative_to(out) for p in out.rglob("*"))

    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(nb, kernel_name=KERNEL, timeout=300,
                            resources={"metadata": {"path": str(tmp_path)}}).execute()

    code = [c for c in nb.cells if c.cell_type == "code"]
    errors = [o for c in code for o in c.outputs if o.output_type == "error"]
    assert not errors
    assert "plan tiny" in code[0].outputs[0]["text"]
    images = sum(1 for c in code for o in c.outputs if "image/png" in o.get("data", {}))
    assert images >= 6  # time series, 2 weight charts, table curve, 2 region maps
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before  # only reads
