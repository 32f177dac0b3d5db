"""The figures' one style: the outcome palette, the file format and the paper sizes.

Outcome palette (:data:`OUTCOME_COLOURS`, every figure and the animation take it from here):
Okabe & Ito's colour-blind-safe colours, recovered bluish green ``#009E73``, not settled yellow
``#F0E442``, fell vermillion ``#D55E00``, diverged dark grey ``#3A3A3A``. Under the Machado et
al. (2009) deuteranopia and protanopia simulations the three main colours stay at least 33.6
and 37.2 CIELAB units apart (CIE76; ``tests/figures/test_figure_style.py`` computes it and asks
for 30); in greyscale recovered and fell have nearly the same lightness (L* 58 and 54), so the fell
cells are also hatched
(:data:`OUTCOME_HATCHES`). Series without an outcome (several runs, configurations,
thresholds) take :data:`SERIES`, the Okabe-Ito colours in a fixed order.

Format and size (:func:`figure_style`, a context: the command line's ``--figure-format`` and
``--figure-size``, the API's ``figure_format=`` and ``figure_size=``):

    format   png (default), svg or pdf: a figure saved through :func:`save` under a name ending
             in .png gets the format's suffix instead (region.png -> region.svg)
    size     screen (default: each figure's own size, as before), one-column (3.5 in, 89 mm
             wide) or two-column (7.2 in, 183 mm): the figure is exactly that wide; its height
             grows until every panel is at least MIN_PANEL_HEIGHT high; fonts are 7 to 9 pt;
             texts and legends that would reach past the figure's edge are wrapped (legends
             first go to one column), so every text lies inside the figure

Light at import (the command line's parser reads the choices): matplotlib and the store load
when a figure is saved.
"""

from __future__ import annotations

import contextvars
import textwrap
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..model.params import ParameterError

if TYPE_CHECKING:  # (annotations only: matplotlib loads when a figure is drawn)
    from matplotlib.typing import RcKeyType

OUTCOME_COLOURS = {
    "recovered": "#009E73",  # Okabe-Ito bluish green
    "not_settled": "#F0E442",  # Okabe-Ito yellow
    "fell": "#D55E00",  # Okabe-Ito vermillion, hatched (greyscale: as light as green)
    "diverged": "#3A3A3A",  # dark grey
}
OUTCOME_HATCHES = {"recovered": "", "not_settled": "", "fell": "///", "diverged": ""}
SERIES = (
    "#0072B2",
    "#D55E00",
    "#009E73",
    "#CC79A7",
    "#E69F00",
    "#56B4E9",
    "#000000",
    "#F0E442",
)  # Okabe-Ito, strongest first

FIGURE_FORMATS = ("png", "svg", "pdf")
FIGURE_SIZES = {"screen": None, "one-column": 3.5, "two-column": 7.2}  # width [in]
MIN_FONT_PT, MAX_FONT_PT = 7.0, 9.0  # a column figure's text sizes
MIN_PANEL_HEIGHT = {"one-column": 1.6, "two-column": 2.2}  # [in]
MAX_HEIGHT = 9.5  # [in]: a column figure never grows taller than a page's text block
COLUMN_RC: dict[RcKeyType, Any]  # (the keys matplotlib knows)
COLUMN_RC = {
    "font.size": 8,
    "axes.titlesize": 8,
    "axes.labelsize": 8,
    "xtick.labelsize": 7,
    "ytick.labelsize": 7,
    "legend.fontsize": 7,
    "legend.title_fontsize": 7,
    "figure.titlesize": 8,
    "lines.linewidth": 1.2,
    "lines.markersize": 4,
    "axes.linewidth": 0.6,
    "hatch.linewidth": 0.6,
}
SAVE_RC: dict[RcKeyType, Any]
SAVE_RC = {"pdf.fonttype": 42, "ps.fonttype": 42}  # TrueType in PDFs (editable, as journals ask)


@dataclass(frozen=True)
class FigureStyle:
    format: str = "png"
    size: str = "screen"

    @property
    def width(self) -> float | None:
        """The figure's width [in] (None: screen, each figure's own)."""
        return FIGURE_SIZES[self.size]


_CURRENT: contextvars.ContextVar[FigureStyle] = contextvars.ContextVar(
    "mjx_balance_figure_style",
    default=FigureStyle(),  # noqa: B039 - a frozen dataclass
)


