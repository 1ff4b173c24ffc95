"""The benchmark report in a real browser (Debian's Chromium driven by Playwright): the
headline table has a row per world and a column per controller, every image loads, a world's
tab shows its table when clicked, the page logs no console error; a screenshot is kept."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from bulletnav.benchmark.report import write_report
from bulletnav.benchmark.runner import build_results
from bulletnav.benchmark.suite import load_suite
from bulletnav.viz.plots import draw_layout

HERE = Path(__file__).resolve().parent
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    """The tiny suite's committed rows as a report (no episodes run: the rows are golden)."""
    suite = load_suite(str(HERE / "data" / "benchmark_tiny.yaml"))
    rows = json.loads((HERE / "golden" / "benchmark_tiny.json").read_text())["episodes"]
    results = build_results(suite, rows)
    results["provenance"] = {"git_commit": "test", "dirty": False, "machine": "test", "workers": 1, "wall_time_s": 0.0,
                             "command": "pytest"}
    out = tmp_path_factory.mktemp("report")
    (out / "results.json").write_text(json.dumps(results))
    return write_report(results, out / "report.html", draw_layout)


def test_report_in_chromium(report, tmp_path):
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed (make install)")
    if CHROMIUM is None:
        pytest.skip("no chromium binary (Debian package 'chromium'; .ci/run installs it)")
    errors: list[str] = []
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=[
            "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
            "--disable-component-update", "--disable-sync"])
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(report.as_uri())
            suite = json.loads((report.parent / "results.json").read_text())["suite"]
            worlds, controllers = suite["worlds"], suite["controllers"]
            assert page.locator("#headline tbody tr").count() == len(worlds)
            assert page.locator("#headline thead th").count() == len(controllers) + 1
            assert page.locator("#headline").is_visible()
            page.screenshot(path=str(tmp_path / "headline.png"), full_page=True)
            for i, world in enumerate(worlds):
                panel = page.locator(f"#panel-w{i}")
                assert panel.is_hidden()
                page.click(f"#tab-w{i}")
                assert panel.is_visible() and panel.locator("table.metrics").is_visible()
                assert page.locator("#panel-headline").is_hidden()
                assert world["name"] in panel.locator("h2").inner_text()
            page.screenshot(path=str(tmp_path / "world.png"), full_page=True)
            images = page.eval_on_selector_all("img", "imgs => imgs.map(i => [i.complete, i.naturalWidth])")
            assert len(images) >= len(worlds) + 1  # a paths picture per world, the failure's thumbnail
            assert all(complete and width > 0 for complete, width in images), images
            page.set_viewport_size({"width": 390, "height": 844})  # a phone: the table scrolls inside its box
            page.click("#tab-headline")
            assert page.evaluate("document.documentElement.scrollWidth") <= 390 + 1
        finally:
            browser.close()
    assert errors == []
    assert (tmp_path / "headline.png").stat().st_size > 0 and (tmp_path / "world.png").stat().st_size > 0
