"""The explore page as a person uses it, in headless Chromium driven through chromedriver
(tests/webdriver.py, a standard-library WebDriver client): the map draws, hovering a cell
shows its values with units, clicking it computes its run (the scalar reference, about a
second in the tiny folder's 1-s window) and draws its series and stick figure, a second click
is served from the folder, a bad request shows its message in the page, a path outside the
folder is refused, and a folder being written refreshes as its chunks arrive.

Chromium and chromium-driver are Debian's packages (.ci/run installs them); where either is
missing the tests skip with the reason, except under CI=true, where they fail: the check
must run somewhere."""

from __future__ import annotations

import shutil
import time

import pytest
from browser_audit import chromium
from explore_folders import sweep_folder
from support import unavailable
from webdriver import Browser, chromedriver

from mjx_balance.report.explore import Explorer

TOOLTIP = [
    "force",
    "20 N",
    "duration",
    "0.5 s",
    "outcome",
    "recovered",
    "settle time",
    "energy, motors' work",
    "J",
    "energy, the study's (eq. 20)",
    "hip share",
    "min. margin of stability",
    "first infeasible QP",
]


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    missing = [
        name
        for name, found in (("chromium", chromium()), ("chromedriver", chromedriver()))
        if found is None
    ]
    if missing:
        reason = (
            f"{' and '.join(missing)} not installed (Debian: apt-get install chromium "
            "chromium-driver; .ci/run does)"
        )
        unavailable(reason, "the browser test")
    b = Browser(chromium(), tmp_path_factory.mktemp("chromium") / "profile")
    yield b
    b.quit()


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return sweep_folder(tmp_path_factory.mktemp("explore") / "sweep")


@pytest.fixture(scope="module")
def page(folder, tmp_path_factory):
    outside = tmp_path_factory.mktemp("outside") / "secret.txt"
    outside.write_text("not to be served\n")
    (folder / "escape.txt").symlink_to(outside)
    with Explorer(folder) as explorer:
        yield explorer


def text(b: Browser, css: str) -> str:
    found = b.find_all(css)
    return b.text(found[0]) if found else ""


def cell(b: Browser, force: str, duration: str) -> dict:
    return b.find(f'#map-svg rect.cell[data-force="{force}"][data-duration="{duration}"]')


def test_hover_click_and_a_second_click_served_from_the_folder(browser, page, folder, tmp_path):
    b = browser
    started = time.perf_counter()
    b.get(page.url)
    b.wait(lambda: len(b.find_all("#map-svg rect.cell")) == 15, 30, "the map's 15 cells")
    loaded = time.perf_counter() - started
    assert b.find_all("#map-svg path.own-boundary"), "the recovery boundary is drawn"
    # with one step and with two (the stand-in's capturability): a black edge and a white dash
    assert len(b.find_all("#map-svg path.step-boundary")) == 4, "the step boundaries"
    assert len(b.find_all("#map-svg .table-point")) == 2  # table.csv's 20 and 40 N
    assert "recovered (" in text(b, "#legend") and "15 of 15 cells computed" in text(b, "#status")

    b.hover(cell(b, "20", "0.5"))
    tip = b.wait(lambda: text(b, "#tooltip"), 10, "the tooltip")
    for word in TOOLTIP:
        assert word in tip, (word, tip)

    kept = folder / "explore" / "20.0_0.5.parquet"
    assert not kept.exists()
    started = time.perf_counter()
    b.click(cell(b, "20", "0.5"))
    status = b.wait(
        lambda: "kept in the folder" in text(b, "#run-status") and text(b, "#run-status"),
        120,
        "the run",
    )
    computed = time.perf_counter() - started
    assert kept.is_file() and "computed now in" in status
    assert text(b, "#run-title").startswith("20 N for 0.5 s: ")
    assert len(b.find_all("#panels svg.chart")) == 9
    assert len(b.find_all("#panels svg.chart polyline")) >= 9
    assert b.find_all("#figure svg line")  # the stick figure
    assert "mjx-balance view --config" in text(b, "#commands")

    b.get(page.url)  # a fresh page: the folder, not the page, keeps the run
    b.wait(lambda: len(b.find_all("#map-svg circle.explored")) == 1, 30, "the kept run's dot")
    started = time.perf_counter()
    b.click(cell(b, "20", "0.5"))
    status = b.wait(
        lambda: "served from the folder" in text(b, "#run-status") and text(b, "#run-status"),
        30,
        "the kept run",
    )
    second = time.perf_counter() - started
    assert second < computed
    b.screenshot(tmp_path / "explore.png")
    print(
        f"page load {loaded:.2f} s, a click computed in {computed:.2f} s, "
        f"the second click in {second:.2f} s"
    )


