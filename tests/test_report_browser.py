"""The job report in a real browser: headless Chromium (Debian's `chromium` and `chromium-driver`, driven
by Selenium) opens the page from disk with the network off, logs no console error, and draws every
figure with a real size and content; a screenshot is written. Skipped when no browser is installed.
MILLPOST_UPDATE_SCREENSHOT=1 also writes docs/report.png (the README's picture)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from millpost.report import collect, write_report

ROOT = Path(__file__).resolve().parents[1]
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


def test_report_in_headless_chromium(browser, slotting_result, tmp_path):
    job, result = slotting_result
    page = tmp_path / "report.html"
    write_report(page, collect(result.summary, result.trace, job))
    browser.get(page.as_uri())
    figures = browser.execute_script("""
        return Array.from(document.querySelectorAll('svg[data-figure]')).map(s => {
            const r = s.getBoundingClientRect();
            return {name: s.dataset.figure, w: r.width, h: r.height,
                    marks: s.querySelectorAll('path, image, use, rect').length};
        });""")
    assert [f["name"] for f in figures] == ["cycle-times", "feed-along-path", "loads-vs-limits", "top-view",
                                            "stock-map"]
    for f in figures:
        assert f["w"] > 300 and f["h"] > 100 and f["marks"] > 20, f
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
