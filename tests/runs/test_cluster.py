"""Region sweeps on a Dask cluster (runs/cluster.py, docs/cluster.md).

The reference is the plain local sweep (``api.run_region``, as ``mjx-balance sweep`` runs it),
in a subprocess that fills a compilation cache folder of this module's own: the cluster's
worker processes inherit ``MJX_BALANCE_CACHE_DIR`` and load the compiled engine from it
instead of compiling it again (the smallest real configuration: t_end = 1 s, 8 slots, 12 cells
in 3 chunks of 4; the same process also writes the local table of TABLE_FORCES, which the
cluster's table must equal). The cluster tests need Dask distributed (the ``cluster`` extra,
which .ci/run installs before the slow run) and are in the slow run; without Dask they skip
(under CI=true they fail). The option's checks and the last test run without Dask.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import jax
import numpy as np
import pandas as pd
import pytest
from support import extra_module, held_sweep, held_table, tiny_config

from mjx_balance.measures.outcomes import SUMMARY_COLUMNS
from mjx_balance.runs.grid import Grid


@pytest.fixture(scope="module")
def distributed():
    """Dask distributed (the extra "cluster")."""
    return extra_module("distributed", "cluster")


T_END = 1.0
FORCES, DURATIONS = "0,60,120,250", "0.1,0.2,0.5"  # recovered, not_settled and fell
CHUNK, SLOTS = 4, 8  # 12 cells: 3 chunks, so both workers of local:2 get one
CHUNK_KEY = "mjx_balance-chunk-"
TABLE_FORCES = "60,120"  # 26 scenarios: a coarse call of 10, one 9-section round of 16


class Fake:
    """FAKE batch function (bookkeeping only): recovered iff |F| * T < 30, else fell."""

    def __call__(self, forces, durations):
        forces = np.asarray(forces, dtype=np.float32)
        durations = np.asarray(durations, dtype=np.float32)
        ok = np.abs(forces) * durations < 30
        out = {c: np.zeros(forces.size) for c in SUMMARY_COLUMNS if c != "convention"}
        out["force"], out["duration"] = forces, durations
        out["outcome"] = np.where(ok, 0, 2).astype(np.int32)
        out["settle_time"] = np.where(ok, 1.0 + durations, np.nan)
        out["fall_time"] = np.where(ok, np.nan, durations)
        return out


@pytest.fixture(scope="module")
def compile_cache(tmp_path_factory):
    """This module's compilation cache folder, inherited by the worker processes it starts."""
    folder = tmp_path_factory.mktemp("jax_cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MJX_BALANCE_CACHE_DIR", str(folder))
        yield folder


@pytest.fixture(scope="module")
def reference(tmp_path_factory, compile_cache) -> Path:
    """region.parquet of the plain local sweep (no Dask), in a fresh process; the local
    table of TABLE_FORCES next to it (``_local_table``), by the same compiled engine."""
    out = tmp_path_factory.mktemp("local") / "sweep"
    code = textwrap.dedent(f"""
        from mjx_balance import api
        from mjx_balance.model.params import Config
        config = Config().replace(scenario={{"t_end": {T_END}}})
        from mjx_balance.runs.grid import Grid
        api.run_region({str(out)!r}, config, Grid.of({FORCES!r}, {DURATIONS!r}, config),
                       chunk={CHUNK},
                       slots={SLOTS})
        api.run_table_folder({str(_local_table(out / "region.parquet"))!r}, config,
                             {TABLE_FORCES!r}, slots={SLOTS})
    """)
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)
    return out / "region.parquet"


def _sweep(out, cluster, **kwargs):
    from mjx_balance.runs import LazyBatch

    config = tiny_config(t_end=T_END)
    with jax.enable_x64(False):  # as sweeps run (conftest switches x64 on for the session)
        return held_sweep(
            out,
            config,
            Grid.of(FORCES, DURATIONS, config),
            chunk=CHUNK,
            progress=False,
            run_batch=LazyBatch(config, slots=SLOTS),
            cluster=cluster,
            say=None,
            **kwargs,
        )


@pytest.mark.slow  # a local Dask cluster: .ci/run runs it after the default suite
@pytest.mark.usefixtures("distributed")
def test_local_cluster_gives_the_local_bytes(tmp_path, reference):
    """``local:2``: the same region.parquet, byte for byte, as the plain local run; the
    manifest records the slots the workers ran; a rerun finds it complete and starts nothing."""
    result = _sweep(tmp_path / "cluster", "local:2")
    assert result.computed_chunks == 3
    assert result.region_path.read_bytes() == reference.read_bytes()
    manifest = json.loads((tmp_path / "cluster" / "manifest.json").read_text())
    assert manifest["region"]["engine"] == {"slots": SLOTS, "early_stop": True, "physics": "mjx"}
    again = _sweep(tmp_path / "cluster", "local:2")
    assert again.already_complete and again.computed_chunks == 0


