"""The figures say what was computed and nothing more: each sampled cell drawn where it was
sampled (the axes end at the grid's cell bounds), a log duration axis across decades, a legend
with every outcome class, the table's max acting time and impulse lines on the map, energies of
recovered runs only (in table.csv too), time series with the push window, bounds, inputs,
outcomes and a trimmed time axis; every figure function draws on a given Axes and returns the
Figure. Synthetic frames only (no simulation), so the module runs in seconds."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from margins import within
from matplotlib.collections import QuadMesh
from matplotlib.patches import Rectangle
from support import (
    FakeThresholdBatch,
    fake_region,
    grid_cells,
    push_energy,
    synthetic_series,
)

from mjx_balance import runs as sweep
from mjx_balance.figures import region as region_plots
from mjx_balance.figures import timeseries as plots
from mjx_balance.measures.outcomes import OUTCOMES
from mjx_balance.model.params import Config


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _mesh(ax) -> QuadMesh:
    (mesh,) = [c for c in ax.collections if isinstance(c, QuadMesh)]
    return mesh


def _mesh_extent(ax) -> tuple[float, float, float, float]:
    xy = _mesh(ax).get_coordinates()
    return xy[..., 0].min(), xy[..., 0].max(), xy[..., 1].min(), xy[..., 1].max()


def test_cell_bounds():
    np.testing.assert_allclose(region_plots.cell_bounds([25, 50]), [25, 37.5, 50])
    np.testing.assert_allclose(region_plots.cell_bounds([0.05, 0.2, 0.1]), [0.05, 0.075, 0.15, 0.2])
    np.testing.assert_allclose(
        region_plots.cell_bounds([0.1, 1.0, 10.0], log=True), [0.1, np.sqrt(0.1), np.sqrt(10), 10.0]
    )
    single = region_plots.cell_bounds([0.005])  # one sample: a band, never below 0
    assert single[0] >= 0 and single[0] < 0.005 < single[1]
    # the bounds of a grid are the area cells of studies.region_numbers
    from mjx_balance.studies import catalog as studies

    np.testing.assert_allclose(
        np.diff(region_plots.cell_bounds([0, 1, 3])), studies.cell_widths([0, 1, 3])
    )


@pytest.mark.parametrize("maker", ["region_map", "energy_map"])
def test_two_cell_grid_paints_exactly_the_sampled_cells(maker):
    region = fake_region(
        grid_cells([25.0, 50.0], [0.05, 0.2], lambda f, d: "recovered" if f * d < 5 else "fell")
    )
    fig = getattr(region_plots, maker)(region)
    ax = fig.axes[0]
    assert ax.get_xlim() == pytest.approx((25.0, 50.0))  # not -25..75 N
    assert ax.get_ylim() == pytest.approx((0.05, 0.2))  # no negative durations
    assert _mesh_extent(ax) == pytest.approx((25.0, 50.0, 0.05, 0.2))
    assert ax.get_yscale() == "linear"
    assert ax.get_xlabel().startswith("push force F [N]")
    assert ax.get_ylabel().startswith("push duration T [s]")
    assert "grid: 2 forces 25..50 N x 2 durations 0.05..0.2 s" in ax.get_title()


def test_log_duration_axis_across_a_decade():
    durations = [0.05, 0.1, 0.5, 1.0, 5.0]
    region = fake_region(
        grid_cells([0, 10, 20], durations, lambda f, d: "recovered" if f * d < 5 else "fell")
    )
    ax = region_plots.region_map(region).axes[0]
    assert ax.get_yscale() == "log"
    assert ax.get_ylim() == pytest.approx((0.05, 5.0))
    ys = np.unique(_mesh(ax).get_coordinates()[..., 1])
    np.testing.assert_allclose(ys, region_plots.cell_bounds(durations, log=True))
    np.testing.assert_allclose(ys[1], np.sqrt(0.05 * 0.1))  # geometric midpoints
    narrow = fake_region(grid_cells([0, 10], [0.05, 0.1, 0.4], lambda f, d: "recovered"))
    assert region_plots.region_map(narrow).axes[0].get_yscale() == "linear"


def _legend_texts(ax) -> list[str]:
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_legend_names_every_outcome_with_its_count():
    outcomes = {
        (0.0, 0.1): "recovered",
        (0.0, 0.2): "recovered",
        (50.0, 0.1): "not_settled",
        (50.0, 0.2): "fell",
        (100.0, 0.1): "diverged",
        (100.0, 0.2): "fell",
    }
    region = fake_region(grid_cells([0, 50, 100], [0.1, 0.2], lambda f, d: outcomes[(f, d)]))
    texts = _legend_texts(region_plots.region_map(region).axes[0])
    for name, count in (
        ("recovered", 2),
        ("not settled by t_end", 1),
        ("fell", 2),
        ("diverged", 1),
    ):
        assert f"{name} ({count})" in texts, texts
    # classes absent from the map are still listed, with 0
    only = fake_region(grid_cells([0, 50], [0.1, 0.2], lambda f, d: "recovered"))
    texts = _legend_texts(region_plots.region_map(only).axes[0])
    assert {
        f"{region_plots.OUTCOME_LABELS[n]} ({4 if n == 'recovered' else 0})" for n in OUTCOMES
    } <= set(texts)


def test_table_curve_and_impulse_lines_on_the_map(tmp_path):
    region = fake_region(
        grid_cells(
            np.arange(0, 130, 10.0),
            np.round(np.arange(0.05, 2.01, 0.05), 2),
            lambda f, d: "recovered" if f * d < 20 else "fell",
        )
    )
    table = pd.DataFrame(
        {
            "force": [20.0, 60.0, 100.0, 500.0],
            "max_acting_time": [0.99, 0.33, 0.19, 0.04],
            "convention": "paper",
        }
    )
    ax = region_plots.region_map(region, table=table).axes[0]
    (curve,) = [line for line in ax.get_lines() if "max acting time" in str(line.get_label())]
    np.testing.assert_allclose(curve.get_xdata(), [20, 60, 100])  # 500 N is off the map
    np.testing.assert_allclose(curve.get_ydata(), [0.99, 0.33, 0.19])
    assert "max acting time, bisected to 0.01 s (table.csv)" in _legend_texts(ax)
    labels = [t.get_text() for t in ax.texts]
    assert any(t.startswith("F·T = ") and t.endswith(" N·s") for t in labels), labels
    # plot_region finds the table.csv of its folder (a sweep folder), of the same convention
    table.to_csv(tmp_path / "table.csv", index=False)
    found = region_plots._table_beside(tmp_path / "region.png", region)
    assert found is not None and list(found.force) == [20, 60, 100, 500]
    assert (
        region_plots._table_beside(tmp_path / "region.png", region.assign(convention="joint"))
        is None
    )


def test_energy_map_shows_recovered_cells_only():
    region = fake_region(
        grid_cells([0, 50, 100], [0.1, 0.2], lambda f, d: "recovered" if f < 60 else "fell")
    )
    ax = region_plots.energy_map(region).axes[0]
    values = _mesh(ax).get_array()
    # cells in grid order (duration rows, force columns): the 100 N column did not recover
    grid = np.ma.getmaskarray(values).reshape(2, 3)
    assert grid[:, 2].all() and not grid[:, :2].any()
    assert any("not recovered (2 cells)" in t for t in _legend_texts(ax))


def test_figure_functions_draw_on_given_axes():
    region = fake_region(grid_cells([0, 50], [0.1, 0.2], lambda f, d: "recovered"))
    fig, axes = plt.subplots(1, 2)
    assert region_plots.region_map(region, ax=axes[0]) is fig
    assert region_plots.energy_map(region, ax=axes[1]) is fig
    table = pd.DataFrame(
        {
            "force": [20.0],
            "max_acting_time": [0.5],
            "monotone": [True],
            "ending_outcome": ["fell"],
            "outcome_01": ["recovered"],
            "energy_total_01": [1.0],
            "energy_total_max": [2.0],
            "energy_ankle_max": [1.5],
            "energy_hip_max": [0.5],
            "convention": ["paper"],
        }
    )
    fig2, axes2 = plt.subplots(1, 2)
    assert region_plots.table_figure(table, axes=axes2) is fig2


def test_table_energies_are_those_of_recovered_runs():
    """table.csv's energy_*_01 / _max hold a recovered run's energy or NaN, never a fall's."""
    forces = [20.0, 200.0, 300.0, 4000.0]  # |F| T < 30 recovers: T = 0.1 s falls from 300 N
    result = sweep.max_acting_time(
        forces, Config(), run_batch=FakeThresholdBatch(), progress=False, say=None
    )
    table = result.table.set_index("force")
    energies = [c for c in sweep.TABLE_COLUMNS if c.startswith(("energy_", "study_energy_"))]
    assert {c.rsplit("_", 1)[1] for c in energies} == {"01", "max"}
    for force, row in table.iterrows():
        ok_01 = row["outcome_01"] == "recovered"
        assert ok_01 == (abs(force) * 0.1 < 30)
        for column in (c for c in energies if c.endswith("_01")):
            assert np.isnan(row[column]) != ok_01, (force, column)
    within(
        table.loc[20.0, "energy_total_01"],
        3 * 20 * 0.1,
        rtol=1e-6,
        why="the stand-in computes 3 |F| T from float32 F and T: three roundings, <= 1.8e-7",
    )
    assert np.isnan(table.loc[300.0, "energy_total_01"])  # fell: 90 J up to the fall, left out
    within(
        table.loc[300.0, "energy_total_max"],
        3 * 300 * 0.09,
        rtol=1e-5,
        why="the stand-in computes 3 |F| T from float32 F and T: three roundings, <= 1.8e-7",
    )
    assert table.loc[4000.0, [c for c in energies if c.endswith("_max")]].isna().all()
    # every energy left in the table is the energy of a recovered run of the same force
    runs = result.runs
    recovered = runs[runs.outcome == "recovered"]
    for force, row in table.iterrows():
        mine = recovered[np.isclose(recovered.force, force)]
        for column in ("energy_total_01", "energy_total_max"):
            if np.isfinite(row[column]):
                # one of them (np.isclose's tolerances): the nearest
                nearest = mine.energy_total.to_numpy()[
                    np.argmin(np.abs(mine.energy_total.to_numpy() - row[column]))
                ]
                within(
                    nearest,
                    row[column],
                    rtol=1e-6,
                    atol=1e-8,
                    msg=(force, column),
                    why="the same float32 number, through the table's float64 frame",
                )


