"""The report's blocks shared by its sections (html.py and the sections of extra.py), and how
their figures are embedded in the page."""

from __future__ import annotations

import base64
import io
from pathlib import Path

# The page's column is at most 1150 CSS px wide (html.CSS: body max-width, less its padding), a
# figure in a row of two about half of it (555 px). An embedded image keeps a little more than
# the pixels it is shown with (headroom for zoom): more only adds bytes.
FULL_WIDTH_PX = 1200
ROW_WIDTH_PX = 600
# Matplotlib's figures are flat colours and their anti-aliased edges: an adaptive palette of 64
# colours chosen for coverage (Pillow's MAXCOVERAGE; median cut turned thin coloured lines
# grey at the same count), without dithering, keeps lines, faint grid lines and text
# (tests/report/test_report_browser.py; the report's size: docs/outputs.md).
PALETTE_COLOURS = 64


def img(path: Path, caption: str = "", alt: str | None = None) -> dict:
    """A figure block of the PNG at ``path`` (embedded when the page is rendered: ``embed``);
    ``alt`` defaults to the caption, else the file's stem."""
    return {
        "kind": "figure",
        "path": str(path),
        "caption": caption,
        "alt": alt or caption or Path(path).stem,
    }


def png_data(path: str | Path, max_width: int) -> str:
    """The PNG at ``path`` as base64 text for the page: scaled down (Lanczos) to ``max_width``
    pixels where wider, as a palette PNG of at most PALETTE_COLOURS colours."""
    from PIL import Image  # lazy: only the page's rendering needs Pillow

    with Image.open(path) as image:
        rgb = image.convert("RGB")
    if rgb.width > max_width:
        rgb = rgb.resize(
            (max_width, round(rgb.height * max_width / rgb.width)), Image.Resampling.LANCZOS
        )
    palette = rgb.quantize(
        colors=PALETTE_COLOURS, method=Image.Quantize.MAXCOVERAGE, dither=Image.Dither.NONE
    )
    buffer = io.BytesIO()
    palette.save(buffer, format="PNG", optimize=True)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def embed(sections: list[dict]) -> list[dict]:
    """The sections with every figure block's image data filled in (``data``): a figure in a
    row of figures at ROW_WIDTH_PX, any other at FULL_WIDTH_PX."""

    def figure(block: dict, width: int) -> dict:
        return {**block, "data": png_data(block["path"], width)}

    def one(block: dict) -> dict:
        if block.get("kind") == "figure":
            return figure(block, FULL_WIDTH_PX)
        if block.get("kind") == "row":
            return {**block, "figures": [figure(f, ROW_WIDTH_PX) for f in block["figures"]]}
        return block

    return [{**s, "blocks": [one(b) for b in s["blocks"]]} for s in sections]
