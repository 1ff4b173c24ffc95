"""The benchmark report in a real browser (Debian's Chromium driven by Playwright): the
headline table has a row per controller and a column per world, every image loads, a world's
tab shows its table when clicked, the page logs no console error; at 1,400 px and at a
phone's 390 px the page never scrolls sideways and every controller's headline cell lies inside
the window; the legend's samples are drawn in the colours the maps use; a replay command
breaks only between its arguments and its text is the command on one line. Screenshots are kept."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from browser import chromium
from bulletnav.benchmark import report as report_module
from bulletnav.benchmark.report import write_report
from bulletnav.benchmark.runner import build_results
from bulletnav.benchmark.suite import load_suite
from bulletnav.viz.plots import draw_layout

HERE = Path(__file__).resolve().parent
WIDTHS = (1400, 390)
"""Viewport widths (px) the page must fit: a laptop's and a phone's."""


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


@pytest.fixture(scope="module")
def browser():
    """One Chromium for the module's tests."""
    yield from chromium()


def _suite(report: Path) -> dict:
    return json.loads((report.parent / "results.json").read_text())["suite"]


@pytest.mark.slow
def test_report_in_chromium(report, browser, tmp_path):
    errors: list[str] = []
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(report.as_uri())
    suite = _suite(report)
    worlds, controllers = suite["worlds"], suite["controllers"]
    assert page.locator("#headline tbody tr").count() == len(controllers)
    assert page.locator("#headline thead th").count() == len(worlds) + 1
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
    # a map per controller and pictured episode in each world, and the failure's map
    episodes = sum(min(report_module.PICTURED, w["episodes"]) for w in worlds)
    assert len(images) == episodes * len(controllers) + 1
    assert all(complete and width > 0 for complete, width in images), images
    # a click enlarges a map to the grid's full width, a second click gives it back
    figure = page.locator(f"#panel-w{len(worlds) - 1} .maps figure").first
    before = figure.bounding_box()["width"]
    figure.locator("img").click()
    assert figure.bounding_box()["width"] > 1.5 * before
    figure.locator("img").click()
    assert figure.bounding_box()["width"] == pytest.approx(before, abs=1)
    page.close()
    assert errors == []
    assert (tmp_path / "headline.png").stat().st_size > 0 and (tmp_path / "world.png").stat().st_size > 0


@pytest.mark.parametrize("width", WIDTHS)
def test_report_fits_the_window_with_every_controller_visible(report, browser, width, tmp_path):
    """At each width: no sideways scrolling of the page (in the headline and in every world's
    tab), every controller's name and each of its world cells visible and inside the window,
    every map at least 320 px wide (or the whole width a phone has)."""
    page = browser.new_page(viewport={"width": width, "height": 900})
    page.goto(report.as_uri())
    suite = _suite(report)
    names = [c["name"] for c in suite["controllers"]]
    inner = page.evaluate("window.innerWidth")
    assert inner == width

    def page_width() -> int:
        return page.evaluate("document.scrollingElement.scrollWidth")

    assert page_width() <= inner
    rows = page.locator("#headline tbody tr")
    assert [rows.nth(i).get_attribute("data-controller") for i in range(rows.count())] == names
    for i, name in enumerate(names):
        row = rows.nth(i)
        cells = [row.locator("th"), *[row.locator("td").nth(k) for k in range(len(suite["worlds"]))]]
        assert row.locator("th").inner_text().strip() == name
        for cell in cells:
            assert cell.is_visible()
            box = cell.bounding_box()
            assert box is not None and box["width"] > 0 and box["height"] > 0
            assert box["x"] >= 0 and box["x"] + box["width"] <= inner + 0.5, (name, width, box)
        assert "success" in cells[1].inner_text()
    page.screenshot(path=str(tmp_path / f"report_{width}.png"), full_page=True)
    for i in range(len(suite["worlds"])):
        page.click(f"#tab-w{i}")
        assert page_width() <= inner, f"world tab {i} at {width} px"
        maps = page.eval_on_selector_all(f"#panel-w{i} details[open] .maps img",
                                         "imgs => imgs.map(i => i.getBoundingClientRect().width)")
        assert maps and min(maps) >= min(320, inner - 60), maps
    page.close()


def _rgb(hex_colour: str) -> str:
    h = hex_colour.lstrip("#")
    return "rgb({}, {}, {})".format(*(int(h[k:k + 2], 16) for k in (0, 2, 4)))


def test_report_legend_shows_the_colours_the_maps_are_drawn_in(report, browser):
    """The legend as the browser paints it: each entry's sample is in the colour the map
    drawing uses for it (:data:`PALETTE`) and its text names that colour."""
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.goto(report.as_uri())
    page.click("#tab-w0")
    legend = page.locator("#panel-w0 ul.legend li[data-key]")
    painted = {}
    for i in range(legend.count()):
        item = legend.nth(i)
        key = item.get_attribute("data-key")
        colours = item.evaluate("li => Array.from(li.querySelectorAll('svg *')).flatMap(e => {"
                                "const s = getComputedStyle(e); return [s.stroke, s.fill]; })")
        painted[key] = (set(colours), item.inner_text())
    palette = report_module.PALETTE
    extra = {"start": {"#ffffff"}, "obstacle": {palette["wall"]}}  # the start's white dot, the racks' outline
    for key in ("success", "collision", "timeout", "goal", "obstacle", "start"):
        colours, text = painted[key]
        assert colours - {"none"} == {_rgb(c) for c in {palette[key], *extra.get(key, ())}}, (key, colours)
        assert report_module.COLOUR_NAMES[key] in text, (key, text)
    # the tiny suite has no movers: no mover entries in its legend
    assert "forklift" not in painted and "worker" not in painted
    page.close()


def test_report_replay_command_wraps_between_arguments_and_copies_as_one_line(report, browser):
    """At a phone's width the replay command of the tiny suite's failure wraps, but no argument
    is broken (each span lies on one line), the command box never widens the page, and its
    text, as a copy gives it, is the row's command on one line."""
    rows = json.loads((report.parent / "results.json").read_text())["episodes"]
    (failure,) = [r for r in rows if not r["success"]]
    page = browser.new_page(viewport={"width": 390, "height": 844})
    page.goto(report.as_uri())
    world = [w["name"] for w in _suite(report)["worlds"]].index(failure["world"])
    page.click(f"#tab-w{world}")
    code = page.locator(f"#panel-w{world} code.cmd").first
    assert code.evaluate("c => c.innerText") == failure["replay"]
    lines = code.evaluate("c => Array.from(c.children).map(s => s.getClientRects().length)")
    assert len(lines) == len(failure["replay"].split()) and set(lines) == {1}
    tops = code.evaluate("c => Array.from(c.children).map(s => Math.round(s.getBoundingClientRect().top))")
    assert len(set(tops)) > 1  # it did wrap (between arguments)
    assert page.evaluate("document.scrollingElement.scrollWidth") <= 390
    page.close()