def test_a_bad_request_shows_its_message(browser, page):
    b = browser
    b.get(page.url + "#map=&force=abc&duration=0.5")
    assert "force: 'abc' is not a number" in b.wait(lambda: text(b, "#error"), 30, "the error")
    b.get(page.url + "#map=&force=20&duration=0.123")
    b.wait(lambda: "not a whole number of physics steps" in text(b, "#error"), 30, "the error")
    b.get(page.url + "#map=&force=25&duration=0.5")
    b.wait(lambda: "not a cell of this map" in text(b, "#error"), 30, "the error")


def test_a_path_outside_the_folder_is_refused(browser, page):
    b = browser
    b.get(page.url + "files/..%2F..%2Fetc%2Fpasswd")
    assert "refused" in text(b, "body") and "root:" not in text(b, "body")
    b.get(page.url + "files/escape.txt")
    body = text(b, "body")
    assert "leads outside the folder" in body and "not to be served" not in body
    b.get(page.url + "files/region.png")  # a file of the folder is served
    assert b.execute("return document.contentType") == "image/png"


def test_a_folder_being_written_refreshes(browser, folder, tmp_path):
    live = tmp_path / "live"
    shutil.copytree(folder, live, ignore=shutil.ignore_patterns(".lock", "explore", "escape*"))
    (live / "region.parquet").unlink()
    last = sorted((live / "chunks").glob("chunk-*.parquet"))[-1]
    held = last.read_bytes()
    last.unlink()
    b = browser
    with Explorer(live) as explorer:
        b.get(explorer.url)
        b.wait(lambda: "12 of 15 cells computed" in text(b, "#status"), 30, "the partial map")
        assert "the page refreshes as it goes" in text(b, "#status")
        assert "white: not computed" in text(b, "#legend")
        last.write_bytes(held)
        b.wait(lambda: "15 of 15 cells computed" in text(b, "#status"), 30, "the refresh")


def test_a_cohorts_share_map_draws_its_boundaries_and_interval(browser, folder, tmp_path):
    """The cohort view: the share of subjects recovering per cell, its 95 % Wilson interval on
    hover, the 95/50/5 % boundaries and the base body's, as cohort_probability.png draws
    them."""
    from explore_folders import shaped_like

    cohort = shaped_like("cohort", folder, tmp_path / "cohort", ["s01", "s02", "s03"])
    shutil.copytree(folder, cohort / "base", ignore=shutil.ignore_patterns(".lock", "explore"))
    b = browser
    with Explorer(cohort) as explorer:
        b.get(explorer.url)
        b.wait(lambda: b.find_all("#map-select option"), 30, "the map choice")
        b.execute(
            "const s = document.getElementById('map-select'); s.value = '*share';"
            "s.dispatchEvent(new Event('change'));"
        )
        b.wait(lambda: b.find_all("#map-svg path.level-boundary"), 30, "the level boundaries")
        levels = {
            e
            for e in b.execute(
                "return [...document.querySelectorAll('#map-svg path.level-boundary')]"
                ".map((p) => p.getAttribute('data-level')).filter((v) => v);"
            )
        }
        assert levels == {"95", "50", "5"}
        assert b.find_all("#map-svg path.base-boundary"), "the base body's boundary"
        legend = text(b, "#legend")
        assert "base configuration's body recovers" in legend and "P(recover) ≥ 95 %" in legend
        b.hover(cell(b, "20", "0.5"))
        tip = b.wait(lambda: text(b, "#tooltip"), 10, "the tooltip")
        # three copies of one map: all three recover there, Wilson (0.4385, 1)
        assert "share recovering" in tip and "(of 3 subjects)" in tip
        assert "95 % interval" in tip and "0.4385 to 1 (Wilson)" in tip, tip
