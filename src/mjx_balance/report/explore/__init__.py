"""``mjx-balance explore DIR``: a local page on which every cell of a region map opens its run.

The page is served on this machine only (127.0.0.1) by the standard library's
``http.server`` and draws the folder's maps itself (inline SVG, plain JavaScript shipped in
``static/``: no file from the network). Clicking a cell runs that push through the scalar
reference (MuJoCo C + OSQP) in the map's own configuration and keeps the run in the map's
folder (``explore/<force>_<duration>.parquet``), so the next click on it is served from there.

    folder.py   what a folder holds: its kind (sweep, compare, cohort), its maps, each map's
                cells, boundary and table points as the page's JSON; read as the folder stands
                (a sweep under way shows the chunks written so far)
    runs.py     one cell's run: the request checked as a command-line value is, computed
                on demand or read back from the folder, and its series, stick figure and the
                commands that reproduce it as the page's JSON
    server.py   the HTTP server (GET only, one endpoint per action, nothing served from
                outside the folder) and :class:`Explorer`, which ``mb.explore`` returns
    static/     index.html, explore.js, explore.css: the page

docs/outputs.md, "mjx-balance explore", describes the page and its endpoints.
"""

from .folder import Folder, open_folder
from .server import Explorer

__all__ = ["Explorer", "Folder", "open_folder"]
