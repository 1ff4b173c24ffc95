"""``report.html``: one self-contained static page of a benchmark's ``results.json``.

No server and no network: CSS and the tab script are inline, every picture is a PNG embedded
as a data URI. Tables come first (the headline: worlds x controllers; then a tab per world
with every metric and its 95 % interval), pictures second (a few episodes' paths over their
maps, side by side for every controller, and a gallery of each controller's first failures
with the command that replays the episode), the raw ``results.json`` one click away.
Colours are the Okabe-Ito palette (distinguishable with the common colour-vision
deficiencies) on a light background; the layout reflows to a phone's width.

The maps under the paths are drawn by the caller's ``draw_layout`` (the CLI passes
:func:`bulletnav.viz.plots.draw_layout`): the benchmark sits below :mod:`bulletnav.viz` and
does not import it.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bulletnav.benchmark.metrics import RATE_METRICS
from bulletnav.files import write_bytes

DrawLayout = Callable[[Any, Any], None]
"""``draw_layout(ax, layout)``: draws a :class:`~bulletnav.sim.layout.Layout` on Matplotlib axes
(:func:`bulletnav.viz.plots.draw_layout`)."""

OUTCOME = {"success": "#0072B2", "collision": "#D55E00", "timeout": "#E69F00"}
"""Okabe-Ito colours of a path by the episode's outcome."""
GALLERY = 3
"""First failures shown per world and controller."""
PICTURED = 3
"""Episodes drawn per world (the first ones; every controller on the same ones)."""

CSS = """
:root { --fg:#1b1b1f; --muted:#55565c; --line:#d0d3d9; --bg:#ffffff; --alt:#f3f5f8; --accent:#0072B2; --best:#e7f1fa; }
* { box-sizing: border-box; }
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg); background: var(--bg);
       margin: 0 auto; max-width: 1280px; padding: 16px; }
h1 { font-size: 1.5rem; margin: 0 0 4px; } h2 { font-size: 1.2rem; margin: 24px 0 8px; } h3 { font-size: 1.05rem; }
p.meta, .note { color: var(--muted); font-size: 0.9rem; }
.scroll { overflow-x: auto; -webkit-overflow-scrolling: touch; }
table { border-collapse: collapse; margin: 8px 0 16px; min-width: 100%; }
th, td { border: 1px solid var(--line); padding: 6px 8px; text-align: left; vertical-align: top; }
th { background: var(--alt); font-weight: 600; }
td.num { font-variant-numeric: tabular-nums; white-space: nowrap; }
td.best { background: var(--best); font-weight: 600; }
.ci { color: var(--muted); font-size: 0.85em; }
[role=tablist] { display: flex; flex-wrap: wrap; gap: 4px; border-bottom: 2px solid var(--line); margin-top: 16px; }
[role=tab] { font: inherit; padding: 8px 14px; border: 1px solid var(--line); border-bottom: none; background: var(--alt);
             color: var(--fg); cursor: pointer; border-radius: 6px 6px 0 0; }
[role=tab][aria-selected=true] { background: var(--accent); color: #fff; border-color: var(--accent); }
[role=tab]:focus-visible { outline: 3px solid #E69F00; outline-offset: 2px; }
img { max-width: 100%; height: auto; border: 1px solid var(--line); }
.gallery { display: grid; grid-template-columns: repeat(auto-fill, minmax(260px, 1fr)); gap: 12px; }
.gallery figure { margin: 0; border: 1px solid var(--line); padding: 8px; background: var(--alt); }
code { font-size: 0.8rem; word-break: break-all; background: var(--alt); padding: 1px 4px; }
.legend span { display: inline-block; margin-right: 14px; }
.swatch { display: inline-block; width: 14px; height: 4px; vertical-align: middle; margin-right: 4px; }
"""

SCRIPT = """
function showTab(id) {
  document.querySelectorAll('[role=tab]').forEach(function (t) {
    var on = t.getAttribute('aria-controls') === id;
    t.setAttribute('aria-selected', on ? 'true' : 'false');
    t.tabIndex = on ? 0 : -1;
  });
  document.querySelectorAll('[role=tabpanel]').forEach(function (p) { p.hidden = p.id !== id; });
}
document.querySelectorAll('[role=tab]').forEach(function (t) {
  t.addEventListener('click', function () { showTab(t.getAttribute('aria-controls')); });
});
"""