def current() -> FigureStyle:
    """The figure style in effect (the defaults outside :func:`figure_style`)."""
    return _CURRENT.get()


def check_format(value: str) -> str:
    """``value`` when it is a figure format, else ParameterError (a ValueError) naming it."""
    text = str(value).strip().lower().lstrip(".")
    if text not in FIGURE_FORMATS:
        raise ParameterError(f"figure format {value!r}: must be one of {', '.join(FIGURE_FORMATS)}")
    return text


def check_size(value: str) -> str:
    """``value`` when it is a figure size, else ParameterError (a ValueError) naming it."""
    text = str(value).strip().lower().replace("_", "-")
    if text not in FIGURE_SIZES:
        raise ParameterError(f"figure size {value!r}: must be one of {', '.join(FIGURE_SIZES)}")
    return text


@contextmanager
def figure_style(format: str | None = None, size: str | None = None) -> Iterator[FigureStyle]:
    """A context in which figures are drawn and saved in a format and a size.

    Column sizes also set matplotlib's font sizes for the figures drawn inside.

    Args:
        format: ``"png"``, ``"svg"`` or ``"pdf"`` (None: the style in effect).
        size: ``"screen"``, ``"one-column"`` (3.5 in) or ``"two-column"`` (7.2 in) (None: the
            style in effect).

    Raises:
        ParameterError: an unknown value.

    Example:
        >>> with mb.figure_style(format="pdf", size="one-column"):
        ...     mb.save_figure(mb.region_map(region), "region.pdf")
    """
    before = current()
    style = FigureStyle(
        check_format(format) if format is not None else before.format,
        check_size(size) if size is not None else before.size,
    )
    token = _CURRENT.set(style)
    try:
        if style.width is None:
            yield style
        else:
            import matplotlib

            with matplotlib.rc_context(COLUMN_RC):
                yield style
    finally:
        _CURRENT.reset(token)


def figure_path(path: str | Path) -> Path:
    """``path`` as the current format names it: a .png name gets the format's suffix."""
    path = Path(path)
    fmt = current().format
    return path.with_suffix("." + fmt) if path.suffix.lower() == ".png" else path


def figure_name(name: str) -> str:
    """A figure's file name (``region.png``) in the current format (``region.svg``)."""
    return figure_path(name).name


def subplots(
    nrows: int = 1,
    ncols: int = 1,
    *,
    figsize: tuple[float, float],
    stack: bool = True,
    **kwargs: Any,
) -> tuple[Any, Any]:
    """``plt.subplots`` with constrained layout in the current size: ``figsize`` on a screen;
    at a column width the figure is that wide (height scaled with it, at least
    MIN_PANEL_HEIGHT per row), and at one column a row of panels is stacked into one column
    (the axes keep the shape ``plt.subplots`` gives them; ``stack=False`` keeps the grid, for
    panels that share a colour bar per column)."""
    import matplotlib.pyplot as plt
    import numpy as np

    style = current()
    kwargs.setdefault("layout", "constrained")
    if style.width is None:
        return plt.subplots(nrows, ncols, figsize=figsize, **kwargs)
    squeeze = kwargs.pop("squeeze", True)
    rows, cols = nrows, ncols
    if style.size == "one-column" and ncols > 1 and stack:
        rows, cols = nrows * ncols, 1
        kwargs.pop("width_ratios", None)
        (kwargs.get("gridspec_kw") or {}).pop("width_ratios", None)
    panel_h = max(
        MIN_PANEL_HEIGHT[style.size],
        style.width / cols * figsize[1] / figsize[0] * ncols / max(nrows, 1) * 0.9,
    )
    height = min(MAX_HEIGHT, panel_h * rows + 0.5)
    fig, axes = plt.subplots(rows, cols, figsize=(style.width, height), squeeze=False, **kwargs)
    axes = np.asarray(axes).reshape(nrows, ncols)
    if squeeze:
        axes = axes.item() if axes.size == 1 else axes.squeeze()
    return fig, axes


