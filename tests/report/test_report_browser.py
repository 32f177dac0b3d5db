"""The report as a reader sees it: rendered by headless Chromium at a laptop's width (1366 px)
and a phone's (390 px), no text under 12 px and nothing wider than the screen outside a table's
scrolling wrapper; the page under 2 MB. Chromium is Debian's package (.ci/run installs it);
where it is missing the browser tests skip with the reason, except under CI=true, where they
fail: the check must run somewhere."""

import pytest
from browser_audit import audit, chromium
from support import unavailable
from tiny_report import ALL, SMALL, tiny_report

WIDTHS = {"laptop": 1366, "phone": 390}
MIN_FONT_PX = 12.0
MAX_BYTES = 2_000_000  # the tiny report, self-contained, under 2 MB


@pytest.fixture(scope="module")
def browser():
    if chromium() is None:
        reason = "chromium is not installed (Debian: apt-get install chromium; .ci/run does)"
        unavailable(reason, "the browser test")


@pytest.fixture(
    scope="module",
    params=[SMALL, pytest.param(ALL, marks=pytest.mark.slow)],
    ids=["two_studies", "all_studies"],
)
def out(request, tmp_path_factory):
    """The tiny report with two studies (default run) and with every study (slow run: the
    page whose size MAX_BYTES bounds)."""
    return tiny_report(tmp_path_factory, request.param)


def test_the_audit_finds_small_text_and_overflow(tmp_path, browser):
    """The check can fail: a 10-px note and a 2000-px box are found; a wide table inside the
    scrolling wrapper and 12-px text are not."""
    page = tmp_path / "page.html"
    page.write_text(
        '<!DOCTYPE html><html><head><meta name="viewport" content="width=device-width">'
        "</head><body><p>fine text</p><p style='font-size:12px'>just large enough</p>"
        "<p style='font-size:10px'>too small</p><div style='width:2000px'>too wide</div>"
        "<div class='table-wrap' style='overflow-x:auto'><table style='width:3000px'>"
        "<tr><td>wide table</td></tr></table></div></body></html>",
        encoding="utf-8",
    )
    found = audit(page, WIDTHS["phone"], MIN_FONT_PX)
    assert found["width"] == WIDTHS["phone"]
    assert [s["text"] for s in found["small"]] == ["too small"]
    assert [w["text"] for w in found["wide"]] == ["too wide"]


@pytest.mark.parametrize("screen", sorted(WIDTHS))
def test_the_report_reads_at_laptop_and_phone_widths(out, browser, screen):
    width = WIDTHS[screen]
    found = audit(out / "report.html", width, MIN_FONT_PX)
    assert found["width"] == width  # the page was laid out at that width
    assert found["texts"] > 500  # the whole report was there to check
    assert found["small"] == [], f"text under {MIN_FONT_PX} px at {width} px: {found['small'][:5]}"
    assert found["wide"] == [], f"wider than {width} px: {found['wide'][:5]}"
    assert found["scroll_width"] <= width  # no sideways scrolling of the page


def test_the_report_is_small_and_phone_ready(out):
    page = out / "report.html"
    assert page.stat().st_size < MAX_BYTES, f"{page.stat().st_size / 1e6:.2f} MB"
    text = page.read_text(encoding="utf-8")
    # a phone lays the page out at its own width only with this tag (the audit's iframe
    # assumes it)
    assert '<meta name="viewport" content="width=device-width, initial-scale=1">' in text