# --- time series ------------------------------------------------------------------------------


def test_timeseries_figure_push_bounds_outcomes_and_trim():
    df, summary = synthetic_series()
    config = Config()
    fig, ax = plt.subplots()
    assert plots.timeseries_figure(df, "u1", config=config, summary=summary, ax=ax) is fig
    # the push window [0, T] shaded
    spans = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_width() > 0]
    assert any(p.get_x() == pytest.approx(0) and p.get_width() == pytest.approx(0.1) for p in spans)
    # the input bound of u1 drawn
    levels = {
        round(float(line.get_ydata()[0]), 9)
        for line in ax.get_lines()
        if line.get_linestyle() == "--"
    }
    assert {-20.0, 20.0} <= levels
    # outcomes in the legend
    texts = _legend_texts(ax)
    assert any(t.startswith("F = 50 N: recovered") for t in texts), texts
    assert any(t.startswith("F = 120 N: fell at 0.90 s") for t in texts), texts
    assert any(t.startswith("MPC bound [-20, 20]") for t in texts), texts
    # the time axis ends after the action (settle ~1.1 s, fall 0.9 s), well before t_end = 4 s
    assert 1.1 < ax.get_xlim()[1] < 2.5
    assert ax.get_xlabel() == "time [s]" and ax.get_ylabel() == "u1 [N m]"
    full = plots.timeseries_figure(df, "u1", config=config, summary=summary, full_window=True).axes[
        0
    ]
    assert full.get_xlim()[1] == pytest.approx(4.0)


