"""``mjx-balance compare`` / ``mb.compare``: several configurations on one grid, with the
stand-in batch function of tests/support.py (recovered iff |F| T < c), whose numbers are
known in closed form: nothing compiles here."""

import json

import numpy as np
import pandas as pd
import pytest
from PIL import Image
from support import FakeThresholdBatch, expected_area, expected_max_time, extra_module

import mjx_balance as mb
from mjx_balance.cli import main
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.studies.compare import boundary_segments, names_for

FORCES, DURATIONS, TABLE_FORCES = "0:40:10", "0.5,1,2", "10,20"
C = {"paper": 30.0, "joint": 60.0}  # the stand-in's threshold per convention


def stand_in_fake(config):
    """The stand-in of a convention (conftest's ``stand_in`` makes one per configuration)."""
    return FakeThresholdBatch(c=C[config.controller.convention])


def configs(tmp_path):
    a, b = tmp_path / "plain.toml", tmp_path / "joint.toml"
    a.write_text('[controller]\nconvention = "paper"\n')
    b.write_text('[controller]\nconvention = "joint"\n')
    return a, b


def test_compare_writes_its_figure_and_table(tmp_path, stand_in):
    a, b = configs(tmp_path)
    out = tmp_path / "out"
    assert (
        main(
            [
                "compare",
                str(a),
                str(b),
                "--forces",
                FORCES,
                "--durations",
                DURATIONS,
                "--table-forces",
                TABLE_FORCES,
                "--out",
                str(out),
            ]
        )
        == 0
    )
    frame = pd.read_csv(out / "compare.csv").set_index("name")
    assert list(frame.index) == ["plain", "joint"]
    for name, convention in (("plain", "paper"), ("joint", "joint")):
        c = C[convention]
        row = frame.loc[name]
        assert row["area"] == pytest.approx(expected_area(c))
        assert row["sustained_push_limit"] == pytest.approx(np.floor(c / 12 * 10 - 1e-9) / 10)
        for force in (10, 20):
            assert row[f"max_acting_time_{force}N"] == expected_max_time(force, c, 12.0)
        region = pd.read_parquet(out / name / "region.parquet")
        recovered = region[region.outcome == "recovered"]
        assert row["mean_recovery_energy"] == pytest.approx(recovered.energy_total.mean())
    with Image.open(out / "compare.png") as image:
        assert image.size[0] > 500
        pixels = np.asarray(image.convert("RGB"), dtype=float)
    # the first configuration's recovered cells are filled in the palette's recovered colour
    # (#009E73 at alpha 0.22 over white: (199, 233, 224)), so the map says which side recovers
    shade = np.abs(pixels - np.array([199.0, 233.0, 224.0])).max(axis=-1) <= 3
    assert shade.mean() > 0.05
    # a rerun finds everything done: no batch function is even called
    calls = sum(len(f.calls) for f in stand_in)
    assert (
        main(
            [
                "compare",
                str(a),
                str(b),
                "--forces",
                FORCES,
                "--durations",
                DURATIONS,
                "--table-forces",
                TABLE_FORCES,
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert sum(len(f.calls) for f in stand_in) == calls


def test_the_api_compares_named_configurations(tmp_path, stand_in):
    frame = mb.compare(
        {
            "paper": {"controller": {"convention": "paper"}},
            "joint": {"controller": {"convention": "joint"}},
        },
        out=tmp_path,
        forces=FORCES,
        durations=DURATIONS,
        table_forces=TABLE_FORCES,
    )
    assert list(frame["name"]) == ["paper", "joint"]
    assert frame["area"].iloc[1] > frame["area"].iloc[0]  # c = 60 recovers more than 30
    manifest = json.loads((tmp_path / "joint" / "manifest.json").read_text())
    assert manifest["config"]["controller"]["convention"] == "joint"


def test_bad_input_is_refused_before_any_work(tmp_path, stand_in, capsys):
    a, _ = configs(tmp_path)
    short = tmp_path / "short.toml"
    short.write_text("[scenario]\nt_end = 1.0\n")
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match="'short'.*t_end"):
        mb.compare([a, short], out=out, forces=FORCES, durations=DURATIONS)
    assert not (out / "plain").exists() and not stand_in  # nothing ran, nothing written
    with pytest.raises(SystemExit) as exited:
        main(["compare", str(tmp_path / "missing.toml"), "--out", str(out)])
    assert exited.value.code == 2 and "missing.toml" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[controller]\nhorizon = 0\n")
    with pytest.raises(ParameterError, match="bad.toml"):
        mb.compare([bad], out=out)
    with pytest.raises(ParameterError, match="plain.toml: this configuration file is given twice"):
        mb.compare([a, tmp_path / "." / "plain.toml"], out=out)
    for name, message in (
        ("../up", "not a folder name"),
        ("compare.csv", "taken by"),
        ("", "not a folder name"),
    ):
        with pytest.raises(ParameterError, match=message):
            mb.compare({name: {}}, out=out)
    mb.compare({"b": {}}, out=out, forces=FORCES, durations="0.5,1", table_forces="10")
    with pytest.raises(ParameterError, match="'b'.*another grid"):  # found before 'a' runs
        mb.compare({"a": {}, "b": {}}, out=out, forces=FORCES, durations=DURATIONS)
    assert not (out / "a").exists()
    with pytest.raises(ParameterError, match="'b'.*different configuration"):
        mb.compare(
            {"b": {"controller": {"convention": "joint"}}},
            out=out,
            forces=FORCES,
            durations="0.5,1",
        )


def test_names_and_boundaries():
    assert names_for(["a/x.toml", "b/x.toml", "c d.toml"]) == ["x", "x-2", "c_d"]
    assert names_for(["compare.png.toml", "..toml"]) == ["compare.png-2", "config"]
    # one recovered cell in a 2 x 2 grid: its outline is 4 edges (2 inner + 2 on the border)
    region = pd.DataFrame(
        {
            "force": [0.0, 0.0, 10.0, 10.0],
            "duration": [0.5, 1.0, 0.5, 1.0],
            "outcome": ["recovered", "fell", "fell", "fell"],
        }
    )
    segments = boundary_segments(region, log=False)
    assert len(segments) == 4
    xs = sorted({x for seg in segments for x, _ in seg})
    assert xs == [0.0, 5.0]  # from the grid's edge to half-way to the next force


@pytest.mark.slow  # a local Dask cluster (one worker process)
def test_compare_on_a_local_cluster_gives_the_local_numbers(tmp_path, monkeypatch):
    """``compare --cluster local:1``: one connection for every configuration's map
    and table, and the same region maps and compare.csv as the plain run. The stand-ins go to
    the worker by value (it cannot import this test module). Needs Dask (the cluster extra)."""
    distributed = extra_module("distributed", "cluster")
    import cloudpickle
    import support  # the stand-in's module (FakeThresholdBatch)

    from mjx_balance.runs import cluster as cluster_mod
    from mjx_balance.studies.compare import run_compare

    configs = {"paper": Config(), "joint": Config().replace(controller={"convention": "joint"})}

    def run(out, **engine):
        batches = {
            name: FakeThresholdBatch(c=C[c.controller.convention]) for name, c in configs.items()
        }
        frame = run_compare(
            out, configs, FORCES, DURATIONS, TABLE_FORCES, run_batches=batches, say=None, **engine
        )
        return frame, sum(len(b.calls) for b in batches.values())  # calls made here

    connections = []
    connect = cluster_mod.connect
    monkeypatch.setattr(
        cluster_mod, "connect", lambda *a, **k: connections.append(a[0]) or connect(*a, **k)
    )
    cloudpickle.register_pickle_by_value(support)
    try:
        on_cluster, here = run(tmp_path / "cluster", cluster="local:1")
    finally:
        cloudpickle.unregister_pickle_by_value(support)
    # one cluster started; each configuration's map and table reuse its client
    assert connections[0] == "local:1" and len(connections) == 1 + 2 * len(configs)
    assert all(c is connections[1] and isinstance(c, distributed.Client) for c in connections[1:])
    plain, plain_here = run(tmp_path / "plain")
    assert here == 0 < plain_here  # on the cluster, every scenario ran on the worker
    pd.testing.assert_frame_equal(on_cluster, plain)
    for name in configs:
        assert (tmp_path / "cluster" / name / "region.parquet").read_bytes() == (
            tmp_path / "plain" / name / "region.parquet"
        ).read_bytes()


def test_sweep_definitions_are_configurations_too(tmp_path, stand_in):
    """A sweep definition (a file with [sweep], or a shipped name) gives its configuration;
    its grid is not used (the comparison's is)."""
    plain = tmp_path / "plain.toml"
    plain.write_text('[controller]\nconvention = "paper"\n')
    out = tmp_path / "out"
    assert (
        main(
            [
                "compare",
                str(plain),
                "study_offset_free",
                "--forces",
                FORCES,
                "--durations",
                DURATIONS,
                "--table-forces",
                TABLE_FORCES,
                "--out",
                str(out),
            ]
        )
        == 0
    )
    made = json.loads((out / "study_offset_free" / "manifest.json").read_text())
    assert made["config"]["controller"]["offset_free"] is True
    region = pd.read_parquet(out / "study_offset_free" / "region.parquet")
    assert sorted(region.force.unique()) == [0.0, 10.0, 20.0, 30.0, 40.0]  # FORCES, not its own
    with pytest.raises(SystemExit):
        main(["compare", "no_such_sweep", "--out", str(out)])