def _png(fig: Any) -> str:
    """A figure as a ``data:`` URI (PNG), closed after."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _fmt(cell: dict[str, Any] | None, name: str) -> str:
    """``mean`` with its interval, as a percentage for rates."""
    if not cell or cell.get("mean") is None:
        return "&ndash;"
    pct = name in RATE_METRICS or name.endswith("_rate")
    scale, unit, digits = (100.0, " %", 1) if pct else (1.0, "", 3)
    mean = f"{cell['mean'] * scale:.{digits}f}{unit}"
    if cell.get("lo") is None or cell["n"] < 2:
        return mean
    return f"{mean} <span class=ci>[{cell['lo'] * scale:.{digits}f}, {cell['hi'] * scale:.{digits}f}]</span>"


def best_controllers(results: dict[str, Any]) -> dict[str, str]:
    """World -> its best controller: highest success, then fewer collisions, then higher SPL."""
    best: dict[str, tuple] = {}
    for cell in results["cells"]:
        s = cell["summary"]
        if not s["episodes"]:
            continue
        key = (s["success"]["mean"], -s["collision"]["mean"], s["spl"]["mean"])
        if cell["world"] not in best or key > best[cell["world"]][0]:
            best[cell["world"]] = (key, cell["controller"])
    return {w: c for w, (_, c) in best.items()}


def _episode_scene(world: dict[str, Any], seed: int) -> tuple[Any, tuple, tuple]:
    """Layout, start pose and goal(s) of one episode of ``world`` (a seeded reset)."""
    import gymnasium as gym

    import bulletnav  # noqa: F401

    env = gym.make(world["env"], **world["kwargs"])
    try:
        _, info = env.reset(seed=seed)
        scene = env.unwrapped.scene
        goals = tuple(info.get("goals") or (scene.goal,))
        return scene.layout, scene.start, goals
    finally:
        env.close()


def _draw_panel(ax: Any, layout: Any, start: tuple, goals: tuple, row: dict[str, Any] | None, title: str,
                draw_layout: DrawLayout | None) -> None:
    from matplotlib.patches import Circle

    if draw_layout is not None:
        draw_layout(ax, layout)
    for g in goals:
        ax.add_patch(Circle(g, 0.5, facecolor="#009E73", alpha=0.3, edgecolor="#009E73", zorder=2))
    ax.plot(start[0], start[1], marker="o", ms=5, mfc="white", mec="black", zorder=5)
    if row is not None and row.get("path"):
        xs, ys = zip(*row["path"])
        outcome = "success" if row["success"] else ("collision" if row["collision"] else "timeout")
        ax.plot(xs, ys, color=OUTCOME[outcome], lw=1.6, zorder=3)
    ax.set_title(title, fontsize=8)
    ax.set_xticks([])
    ax.set_yticks([])


def _paths_figure(world: dict[str, Any], controllers: list[str], rows: dict[tuple[str, int], dict], seed: int,
                  episodes: int, draw_layout: DrawLayout | None) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = min(PICTURED, episodes)
    fig, axes = plt.subplots(len(controllers), cols, figsize=(2.6 * cols, 2.4 * len(controllers)), squeeze=False)
    for k in range(cols):
        layout, start, goals = _episode_scene(world, seed + k)
        for i, name in enumerate(controllers):
            _draw_panel(axes[i][k], layout, start, goals, rows.get((name, k)), f"{name} - episode {k} (seed {seed + k})",
                        draw_layout)
    fig.tight_layout()
    return _png(fig)


def _failure_thumb(world: dict[str, Any], row: dict[str, Any], draw_layout: DrawLayout | None) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    layout, start, goals = _episode_scene(world, row["seed"])
    fig, ax = plt.subplots(figsize=(3.0, 2.6))
    outcome = "collision" if row["collision"] else "timeout"
    _draw_panel(ax, layout, start, goals, row, f"{row['controller']}: {outcome}, seed {row['seed']}", draw_layout)
    return _png(fig)


def render_report(results: dict[str, Any], results_name: str = "results.json",
                  draw_layout: DrawLayout | None = None) -> str:
    """The HTML page of ``results`` (a ``results.json`` record); ``draw_layout`` draws the maps
    under the pictured paths (None: paths on blank axes)."""
    suite = results["suite"]
    worlds = suite["worlds"]
    controllers = [c["name"] for c in suite["controllers"]]
    cells = {(c["world"], c["controller"]): c["summary"] for c in results["cells"]}
    rows_by_world: dict[str, dict[tuple[str, int], dict]] = {w["name"]: {} for w in worlds}
    for row in results["episodes"]:
        rows_by_world[row["world"]][(row["controller"], row["episode"])] = row
    out = _page_head(results, results_name, controllers)
    out += _headline(worlds, controllers, cells, best_controllers(results))
    for i, w in enumerate(worlds):  # one tab per world
        out += _world_panel(i, w, controllers, cells, rows_by_world[w["name"]], results["metrics"], suite["seed"],
                            draw_layout)
    esc = html.escape
    definitions = "".join(f"<dt><b>{esc(k)}</b></dt><dd>{esc(v)}</dd>" for k, v in results["metrics"].items())
    out.append(f"<h2>Metrics</h2><dl>{definitions}</dl>")
    out.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(out)


def _page_head(results: dict[str, Any], results_name: str, controllers: list[str]) -> list[str]:
    """The page's lines up to its tab list: title, the run's provenance and one tab per view."""
    suite, worlds = results["suite"], results["suite"]["worlds"]
    prov = results.get("provenance", {})
    esc = html.escape
    out = ["<!doctype html><html lang=en><head><meta charset=utf-8>",
           "<meta name=viewport content='width=device-width, initial-scale=1'>",
           f"<title>bulletnav benchmark: {esc(suite['name'])}</title><style>{CSS}</style></head><body>",
           f"<h1>bulletnav benchmark: <code>{esc(suite['name'])}</code></h1>",
           f"<p class=meta>{sum(w['episodes'] for w in worlds) * len(controllers)} episodes: "
           f"{len(worlds)} worlds x {len(controllers)} controllers; episode k of a world is "
           f"<code>env.reset(seed={suite['seed']} + k)</code> for every controller. "
           f"Commit {esc(str(prov.get('git_commit', '?'))[:12])}{' (dirty)' if prov.get('dirty') else ''}, "
           f"{esc(str(prov.get('machine', '?')))}, {prov.get('workers', '?')} workers, "
           f"{prov.get('wall_time_s', '?')} s. Command: <code>{esc(str(prov.get('command', '')))}</code>. "
           f"Raw data: <a href='{esc(results_name)}'>{esc(results_name)}</a>.</p>",
           "<div role=tablist aria-label='Benchmark views'>",
           "<button role=tab id=tab-headline aria-controls=panel-headline aria-selected=true>Headline</button>"]
    for i, w in enumerate(worlds):
        out.append(f"<button role=tab id=tab-w{i} aria-controls=panel-w{i} aria-selected=false tabindex=-1>"
                   f"{esc(w['name'])}</button>")
    out.append("</div>")
    return out


def _headline(worlds: list[dict[str, Any]], controllers: list[str], cells: dict[tuple[str, str], Any],
              best: dict[str, str]) -> list[str]:
    """The headline tab's lines: success, collisions and SPL of every world and controller, the
    best of each world starred."""
    esc = html.escape
    out = ["<section role=tabpanel id=panel-headline aria-labelledby=tab-headline>"
           "<h2>Headline: success, collisions and SPL (95 % bootstrap intervals)</h2>"
           "<div class=scroll><table id=headline><thead><tr><th scope=col>world</th>"]
    out += [f"<th scope=col>{esc(c)}</th>" for c in controllers]
    out.append("</tr></thead><tbody>")
    for w in worlds:
        out.append(f"<tr><th scope=row>{esc(w['name'])}<br><span class=ci>{esc(w['env'])}"
                   f"{' ' + esc(str(w['kwargs'])) if w['kwargs'] else ''}, {w['episodes']} episodes</span></th>")
        for c in controllers:
            s = cells.get((w["name"], c))
            mark = best.get(w["name"]) == c
            body = ("&ndash;" if not s or not s["episodes"] else
                    f"success {_fmt(s['success'], 'success')}<br>collisions {_fmt(s['collision'], 'collision')}"
                    f"<br>SPL {_fmt(s['spl'], 'spl')}")
            out.append(f"<td class='num{' best' if mark else ''}'>{'&#9733; best<br>' if mark else ''}{body}</td>")
        out.append("</tr>")
    out.append("</tbody></table></div><p class=note>&#9733; best: highest success, then fewest collisions, then "
               "highest SPL. Every world's tab has all the metrics.</p></section>")
    return out


def _world_panel(i: int, w: dict[str, Any], controllers: list[str], cells: dict[tuple[str, str], Any],
                 rows: dict[tuple[str, int], dict], metrics: dict[str, str], seed: int,
                 draw_layout: DrawLayout | None) -> list[str]:
    """World ``i``'s tab: every metric of every controller, the first episodes' paths and the
    failure gallery."""
    esc = html.escape
    out = [f"<section role=tabpanel id=panel-w{i} aria-labelledby=tab-w{i} hidden>"
           f"<h2>{esc(w['name'])} ({esc(w['env'])}, {w['episodes']} episodes)</h2>"
           f"<div class=scroll><table class=metrics><thead><tr><th scope=col>metric</th>"]
    out += [f"<th scope=col>{esc(c)}</th>" for c in controllers]
    out.append("</tr></thead><tbody>")
    for name, definition in metrics.items():
        out.append(f"<tr><th scope=row title='{esc(definition, quote=True)}'>{esc(name)}</th>")
        out += [f"<td class=num>{_fmt((cells.get((w['name'], c)) or {}).get(name), name)}</td>" for c in controllers]
        out.append("</tr>")
    out.append("</tbody></table></div>")
    out.append("<p class='note legend'>Paths: <span><i class=swatch style='background:#0072B2'></i>success</span>"
               "<span><i class=swatch style='background:#D55E00'></i>collision</span>"
               "<span><i class=swatch style='background:#E69F00'></i>timeout</span> green disc: goal, "
               "white dot: start.</p>")
    out.append(f"<h3>The first episodes, every controller</h3><img alt='paths of the first episodes of "
               f"{esc(w['name'], quote=True)}' src='"
               f"{_paths_figure(w, controllers, rows, seed, w['episodes'], draw_layout)}'>")
    out.append("<h3>Failure gallery</h3>")
    out += _failure_gallery(w, controllers, rows, draw_layout)
    out.append("</section>")
    return out


def _failure_gallery(w: dict[str, Any], controllers: list[str], rows: dict[tuple[str, int], dict],
                     draw_layout: DrawLayout | None) -> list[str]:
    """The first :data:`GALLERY` failed episodes of each controller in world ``w``, each a
    thumbnail with its outcome and replay command."""
    esc = html.escape
    failures = [r for r in sorted(rows.values(), key=lambda r: (controllers.index(r["controller"]), r["episode"]))
                if not r["success"]]
    shown = []
    for c in controllers:
        shown += [r for r in failures if r["controller"] == c][:GALLERY]
    if not shown:
        return ["<p class=note>No failures.</p>"]
    out = ["<div class=gallery>"]
    for r in shown:
        outcome = "collision" if r["collision"] else "timeout"
        out.append(f"<figure><img alt='{esc(r['controller'], quote=True)} {outcome} seed {r['seed']}' "
                   f"src='{_failure_thumb(w, r, draw_layout)}'><figcaption>{esc(r['controller'])}: {outcome} after "
                   f"{r['time_s']:.1f} s (episode {r['episode']}). Replay: <code>{esc(r.get('replay', ''))}"
                   f"</code></figcaption></figure>")
    out.append("</div>")
    return out


def write_report(results: dict[str, Any], path: Path, draw_layout: DrawLayout | None = None) -> Path:
    """Write :func:`render_report` to ``path`` atomically (:func:`bulletnav.files.write_bytes`)."""
    write_bytes(path, render_report(results, draw_layout=draw_layout).encode())
    return path


def screenshots(report: Path, out: Path, tab: int = 0, width: int = 1280) -> list[Path]:
    """PNG screenshots of a report in Debian's Chromium (Playwright): ``headline.png`` and the
    world tab ``tab`` (``world.png``), full page at ``width`` pixels.

    Raises:
        BulletnavError: Playwright or a Chromium binary is missing.
    """
    import shutil

    from bulletnav.errors import BulletnavError

    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        raise BulletnavError("screenshots need playwright (pip install -e '.[dev]')") from None
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise BulletnavError("screenshots need a chromium binary (Debian: apt-get install chromium)")
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "headline.png", out / "world.png"]
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, args=[
            "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
            "--disable-component-update", "--disable-sync"])
        try:
            page = browser.new_page(viewport={"width": width, "height": 900})
            page.goto(report.resolve().as_uri())
            write_bytes(paths[0], page.screenshot(full_page=True))  # whole PNGs under the names, or none
            page.click(f"#tab-w{tab}")
            write_bytes(paths[1], page.screenshot(full_page=True))
        finally:
            browser.close()
    return paths
