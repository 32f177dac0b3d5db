"""Publication figures: one colour-blind-safe outcome palette used by every
figure, the figure formats (png, svg, pdf) and the paper sizes (one and two columns) with
every text inside the figure. Synthetic frames only (no simulation) except the command-line
test, which runs the stand-in rollout of test_store_faults."""

from __future__ import annotations

import argparse
import itertools
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from support import REPO, cli_sweep, fake_region, grid_cells, synthetic_series

from mjx_balance.cli.main import build_parser
from mjx_balance.figures import animation, strategy, style, timeseries
from mjx_balance.figures import region as region_plots
from mjx_balance.figures import scorecard as scorecard_plots
from mjx_balance.model.params import ParameterError
from mjx_balance.store.files import readable_figure
from mjx_balance.studies import compare

SRC = REPO / "src" / "mjx_balance"
MAIN = ("recovered", "not_settled", "fell")


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


# --- the palette ------------------------------------------------------------------------------

# Machado, Oliveira & Fernandes (2009), "A physiologically-based model for simulation of color
# vision deficiency", IEEE TVCG 15(6), severity 1.0; applied to linear RGB.
MACHADO = {
    "protanopia": np.array(
        [
            [0.152286, 1.052583, -0.204868],
            [0.114503, 0.786281, 0.099216],
            [-0.003882, -0.048116, 1.051998],
        ]
    ),
    "deuteranopia": np.array(
        [
            [0.367322, 0.860646, -0.227968],
            [0.280085, 0.672501, 0.047413],
            [-0.011820, 0.042940, 0.968881],
        ]
    ),
}
SRGB_TO_XYZ = np.array(
    [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]
)
D65 = np.array([0.95047, 1.0, 1.08883])