def _local_table(reference: Path) -> Path:
    return reference.parent.parent / "table"


@pytest.fixture(scope="module")
def cluster(compile_cache, distributed):
    """A local cluster of 2 worker processes for the module (nannies restart a killed
    worker; a later test reuses the runners the workers built)."""
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as local:
        with distributed.Client(local) as client:
            yield local, client


@pytest.mark.slow  # a local Dask cluster: .ci/run runs it after the default suite
def test_worker_killed_mid_chunk_loses_nothing(tmp_path, reference, cluster, distributed):
    """A worker SIGKILLed while it runs a chunk: Dask runs the chunk again elsewhere and the
    sweep (on the scheduler's address) ends complete and byte-identical, each chunk once."""
    local, watch = cluster
    killed: list[tuple[str, int, str]] = []
    stop = threading.Event()

    def kill_one_worker_mid_chunk() -> None:
        deadline = time.monotonic() + 240
        while not stop.is_set() and time.monotonic() < deadline:
            for worker, keys in watch.processing().items():
                running = [str(k) for k in keys if str(k).startswith(CHUNK_KEY)]
                if running:
                    pid = watch.run(os.getpid, workers=[worker])[worker]
                    if running[0] in map(str, watch.processing().get(worker, ())):
                        os.kill(pid, signal.SIGKILL)
                        killed.append((worker, pid, running[0]))
                        return
            time.sleep(0.05)

    thread = threading.Thread(target=kill_one_worker_mid_chunk, daemon=True)
    thread.start()
    with distributed.get_task_stream(watch) as stream:
        try:
            result = _sweep(tmp_path / "cluster", local.scheduler_address)
        finally:
            stop.set()
            thread.join()
    assert killed, "no chunk was seen running"
    print(f"killed worker {killed[0][0]} (PID {killed[0][1]}) while it ran {killed[0][2]}")
    assert killed[0][1] not in watch.run(os.getpid).values()  # it was really killed (restarted)
    assert result.computed_chunks == 3
    assert len(list((tmp_path / "cluster" / "chunks").glob("chunk-*.parquet"))) == 3
    assert result.region_path.read_bytes() == reference.read_bytes()
    finished = [t for t in stream.data if str(t["key"]).startswith(CHUNK_KEY)]
    assert len({t["key"] for t in finished}) == 3  # every chunk finished (once per key)


@pytest.mark.slow  # a local Dask cluster: .ci/run runs it after the default suite
def test_table_on_the_cluster_is_the_local_table(tmp_path, reference, cluster, distributed):
    """``table --cluster``: each bisection round's calls run as tasks on the workers (split
    between them) and come back in order; table.csv, table_runs.parquet, every kept part
    file of table_runs/ and the engine record are those of the plain local table."""
    from mjx_balance.runs import LazyBatch, table_batch_size

    local, client = cluster
    config = tiny_config(t_end=T_END)
    out = tmp_path / "cluster"
    with jax.enable_x64(False), distributed.get_task_stream(client) as stream:
        result = held_table(
            out,
            config,
            TABLE_FORCES,
            run_batch=LazyBatch(config, slots=SLOTS),
            batch=table_batch_size(config, 2),
            progress=False,
            say=None,
            cluster=client,
        )
    expected = _local_table(reference)
    assert len(result.runs) == len(pd.read_parquet(expected / "table_runs.parquet")) > 26
    for name in ("table.csv", "table_runs.parquet"):
        assert (out / name).read_bytes() == (expected / name).read_bytes(), name
    parts = sorted(p.name for p in (expected / "table_runs").glob("*.parquet"))
    assert parts and sorted(p.name for p in (out / "table_runs").glob("*.parquet")) == parts
    for name in parts:
        assert (out / "table_runs" / name).read_bytes() == (
            expected / "table_runs" / name
        ).read_bytes(), name
    manifests = [json.loads((d / "manifest.json").read_text()) for d in (out, expected)]
    assert manifests[0]["table_engine"] == manifests[1]["table_engine"]
    assert (
        len({t["key"] for t in stream.data if str(t["key"]).startswith("mjx_balance-cells-")}) >= 2
    )


def _other_version():
    import mjx_balance.store.provenance as provenance

    provenance.__version__ = "0.0.0+other"


