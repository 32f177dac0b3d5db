"""Render an HTML page in headless Chromium at a given width and audit its layout: every text
whose computed font size is under a minimum, and every element wider than the viewport that is
not inside a horizontally scrolling table wrapper (``.table-wrap``).

The driver needs no package beyond the standard library: it copies the page with an audit
script appended, loads the copy in an iframe of the given width inside a host page (headless
Chromium's window is at least 500 px wide, so a phone's 390 px needs the iframe; the report's
viewport meta tag makes a phone lay the page out at its own width, as the iframe does), asks
``chromium --headless --dump-dom`` for the host's DOM after the script ran and posted its result
to the host, and reads the JSON back from the dumped DOM. Used by
tests/report/test_report_browser.py.
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

# The audit, run in the page after layout. A text node's size is its parent element's computed
# font size; an element is "too wide" when its box reaches past the viewport's right edge (or
# starts left of 0) by more than half a CSS pixel, unless it sits inside a .table-wrap (which
# scrolls by design) — the wrapper itself is still checked.
AUDIT_JS = r"""
(function () {
  const width = document.documentElement.clientWidth;
  const small = [], wide = [], seen = new Set();
  const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  for (let n = walker.nextNode(); n; n = walker.nextNode()) {
    const text = n.textContent.trim();
    const el = n.parentElement;
    if (!text || seen.has(el)) continue;
    seen.add(el);
    const style = getComputedStyle(el);
    if (style.display === "none" || style.visibility === "hidden") continue;
    const size = parseFloat(style.fontSize);
    if (size < MIN_FONT) small.push({tag: el.tagName, size: size, text: text.slice(0, 80)});
  }
  for (const el of document.body.querySelectorAll("*")) {
    const wrap = el.closest(".table-wrap");
    if (wrap && wrap !== el) continue;
    const r = el.getBoundingClientRect();
    if (r.width === 0 && r.height === 0) continue;
    if (r.right > width + 0.5 || r.left < -0.5) {
      wide.push({tag: el.tagName, cls: String(el.className), left: r.left, right: r.right,
                 text: (el.textContent || "").trim().slice(0, 80)});
    }
  }
  const out = document.createElement("pre");
  out.id = "mjx-audit";
  out.textContent = JSON.stringify({width: width,
    scroll_width: document.documentElement.scrollWidth, small: small, wide: wide,
    texts: seen.size, elements: document.body.querySelectorAll("*").length});
  document.body.appendChild(out);
  if (window.parent !== window) window.parent.postMessage(out.textContent, "*");
})();
"""


# The host page: the audited page in an iframe exactly ``width`` CSS pixels wide, and the audit's
# message written into the host's own DOM (which --dump-dom prints).
HOST = """<!DOCTYPE html><html><body style="margin:0">
<iframe src="{src}" style="width:{width}px;height:{height}px;border:0"></iframe>
<script>window.addEventListener("message", function (e) {{
  var pre = document.createElement("pre"); pre.id = "mjx-audit"; pre.textContent = e.data;
  document.body.appendChild(pre); }});</script></body></html>"""


def chromium() -> str | None:
    """The Chromium executable on PATH (Debian's ``chromium``), or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def audit(
    page: Path, width: int, min_font: float = 12.0, height: int = 900, timeout: float = 120.0
) -> dict:
    """The layout audit of ``page`` rendered ``width`` CSS pixels wide: {"width",
    "scroll_width", "small": [...], "wide": [...], "texts", "elements"}."""
    exe = chromium()
    if exe is None:
        raise FileNotFoundError("chromium is not installed (Debian: apt-get install chromium)")
    source = Path(page).read_text(encoding="utf-8")
    script = f"<script>const MIN_FONT = {float(min_font)};{AUDIT_JS}</script>"
    if "</body>" not in source:
        raise ValueError(f"{page} has no </body>")
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "page.html"
        copy.write_text(source.replace("</body>", script + "</body>", 1), encoding="utf-8")
        host = Path(tmp) / "host.html"
        host.write_text(
            HOST.format(src=copy.name, width=int(width), height=int(height)), encoding="utf-8"
        )
        argv = [
            exe,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            f"--user-data-dir={tmp}/profile",
            f"--window-size={max(width, 500) + 40},{height + 40}",
            "--virtual-time-budget=10000",
            "--dump-dom",
            host.as_uri(),
        ]
        env = {**os.environ, "HOME": tmp}
        proc = subprocess.run(
            argv, capture_output=True, text=True, timeout=timeout, check=False, env=env
        )
    found = re.search(r'<pre id="mjx-audit">(.*?)</pre>', proc.stdout, re.S)
    if proc.returncode != 0 or found is None:
        raise RuntimeError(
            f"chromium exited {proc.returncode} without the audit: {proc.stderr[-2000:]}"
        )
    return json.loads(html.unescape(found.group(1)))