def linear_rgb(colour: str) -> np.ndarray:
    c = np.array(matplotlib.colors.to_rgb(colour))
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lab(linear: np.ndarray) -> np.ndarray:
    """CIELAB (D65) of a linear-RGB colour."""
    t = SRGB_TO_XYZ @ np.clip(linear, 0, 1) / D65
    f = np.where(t > (6 / 29) ** 3, np.cbrt(t), t / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def delta_e(a: str, b: str, matrix: np.ndarray | None = None) -> float:
    """CIE76 colour difference of two colours as seen through ``matrix`` (None: as they are)."""
    matrix = np.eye(3) if matrix is None else matrix
    return float(np.linalg.norm(lab(matrix @ linear_rgb(a)) - lab(matrix @ linear_rgb(b))))


# Tolerance: 30 CIELAB units between the three main outcomes, in normal vision and under both
# red-green simulations. A just-noticeable difference is about 2.3; map cells must read apart
# at a glance, so we ask for a wide margin (the old set1-like palette's green and red came to
# 21 under deuteranopia and fails). Greyscale: 20 L* units, unless one of the two is hatched.
MIN_DELTA_E = 30.0
MIN_LIGHTNESS = 20.0


def test_outcome_palette_reads_under_colour_blindness_and_in_greyscale():
    colours = style.OUTCOME_COLOURS
    for a, b in itertools.combinations(MAIN, 2):
        assert delta_e(colours[a], colours[b]) >= MIN_DELTA_E, (a, b)
        for name, matrix in MACHADO.items():
            assert delta_e(colours[a], colours[b], matrix) >= MIN_DELTA_E, (name, a, b)
    for a, b in itertools.combinations(colours, 2):
        lightness = abs(lab(linear_rgb(colours[a]))[0] - lab(linear_rgb(colours[b]))[0])
        hatched = bool(style.OUTCOME_HATCHES[a] or style.OUTCOME_HATCHES[b])
        assert lightness >= MIN_LIGHTNESS or hatched, (a, b, lightness)


def test_old_red_green_palette_fails_the_check():
    """The check can fail: the set1-like colours the region map had before."""
    green, red = "#4daf4a", "#e41a1c"
    assert delta_e(green, red, MACHADO["deuteranopia"]) < MIN_DELTA_E


OLD_OUTCOME_HEX = (
    "#4daf4a",
    "#ffd92f",
    "#e41a1c",
    "#1a9850",
    "#b8860b",
    "#d73027",
    "#e8b4a8",
    "#9fd0a4",
    "#1b5e20",
    "#b71c1c",
)


def test_every_outcome_colour_comes_from_the_one_palette():
    assert region_plots.OUTCOME_COLOURS is style.OUTCOME_COLOURS
    assert animation.OUTCOME_COLOURS is style.OUTCOME_COLOURS
    for path in SRC.rglob("*.py"):
        text = path.read_text().lower()
        found = [h for h in OLD_OUTCOME_HEX if h in text]
        assert not found, f"{path.relative_to(SRC)}: old outcome colours {found}"
        if path.name != "style.py":
            assert not re.search(r"outcome_colou?rs\s*=\s*\{", text), (
                f"{path.relative_to(SRC)} defines its own outcome colours"
            )
    for path in SRC.rglob("*.html"):  # the report's templates
        text = path.read_text().lower()
        assert not [h for h in OLD_OUTCOME_HEX if h in text], path


def test_region_map_uses_the_palette_and_hatches_the_falls():
    region = fake_region(CELLS, **JOINTS)
    ax = region_plots.region_map(region).axes[0]
    handles = ax.get_legend().legend_handles
    for name in style.OUTCOME_COLOURS:
        (patch,) = [
            h for h in handles if h.get_label().startswith(region_plots.OUTCOME_LABELS[name] + " (")
        ]
        assert (
            matplotlib.colors.to_hex(patch.get_facecolor()) == style.OUTCOME_COLOURS[name].lower()
        )
        assert (patch.get_hatch() or "") == style.OUTCOME_HATCHES[name]
    hatched = [c for c in ax.collections if c.get_hatch()]
    assert len(hatched) == 1 and len(hatched[0].get_paths()) == int(
        (region["outcome"] == "fell").sum()
    )


# --- formats and sizes ------------------------------------------------------------------------


# the made-up region of these figures (support.fake_region): every outcome on a 13 x 40 grid,
# with the energies of both joints
CELLS = grid_cells(
    np.arange(0, 130, 10.0),
    np.round(np.arange(0.05, 2.01, 0.05), 2),
    lambda f, d: (
        "recovered"
        if f * d < 12
        else "not_settled"
        if f * d < 16
        else "diverged"
        if f * d > 60
        else "fell"
    ),
)
JOINTS = {"energy_ankle": lambda f, d: 1 + 0.7 * f * d, "energy_hip": lambda f, d: 0.3 * f * d}


def _table() -> pd.DataFrame:
    force = np.array([20.0, 60.0, 100.0])
    return pd.DataFrame(
        {
            "force": force,
            "max_acting_time": [0.6, 0.2, 0.12],
            "monotone": True,
            "ending_outcome": "fell",
            "outcome_01": "recovered",
            "convention": "joint",
            "energy_total_01": 2.0,
            "energy_total_max": 5.0,
            "energy_ankle_max": 4.0,
            "energy_hip_max": 1.0,
        }
    )


def _scorecard() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "measure": "max_acting_time",
            "source": "paper",
            "force": [20.0, 60.0],
            "reference": [0.55, 0.21],
            "ours": [0.6, 0.2],
            "our_uncertainty": 0.01,
            "status": ["agrees", "differs"],
        }
    )


FIGURES = {  # name -> a function that draws it (a new figure)
    "region": lambda: region_plots.region_map(
        fake_region(CELLS, **JOINTS), table=_table().assign(convention="paper")
    ),
    "energy": lambda: region_plots.energy_map(fake_region(CELLS, **JOINTS)),
    "table": lambda: region_plots.table_figure(_table()),
    "strategy": lambda: strategy.strategy_map(fake_region(CELLS, **JOINTS)),
    "strategy_threshold": lambda: strategy.threshold_figure(fake_region(CELLS, **JOINTS)),
    "timeseries": lambda: timeseries.timeseries_figure(
        synthetic_series()[0], "ankle_angle", summary=synthetic_series()[1]
    ),
    "scorecard": lambda: scorecard_plots.scorecard_figure(_scorecard()),
}

INCH = 72.0  # PostScript points per inch (PDF and matplotlib's SVG use points)