@pytest.mark.slow  # a local Dask cluster (one worker process)
def test_worker_of_another_version_is_refused(tmp_path, distributed):
    """A worker that reports another mjx_balance version is refused at connect time, with a
    message naming it; nothing is computed. A task on such a worker refuses too."""
    from mjx_balance.runs.cluster import (
        ChunkSpec,
        ClusterError,
        compute_chunk,
        local_facts,
    )

    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
        ) as local,
        distributed.Client(local) as client,
    ):
        _run_by_value(client, _other_version)
        refused = r"refusing the cluster.*worker tcp://.*: mjx_balance 0\.0\.0\+other \(driver: "
        with pytest.raises(ClusterError, match=refused):
            config = tiny_config(t_end=T_END)
            held_sweep(
                tmp_path / "out",
                config,
                Grid.of(FORCES, DURATIONS, config),
                run_batch=Fake(),
                chunk=CHUNK,
                progress=False,
                say=None,
                cluster=client,
            )
    assert not list((tmp_path / "out" / "chunks").glob("*.parquet"))
    # a worker that joined after the check: the task itself refuses
    spec = ChunkSpec(
        tiny_config(t_end=T_END),
        None,
        True,
        CHUNK,
        False,
        facts={**local_facts(), "jax": "0.0.1"},
        batch=Fake(),
    )
    with pytest.raises(ClusterError, match=r"jax .* \(driver: 0\.0\.1\)"):
        compute_chunk(spec, 0, np.array([0.0]), np.array([0.1]))


def _run_by_value(client, function):
    """``client.run(function)``, the function pickled by value (the workers cannot import this
    test module)."""
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        return client.run(function)
    finally:
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


def test_cluster_spec_errors():
    from mjx_balance.runs.cluster import ClusterError, parse_cluster

    assert parse_cluster("local:3") == ("local", 3)
    assert parse_cluster("tcp://10.0.0.1:8786") == ("address", "tcp://10.0.0.1:8786")
    for bad in ("local:0", "local:x", "local:", " "):
        with pytest.raises(ClusterError):
            parse_cluster(bad)


def test_cluster_option_is_checked_before_any_work(tmp_path, capsys):
    """``sweep --cluster`` with a bad spec: usage error (exit 2), nothing created."""
    from mjx_balance import cli

    with pytest.raises(SystemExit) as exc:
        cli.main(
            [
                "sweep",
                "--forces",
                "0,50",
                "--durations",
                "0.1",
                "--cluster",
                "local:0",
                "--out",
                str(tmp_path / "out"),
            ]
        )
    assert exc.value.code == 2
    assert "argument --cluster" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_plain_install_runs_without_dask(tmp_path):
    """With ``import dask`` failing: the command line and a plain sweep work and never import
    Dask; asking for a cluster says which extra to install."""
    code = textwrap.dedent(f"""
        import sys

        class NoDask:
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in ("dask", "distributed"):
                    raise ImportError(f"blocked: {{name}}")
                return None

        sys.meta_path.insert(0, NoDask())
        import pytest
        from mjx_balance.cli import main
        from mjx_balance.model.params import Config
        from mjx_balance.runs.cluster import ClusterError
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        sys.path.insert(0, {str(Path(__file__).parents[1])!r})  # support.py, which it imports
        from test_cluster import Fake
        from support import held_sweep, held_table

        for command in ("sweep", "table"):
            try:
                main([command, "--help"])
            except SystemExit as exc:
                assert exc.code == 0, exc.code
        config = Config().replace(scenario={{"t_end": 1.0}})
        from mjx_balance.runs.grid import Grid
        result = held_sweep({str(tmp_path / "plain")!r}, config, Grid.of("0,60", "0.1,0.5", config),
                           run_batch=Fake(), progress=False, say=None)
        assert len(result.region) == 4
        with pytest.raises(ClusterError, match="mjx_balance\\\\[cluster\\\\]"):
            held_sweep({str(tmp_path / "asked")!r}, config, Grid.of("0,60", "0.1,0.5", config),
                      run_batch=Fake(), progress=False, say=None, cluster="local:2")
        table = held_table({str(tmp_path / "plain_table")!r}, config, "0,60", run_batch=Fake(),
                          progress=False, say=None)
        assert len(table.table) == 2
        with pytest.raises(ClusterError, match="mjx_balance\\\\[cluster\\\\]"):
            held_table({str(tmp_path / "asked_table")!r}, config, "0,60", run_batch=Fake(),
                      progress=False, say=None, cluster="local:2")
        assert not [m for m in sys.modules if m.split(".")[0] in ("dask", "distributed")]
        print("ok without dask")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "ok without dask" in out.stdout
