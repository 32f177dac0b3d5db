"""The report's blocks shared by its sections (html.py and the sections of extra.py)."""

from __future__ import annotations

import base64
from pathlib import Path


def img(path: Path, caption: str = "", alt: str | None = None) -> dict:
    """A figure block of the PNG at ``path`` (embedded); ``alt`` defaults to the caption, else
    the file's stem."""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return {"kind": "figure", "data": data, "caption": caption,
            "alt": alt or caption or Path(path).stem}