def assert_fits(fig, width: float) -> None:
    """The figure is ``width`` inches wide, every drawn text lies inside it, none under 7 pt.

    Checked two ways: our list of drawn texts (titles, labels, tick labels in view, legends),
    each text's window extent within the figure's (1 px tolerance: extents are rounded to
    whole pixels), and matplotlib's own tight bounding box of everything drawn."""
    assert fig.get_figwidth() == pytest.approx(width, abs=1e-9)
    fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    texts = style.drawn_texts(fig)
    assert texts
    for text in texts:
        ext = text.get_window_extent(renderer)
        assert (
            ext.x0 >= box.x0 - 1
            and ext.x1 <= box.x1 + 1
            and ext.y0 >= box.y0 - 1
            and ext.y1 <= box.y1 + 1
        ), (text.get_text(), ext.bounds, box.bounds)
        assert text.get_fontsize() >= style.MIN_FONT_PT, (text.get_text(), text.get_fontsize())
    tight = fig.get_tightbbox(renderer)  # inches
    assert tight.x0 >= -0.02 and tight.x1 <= width + 0.02, tight.bounds
    assert tight.y0 >= -0.02 and tight.y1 <= fig.get_figheight() + 0.02, tight.bounds


@pytest.mark.parametrize("size", ["one-column", "two-column"])
@pytest.mark.parametrize("name", list(FIGURES))
def test_column_figures_fit_their_width_with_every_text_inside(tmp_path, name, size):
    with style.figure_style(format="png", size=size):
        fig = FIGURES[name]()
        path = style.save(fig, tmp_path / f"{name}.png", close=False)
    assert path == tmp_path / f"{name}.png" and readable_figure(path)
    assert_fits(fig, style.FIGURE_SIZES[size])
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>" and ax.get_visible()]
    assert (
        min(ax.get_position().height for ax in panels) * fig.get_figheight()
        >= min(style.MIN_PANEL_HEIGHT[size], 0.5 * style.MAX_HEIGHT) - 0.05
    )


# every time-series figure as PDF; one-column PNG and vector region maps stay in the default run
@pytest.mark.slow
def test_timeseries_figures_in_pdf_at_one_column(tmp_path):
    """Every time-series file (the single quantities and the panels of pairs, stacked at one
    column) in PDF, 3.5 in wide; the tolerance as in the region's test below."""
    series, summary = synthetic_series()
    with style.figure_style(format="pdf", size="one-column"):
        paths = timeseries.timeseries_figures(series, tmp_path, summary=summary)
    assert paths and all(p.suffix == ".pdf" and readable_figure(p) for p in paths)
    assert {p.stem for p in paths} >= {*timeseries.SINGLE, "states", "inputs"}
    for path in paths:
        assert _pdf_width(path) == pytest.approx(3.5 * INCH, abs=0.01), path.name
    assert not list(tmp_path.glob("*.png"))


def test_compare_figure_fits_one_column(tmp_path):
    regions = {
        "base": fake_region(CELLS, **JOINTS),
        "stiffer": fake_region(CELLS, **JOINTS).assign(
            outcome=lambda r: np.where(r.force < 60, "recovered", r.outcome)
        ),
    }
    frame = pd.DataFrame(
        {
            "name": list(regions),
            "area": [10.0, 20.0],
            "sustained_push_limit": [30.0, np.nan],
            "t_end": 4.0,
        }
    )
    with style.figure_style(format="svg", size="one-column"):
        path = compare.plot_compare(regions, tmp_path / compare.COMPARE_PNG, frame)
    assert path == tmp_path / "compare.svg" and readable_figure(path)
    assert not (tmp_path / "compare.png").exists()


def _pdf_width(path: Path) -> float:
    """The width [pt] of a PDF's first page (its MediaBox)."""
    box = re.search(
        rb"/MediaBox\s*\[\s*([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)\s*\]", path.read_bytes()
    )
    assert box, "no MediaBox"
    return float(box.group(3)) - float(box.group(1))


def _svg_width(path: Path) -> float:
    """The width [pt] of an SVG from its root's width attribute (matplotlib writes "252pt")."""
    import xml.etree.ElementTree as ET

    width = ET.parse(path).getroot().get("width")
    assert width and width.endswith("pt"), width
    return float(width[:-2])


