"""A cohort through one engine queue (``cohort --queue one``, runs/population.py): each slot
runs its scenario's body as per-lane data, so a subject's map does not depend on the other
subjects in the queue, their order or their number; the options that cannot run that way are
refused before anything is written."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import mjx_balance as mb
from mjx_balance.cli.main import main
from mjx_balance.model.params import Config, ParameterError
from mjx_balance.model.subject import Subject
from mjx_balance.runs import population
from mjx_balance.studies import cohort
from mjx_balance.studies import members as cohort_members

BASE = Config().replace(scenario={"t_end": 1.0})


def test_queues_split_the_bodies_by_cells():
    assert population.queues(5, 100, limit=250) == [range(0, 2), range(2, 4), range(4, 5)]
    assert population.queues(3, 1000, limit=250) == [range(0, 1), range(1, 2), range(2, 3)]
    assert population.queues(4, 10, limit=1000) == [range(0, 4)]


def test_the_first_queue_is_short_and_each_next_one_twice_the_last():
    """The first scenario waits for the first queue's bodies only (each built when its queue
    starts): 16 bodies, then 32, 64, ... up to the cell limit, every body once, in order."""
    parts = population.queues(1000, 2, limit=200, first=16)
    assert [len(p) for p in parts] == [16, 32, 64] + [100] * 8 + [88]  # 112 + 800 + 88
    assert [i for p in parts for i in p] == list(range(1000))
    assert population.queues(3, 2, limit=200) == [range(0, 3)]
    capped = population.queues(5000, 2, limit=20_000, bodies=1024)  # a queue's bodies' memory
    assert max(len(p) for p in capped) == 1024 and sum(len(p) for p in capped) == 5000
    assert population.queues(40, 50, limit=200, first=16) == [
        range(4 * k, 4 * k + 4) for k in range(10)
    ]


def test_a_refused_body_is_named_before_its_queue_runs(tmp_path):
    """A map's configuration is checked when its queue starts (a large cohort's subjects are
    not all checked before the folder is made): a refusal names the map by ``label`` and no
    body of that queue has run (nothing written, nothing compiled)."""
    refused = BASE.replace(controller={"admm_rho": 1e-300})  # float32 makes it 0
    maps = [(tmp_path / "ok", BASE), (tmp_path / "bad", lambda: refused)]
    with pytest.raises(ParameterError, match=r"^subject 'bad': controller.admm_rho = 1e-300"):
        population.run_maps(
            maps,
            np.array([0.0, 50.0]),
            np.array([0.1]),
            label=lambda folder: f"subject {folder.name!r}",
        )
    assert not any(tmp_path.iterdir())


def test_a_large_cohort_checks_its_representatives_before_the_folder(tmp_path, monkeypatch):
    """Up to CHECKED_FIRST subjects every configuration is checked before the folder is made;
    beyond, each sex's extremes of every body value (and the base), the rest when their queue
    starts (test above)."""
    checked = []
    monkeypatch.setattr(cohort, "check_batched", lambda config, *grids: checked.append(config))
    small = cohort_members.population(cohort.CHECKED_FIRST, 5, age_mean=60, age_sd=15)
    cohort.plan_cohort(tmp_path / "small", small, BASE, "0,50", "0.1")
    assert len(checked) == cohort.CHECKED_FIRST + 1  # and the base
    checked.clear()
    large = cohort_members.population(500, 5, age_mean=60, age_sd=15)
    cohort.plan_cohort(tmp_path / "large", large, BASE, "0,50", "0.1")
    picked = cohort.representatives(large)
    assert len(checked) == len(picked) + 1 <= cohort.checked_first(500) + 1
    assert checked[-1] == BASE
    for sex in ("male", "female"):
        same = [m.subject for m in large if m.subject.sex == sex]
        mine = [m.subject for m in picked if m.subject.sex == sex]
        for value in ("height", "mass", "age"):
            values = [getattr(s, value) for s in same]
            assert {min(values), max(values)} <= {getattr(s, value) for s in mine}
        bmi = [s.mass / s.height**2 for s in same]
        assert {min(bmi), max(bmi)} <= {s.mass / s.height**2 for s in mine}
    assert not (tmp_path / "large").exists()


def test_a_served_batch_hands_back_the_rows_asked_for():
    columns = {
        "force": np.array([0.0, 0.0, 10.0, 10.0]),
        "duration": np.array([0.1, 0.2, 0.1, 0.2]),
        "outcome": np.array([0, 0, 0, 1], np.int32),
        "settle_time": np.arange(4.0),
    }
    batch = population.ServedBatch(BASE, columns, slots=8, early_stop=True)
    assert batch.can_stream() and batch.engine_record() == {
        "slots": 8,
        "early_stop": True,
        "physics": "mjx",
        "queue": "one",
    }
    index, got = next(batch.stream(np.array([10.0, 0.0]), np.array([0.2, 0.1])))
    assert index.tolist() == [0, 1]
    assert got["settle_time"].tolist() == [3.0, 0.0] and got["outcome"].tolist() == [1, 0]
    with pytest.raises(ValueError, match="started with 16 slots"):
        batch.use_engine(16, True, "mjx")
    batch.use_engine(8, True, "mjx")  # the same settings: nothing to say


@pytest.mark.parametrize(
    "options, message",
    [
        ({"queue": "all"}, "queue = 'all'"),
        ({"queue": "one", "physics": "c"}, "not with physics 'c'"),
        ({"queue": "one", "cluster": "local:2"}, "or a cluster"),
    ],
)
def test_a_queue_that_cannot_run_is_refused_before_anything_is_written(tmp_path, options, message):
    out = tmp_path / "out"
    with pytest.raises(ParameterError, match=message):
        cohort.plan_cohort(
            out, cohort_members.numbered([Subject(1.7, 70)]), BASE, "0,50", "0.1", **options
        )
    assert not out.exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (("all",), "queue = 'all'"),
        (("one", "c"), "not with physics 'c'"),
        (("one", "mjx", "local:2"), "or a cluster"),
    ],
)
def test_every_command_checks_its_queue_alike(args, message):
    with pytest.raises(ParameterError, match=message):
        population.check_queue(*args)
    assert population.check_queue("one", "auto") == "one"


def test_bodies_of_another_shape_cannot_share_a_queue():
    """The stacked arrays need one compiled program's shapes: a horizon of another length is
    refused (building runners compiles nothing)."""
    from mjx_balance.rollout import BatchRunner
    from mjx_balance.rollout.engine import lane_bodies

    one = BatchRunner(BASE, physics="mjx")
    other = BatchRunner(
        BASE.replace(controller={"horizon": BASE.controller.horizon + 2}), physics="mjx"
    )
    with pytest.raises(ValueError, match="shapes and static settings"):
        lane_bodies(one, [one, other], early_stop=True)
    arrays, cert = lane_bodies(one, [one, one, one], early_stop=True)
    import jax

    assert {np.shape(v)[0] for v in jax.tree.leaves(arrays)} == {4}  # padded to 4
    assert {np.shape(v)[0] for v in jax.tree.leaves(cert)} == {4}


def test_each_lane_holds_its_own_bodys_compiled_model():
    """A lane's body is the arrays its runner built from that body's own MJCF (MuJoCo's
    derived quantities, mj_setConst's included), gathered unchanged: field by field, bit for
    bit, for bodies of several sizes, and padding repeats the last body."""
    import jax

    from mjx_balance.rollout import BatchRunner
    from mjx_balance.rollout.engine import lane_bodies
    from mjx_balance.rollout.kernel import lane_arrays

    people = [
        Subject(1.52, 48, "female", ankle_strength=0.6),
        Subject(1.75, 75),
        Subject(1.95, 110, hip_strength=1.3),
    ]
    runners = [BatchRunner(p.config(BASE), physics="mjx") for p in people]
    stacked, _ = lane_bodies(runners[0], runners, early_stop=True)
    lanes = jax.tree.map(np.asarray, lane_arrays(stacked, np.array([2, 0, 1, 3])))
    for lane, runner in zip(range(4), [runners[2], runners[0], runners[1], runners[2]]):
        mine = jax.tree.leaves(jax.tree.map(lambda v, lane=lane: v[lane], lanes))  # numpy
        own = jax.tree.leaves(runner.arrays)
        assert len(mine) == len(own)
        for a, b in zip(mine, own):
            assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
    masses = [float(np.asarray(r.arrays.mx.body_mass).sum()) for r in runners]
    assert masses[0] < masses[1] < masses[2]  # three bodies, not one three times


@pytest.mark.slow  # compiles the per-lane engine twice (2 and 4 bodies): about 3 min on 2 cores
def test_a_subject_in_one_queue_is_the_same_among_any_others(tmp_path):
    """Bit for bit (region.parquet's every column): each subject of a three-subject cohort
    through one queue equals the same subject's one-subject cohort through one queue, whatever
    the others and their order, and compare's one queue maps that subject's configuration to
    the same bytes."""
    people = tmp_path / "people.csv"
    people.write_text(
        "id,height,mass,sex\nann,1.55,50,female\nbob,1.75,75,male\ncy,1.92,100,male\n"
    )
    grid = [
        "--forces",
        "20,60,100",
        "--durations",
        "0.1,0.3",
        "--set",
        "scenario.t_end=2",
        "--slots",
        "4",
        "--queue",
        "one",
        "-q",
    ]
    assert main(["cohort", "--subjects", str(people), *grid, "--out", str(tmp_path / "three")]) == 0
    for name, row in (("bob", "bob,1.75,75,male"), ("cy", "cy,1.92,100,male")):
        alone = tmp_path / f"{name}.csv"
        alone.write_text(f"id,height,mass,sex\n{row}\n")
        assert main(["cohort", "--subjects", str(alone), *grid, "--out", str(tmp_path / name)]) == 0
        mine = pd.read_parquet(tmp_path / name / "subjects" / name / "region.parquet")
        among = pd.read_parquet(tmp_path / "three" / "subjects" / name / "region.parquet")
        pd.testing.assert_frame_equal(mine, among, check_exact=True)
    maps = [
        pd.read_parquet(tmp_path / "three" / "subjects" / i / "region.parquet")
        for i in ("ann", "bob", "cy")
    ]
    assert (maps[0]["outcome"] != maps[2]["outcome"]).any()  # the bodies do differ
    # compare's one queue is the same queue: its map of cy's configuration is the cohort's
    base = Config().replace(scenario={"t_end": 2.0})
    mb.compare(
        {"plain": base, "cy": Subject(1.92, 100, "male").config(base)},
        out=tmp_path / "compare",
        forces="20,60,100",
        durations="0.1,0.3",
        table_forces="60",
        slots=4,
        queue="one",
    )
    pd.testing.assert_frame_equal(
        pd.read_parquet(tmp_path / "compare" / "cy" / "region.parquet"), maps[2], check_exact=True
    )
