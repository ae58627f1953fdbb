"""The job report in a real browser: headless Chromium (Debian's `chromium` and `chromium-driver`, driven
by Selenium) opens the page from disk with the network off, logs no console error, and draws every
figure at a readable size with what it must contain (the optimized feed over the whole cutting length,
top views in the part's proportions with their colour bar beside them, also for a long thin part); a
screenshot is written. Skipped when no browser is installed.
MILLPOST_UPDATE_SCREENSHOT=1 also writes docs/report.png (the README's picture)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from millpost.report import collect, write_report
from test_report import zigzag_report

ROOT = Path(__file__).resolve().parents[2]
BROWSER = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")


@pytest.fixture(scope="module")
def browser():
    if not (BROWSER and DRIVER):
        pytest.skip("no headless Chromium (apt-get install chromium chromium-driver)")
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = BROWSER
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,900", "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>"):
        options.add_argument(arg)  # an unreachable proxy: anything fetched from the network fails and logs
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    yield driver
    driver.quit()


# per figure: its box, its number of marks, each axes' box (its background patch) and the optimized feed
# curve's box (left, width), in CSS pixels
FIGURE_BOXES = """
    const box = e => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; };
    return Array.from(document.querySelectorAll('svg[data-figure]')).map(s => {
        const line = s.querySelector('#feed-optimized');
        return {name: s.dataset.figure, box: box(s), marks: s.querySelectorAll('path, image, use, rect').length,
                axes: Array.from(s.querySelectorAll('g[id^="axes_"]')).map(
                    a => box(a.querySelector(':scope > g[id^="patch_"]'))),
                line: line ? box(line) : null};
    });"""


def check_figures(figures: list[dict]) -> None:
    """Every figure readable and showing the whole job (see the module docstring)."""
    for f in figures:
        assert f["box"][2] >= 400 and f["box"][3] >= 200 and f["marks"] > 20, f  # px
    by_name = {f["name"]: f for f in figures}
    for name in ("top-view", "stock-map"):
        if name in by_name:
            (_, _, w, h), (_, _, bw, bh) = by_name[name]["axes"][:2]
            assert min(w, h) >= 150 and max(w, h) >= 500, by_name[name]  # px
            assert max(bw, bh) == pytest.approx(w if bw > bh else h, rel=0.05), by_name[name]  # bar alongside
    feed = by_name["feed-along-path"]
    assert feed["line"], "no optimized feed curve"
    left, _, width, _ = feed["axes"][0]
    assert feed["line"][0] <= left + 0.01 * width and feed["line"][2] >= 0.97 * width, feed  # end to end


def test_report_in_headless_chromium(browser, slotting_result, tmp_path):
    job, result = slotting_result
    page = tmp_path / "report.html"
    write_report(page, collect(result.summary, result.trace, job))
    browser.get(page.as_uri())
    figures = browser.execute_script(FIGURE_BOXES)
    assert [f["name"] for f in figures] == ["cycle-times", "feed-along-path", "loads-vs-limits", "top-view",
                                            "stock-map", "surface-error"]
    check_figures(figures)
    # rasterised parts (point clouds, the stock map) decode to real images
    images = browser.execute_script("""
        return Array.from(document.querySelectorAll('svg image')).map(i => i.href.baseVal.slice(0, 22));""")
    assert images and all(src.startswith("data:image/png;base64") for src in images)
    errors = [e for e in browser.get_log("browser") if e["level"] in ("SEVERE", "WARNING")]
    assert not errors, errors
    height = browser.execute_script("return document.body.scrollHeight")
    browser.set_window_size(1200, height + 40)
    shot = tmp_path / "report.png"
    assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 50_000
    if os.environ.get("MILLPOST_UPDATE_SCREENSHOT"):
        (ROOT / "docs").mkdir(exist_ok=True)
        shutil.copyfile(shot, ROOT / "docs" / "report.png")


def test_long_thin_part_in_headless_chromium(browser, tmp_path):
    page = tmp_path / "strip.html"
    write_report(page, zigzag_report(300.0, 12.0, n=50_000)[0])
    browser.get(page.as_uri())
    check_figures(browser.execute_script(FIGURE_BOXES))