@pytest.mark.parametrize("fmt", ["pdf", "svg"])
def test_region_at_one_column_in_vector_formats(tmp_path, fmt):
    """plot_region in --figure-format pdf / svg at one column: the file takes the format's
    suffix, its page is 3.5 in (252 pt) wide, every text inside. We save without
    bbox_inches="tight" (the width stays the one set), so the page width is checked; the
    tolerance, 0.01 pt, covers the number's printed decimals."""
    with style.figure_style(format=fmt, size="one-column"):
        path = region_plots.plot_region(fake_region(CELLS, **JOINTS), tmp_path / "region.png")
        fig = region_plots.region_map(fake_region(CELLS, **JOINTS))
        style.save(fig, tmp_path / "again.png", close=False)
    assert path == tmp_path / f"region.{fmt}" and readable_figure(path)
    assert not (tmp_path / "region.png").exists()
    width = _pdf_width(path) if fmt == "pdf" else _svg_width(path)
    assert width == pytest.approx(3.5 * INCH, abs=0.01)
    assert_fits(fig, 3.5)


@pytest.mark.filterwarnings("ignore:constrained_layout not applied")  # the point: it does not fit
def test_fitting_is_what_keeps_the_texts_inside(tmp_path, monkeypatch):
    """Without the fitting (the figure only resized to the column), the region map's legend
    and title reach past the figure: the check above would fail."""
    with style.figure_style(size="one-column"):
        fig = region_plots.region_map(fake_region(CELLS, **JOINTS))
    fig.set_size_inches(3.5, 4.0)
    fig.draw_without_rendering()
    assert style.outside(fig)


def test_readable_figure_rejects_cut_vector_files(tmp_path):
    for fmt in ("pdf", "svg"):
        with style.figure_style(format=fmt):
            path = region_plots.plot_energy(fake_region(CELLS, **JOINTS), tmp_path / "energy.png")
        assert readable_figure(path)
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        assert not readable_figure(path)
    assert not readable_figure(tmp_path / "missing.svg")


def test_bad_format_or_size_is_refused_with_its_value():
    with pytest.raises(ParameterError, match="'tiff'"), style.figure_style(format="tiff"):
        pass
    with pytest.raises(ParameterError, match="'a4'"), style.figure_style(size="a4"):
        pass
    assert style.current() == style.FigureStyle()  # nothing left set


# --- the command line -------------------------------------------------------------------------

FIGURE_COMMANDS = ("sweep", "table", "simulate", "compare", "landscape", "basin", "sensitivity")
NO_FIGURES = ("report", "animate", "bench", "model", "view")  # PNG in a page, a GIF, none


def test_every_command_that_writes_figures_takes_the_options(capsys):
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in FIGURE_COMMANDS + NO_FIGURES:  # a new command: its own test says which
        options = {o for a in sub.choices[name]._actions for o in a.option_strings}
        wanted = name in FIGURE_COMMANDS
        assert ("--figure-format" in options) == wanted, name
        assert ("--figure-size" in options) == wanted, name
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(["sweep", "--out", "x", "--figure-format", "tiff"])
    assert exc.value.code == 2 and "invalid choice: 'tiff'" in capsys.readouterr().err


def test_sweep_writes_svg_figures_and_resumes_on_them(tmp_path, fake_rollout, capsys):
    out = tmp_path / "run"
    assert cli_sweep(out, "--figure-format", "svg", "--figure-size", "two-column") == 0
    for stem in ("region", "energy", "strategy", "strategy_threshold"):
        assert readable_figure(out / f"{stem}.svg") and not (out / f"{stem}.png").exists()
        assert _svg_width(out / f"{stem}.svg") == pytest.approx(7.2 * INCH, abs=0.01)
    capsys.readouterr()
    assert cli_sweep(out, "--figure-format", "svg") == 0  # whole svg figures: left alone
    assert "wrote" not in capsys.readouterr().out
    (out / "energy.svg").write_text("<svg")  # cut short: drawn again
    assert cli_sweep(out, "--figure-format", "svg") == 0
    assert f"wrote {out / 'energy.svg'}" in capsys.readouterr().out
    assert readable_figure(out / "energy.svg")