def save(fig: Any, path: str | Path, *, dpi: int = 120, close: bool = True) -> Path:
    """Save a figure atomically in the current style.

    The path's .png becomes the format's suffix; a column size fits the figure to the column.

    Args:
        fig: The Figure.
        path: Where to save it.
        dpi: Dots per inch for raster formats (None: the style's).
        close: Close the figure afterwards (also on a failed write).

    Returns:
        The path written.
    """
    import matplotlib

    from ..store.files import write_figure  # lazy: the store floor loads pandas

    path = figure_path(path)
    try:
        if current().width is not None:
            fit_to_column(fig)
        with matplotlib.rc_context(SAVE_RC):
            write_figure(fig, path, dpi=dpi)
    finally:
        if close:
            import matplotlib.pyplot as plt

            plt.close(fig)
    return path


# ---------------------------------------------------------------------------------------------
# Fitting a figure to a column: its width, font sizes, wrapped texts, tall enough panels


def drawn_texts(fig: Any) -> list[Any]:
    """Every non-empty visible text the figure draws: its own texts and titles, each axes'
    titles, texts, axis labels, tick labels inside the view and legends' texts."""
    from matplotlib.text import Text

    texts = [t for t in fig.get_children() if isinstance(t, Text)]
    for legend in fig.legends:
        texts += [*legend.get_texts(), legend.get_title()]
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        texts += [t for t in ax.get_children() if isinstance(t, Text)]
        for axis in (ax.xaxis, ax.yaxis):
            low, high = sorted(axis.get_view_interval())
            span = (high - low) * 1e-9
            texts += [axis.label, axis.get_offset_text()]
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if low - span <= tick.get_loc() <= high + span:
                    texts += [tick.label1, tick.label2]
        legend = ax.get_legend()
        if legend is not None:
            texts += [*legend.get_texts(), legend.get_title()]
    return [
        t
        for t in texts
        if t.get_visible() and t.get_text().strip() and (t.axes is None or t.axes.get_visible())
    ]


def outside(fig: Any, texts: list[Any] | None = None, tolerance: float = 1.0) -> list[Any]:
    """The drawn texts whose window extent reaches past the figure's edge by more than
    ``tolerance`` pixels, in the figure's layout as it is drawn (drawn here: a savefig at
    another dpi leaves the canvas's renderer at that dpi)."""
    fig.draw_without_rendering()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    found = []
    for text in drawn_texts(fig) if texts is None else texts:
        ext = text.get_window_extent(renderer)
        if (
            ext.x0 < box.x0 - tolerance
            or ext.x1 > box.x1 + tolerance
            or ext.y0 < box.y0 - tolerance
            or ext.y1 > box.y1 + tolerance
        ):
            found.append(text)
    return found


def _rewrap(text: Any, factor: float) -> bool:
    """Wrap ``text``'s lines to ``factor`` of its longest line's characters (mathtext is left
    as it is); whether it changed."""
    content = text.get_text()
    if "$" in content:
        return False
    lines = content.split("\n")
    width = max(8, int(max(len(line) for line in lines) * factor))
    wrapped = "\n".join(textwrap.fill(line, width) if len(line) > width else line for line in lines)
    if wrapped == content:
        return False
    text.set_text(wrapped)
    return True


def _legends(fig: Any) -> list[Any]:
    return list(fig.legends) + [
        ax.get_legend() for ax in fig.axes if ax.get_legend() is not None and ax.get_visible()
    ]


def _legends_below(fig: Any) -> None:
    """An axes' legend placed below it (a map's key) becomes a figure legend under the whole
    figure, in two columns where they fit, else one: constrained layout would otherwise widen
    the axes' margins to the legend's width."""
    for ax in list(fig.axes):
        legend = ax.get_legend()
        if legend is None or legend.get_bbox_to_anchor().y1 >= ax.bbox.y0 - 1:
            continue
        title = legend.get_title().get_text() or None
        handles, labels = legend.legend_handles, [t.get_text() for t in legend.get_texts()]
        size = legend.get_texts()[0].get_fontsize() if labels else MIN_FONT_PT
        legend.remove()
        for ncols in (2, 1):
            moved = fig.legend(
                handles,
                labels,
                loc="outside lower center",
                ncols=ncols,
                frameon=False,
                fontsize=size,
                title=title,
                title_fontsize=size,
            )
            fig.draw_without_rendering()
            wide = moved.get_window_extent(fig.canvas.get_renderer()).width
            if ncols == 1 or wide <= 0.94 * fig.bbox.width:
                break
            moved.remove()


