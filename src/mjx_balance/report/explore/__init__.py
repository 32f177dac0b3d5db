"""``mjx-balance explore DIR``: a local page on which every cell of a region map opens its run.

The page is served on this machine only (127.0.0.1) by the standard library's
``http.server`` and draws the folder's maps itself (inline SVG, plain JavaScript shipped in
``static/``: no file from the network). Clicking a cell runs that push through the scalar
reference (MuJoCo C + OSQP) in the map's own configuration and keeps the run in the map's
folder (``explore/<force>_<duration>.parquet``), so the next click on it is served from there.

docs/explore.md, "mjx-balance explore", describes the page and its endpoints;
docs/architecture.md, "The modules", maps this package's modules.
"""

from .folder import Folder, open_folder
from .server import Explorer

__all__ = ["Explorer", "Folder", "open_folder"]