def test_recovered_runs_stay_readable_beside_a_fall():
    df, summary = synthetic_series()
    ax = plots.timeseries_figure(df, "ankle_angle", summary=summary).axes[0]
    kept = df[df.force < 100].q_a
    low, high = ax.get_ylim()
    assert low <= kept.min() and high >= kept.max()
    assert high < 0.5 * df.q_a.max()  # the fall leaves the axes: the recoveries fill them
    assert "zoomed" in ax.get_title()


def test_timeseries_outcomes_without_a_summary():
    df, _ = synthetic_series()
    runs = plots.runs_of(df)
    assert [r.outcome for r in runs] == ["recovered", "recovered", "fell"]


def test_timeseries_figures_write_states_and_inputs(tmp_path):
    df, summary = synthetic_series(t_end=1.5)
    paths = plots.timeseries_figures(df, tmp_path, config=Config(), summary=summary)
    names = {p.name for p in paths}
    assert {"states.png", "inputs.png", "energy.png", "ankle_angle.png", "cop.png"} <= names
    assert all(p.stat().st_size > 5_000 for p in paths)


def test_the_step_boundaries_join_the_legend_and_it_stays_on_the_figure():
    """With steps_needed (capturability) the map's key gains the two step boundaries; on a
    grid where one step saves every fall the label says so, and the key, with every line the
    default sweep's map draws (the hip's takeover too), still lies inside the figure (a longer
    label once pushed it past both edges)."""
    region = fake_region(
        grid_cells(
            np.arange(0, 160, 10.0),
            [0.05, 0.1, 0.2, 0.5, 1.0, 1.5],
            lambda f, d: "recovered" if f * d < 20 else "fell",
        ),
        steps_needed=lambda f, d: 0.0 if f * d < 20 else 1.0,
        energy_hip=lambda f, d: push_energy(f, d) * (0.5 if f >= 30 else 0.1),
    )
    table = pd.DataFrame({"force": [20.0, 50.0], "max_acting_time": [0.99, 0.39]})
    fig = region_plots.region_map(region, table=table)
    ax = fig.axes[0]
    texts = _legend_texts(ax)
    assert "with one step: whole grid (top edge)" in texts
    assert "with two steps: whole grid (top edge)" in texts
    assert any(t.startswith("hip takes over") for t in texts), texts
    fig.canvas.draw()
    box, page = ax.get_legend().get_window_extent(), fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1, (box, page)
    plt.close(fig)