def _narrow_legends(fig: Any, renderer: Any, room: float) -> None:
    """Before the layout: a legend wider than ``room`` pixels has its labels wrapped (a
    legend's width does not depend on where the layout puts it)."""
    for legend in _legends(fig):
        for _ in range(6):
            ext = legend.get_window_extent(renderer)
            if ext.width <= room:
                break
            texts = legend.get_texts() + [legend.get_title()]
            widest = max(t.get_window_extent(renderer).width for t in texts)
            allowed = widest - (ext.width - room)
            if not any(
                _rewrap(t, 0.95 * allowed / widest)
                for t in texts
                if t.get_window_extent(renderer).width > allowed
            ):
                break
            fig.draw_without_rendering()


def _wrap_long(fig: Any, renderer: Any, room_x: float, room_y: float) -> bool:
    """Wrap the titles and labels longer than the room they have (pixels, along the text)."""
    changed = False
    for text in drawn_texts(fig):
        ext = text.get_window_extent(renderer)
        vertical = abs(text.get_rotation() % 180 - 90) < 1
        length, room = (ext.height, room_y) if vertical else (ext.width, room_x)
        if length > room:
            changed |= _rewrap(text, 0.95 * room / length)
    return changed


def _layout(fig: Any) -> bool:
    """Draw the layout; whether constrained layout collapsed (the figure too small for it)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fig.draw_without_rendering()
    return any("collapsed" in str(w.message) for w in caught)


def _grow(fig: Any, size: str) -> bool:
    """Make the figure taller when its shortest panel is under MIN_PANEL_HEIGHT."""
    panels = [ax for ax in fig.axes if ax.get_visible() and ax.get_label() != "<colorbar>"]
    if not panels:
        return False
    height = fig.get_figheight()
    shortest = min(ax.get_position().height for ax in panels) * height
    rows = len({round(ax.get_position().y0, 3) for ax in panels})
    lack = (MIN_PANEL_HEIGHT[size] - shortest) * rows
    if lack <= 0.02 or height >= MAX_HEIGHT:
        return False
    fig.set_figheight(min(MAX_HEIGHT, height + lack))
    return True


def _clamp_fonts(fig: Any) -> None:
    """Every text's size within [MIN_FONT_PT, MAX_FONT_PT] (tick labels through tick_params:
    new ticks copy the first tick's label size)."""

    def clamp(size: float) -> float:
        return min(max(size, MIN_FONT_PT), MAX_FONT_PT)

    for ax in fig.axes:
        for axis, which in ((ax.xaxis, "x"), (ax.yaxis, "y")):
            for minor in (False, True):
                ticks = axis.get_minor_ticks() if minor else axis.get_major_ticks()
                if ticks:
                    ax.tick_params(
                        axis=which,
                        which="minor" if minor else "major",
                        labelsize=clamp(ticks[0].label1.get_fontsize()),
                    )
    for text in drawn_texts(fig):
        text.set_fontsize(clamp(text.get_fontsize()))


def fit_to_column(fig: Any) -> None:
    """Fit ``fig`` to the current column size: exactly its width, fonts within [MIN_FONT_PT,
    MAX_FONT_PT], legends narrowed and texts wrapped to stay inside the figure, the figure
    taller until its panels are at least MIN_PANEL_HEIGHT high (at most MAX_HEIGHT)."""
    style = current()
    width, height = fig.get_size_inches()
    if abs(width - style.width) > 1e-6:
        fig.set_size_inches(style.width, min(MAX_HEIGHT, height * style.width / width))
    if fig.get_layout_engine() is None:
        fig.set_layout_engine("constrained")
    _layout(fig)
    _clamp_fonts(fig)
    _legends_below(fig)
    _layout(fig)  # a legend measures its size when drawn
    renderer = fig.canvas.get_renderer()
    room = 0.94 * fig.bbox.width
    _narrow_legends(fig, renderer, room)
    _wrap_long(fig, renderer, room, 0.8 * fig.bbox.height)
    for _ in range(20):
        if _layout(fig):
            if fig.get_figheight() >= MAX_HEIGHT:
                break
            fig.set_figheight(min(MAX_HEIGHT, fig.get_figheight() + 0.5))
            continue
        renderer = fig.canvas.get_renderer()
        changed = _grow(fig, style.size)
        for text in [] if changed else outside(fig):  # placed past the edge: wrap it shorter
            changed |= _rewrap(text, 0.8)
        if not changed:
            break
    fig.draw_without_rendering()  # the layout as saved (a collapse that remains warns)
