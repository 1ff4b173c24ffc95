"""``report.html``: one self-contained static page of a benchmark's ``results.json``.

No server and no network: CSS and the small script (tabs, enlarging a map) are inline, every
picture is a PNG embedded as a data URI. Tables come first (the headline: a row per controller,
a column per world with success, collisions and SPL; then a tab per world with every metric and
its 95 % interval), pictures second (a few episodes' paths over their maps for every
controller, and a gallery of each controller's first failures with the command that replays
the episode), the raw ``results.json`` one click away.

The page fits a 1,400 px screen and a 390 px phone without scrolling sideways: the headline
table turns into one card per controller on a narrow screen, the wide per-world tables scroll
inside their own box (and say so), maps are at least 320 px wide in a grid that reflows, and a
replay command breaks only between its arguments (each argument a ``white-space: pre`` span;
copied, the command is one line).

Colours (:data:`PALETTE`) are the Okabe-Ito palette, distinguishable with the common
colour-vision deficiencies: success, collision and time-out paths differ in colour and also in
line style and end mark; the goal zone, the (grey) racks and the movers have colours no path
uses; the legend is drawn from the same constants (:func:`legend_html`). In worlds with movers,
every map draws each forklift and worker where it was when the episode ended, re-created from
the episode's seed (its movers' specs) and the robot's recorded track
(:func:`bulletnav.sim.movers.kinematic_poses`), with its route dashed.

The maps under the paths are drawn by the caller's ``draw_layout`` (the CLI passes
:func:`bulletnav.viz.plots.draw_layout`): the benchmark sits below :mod:`bulletnav.viz` and
does not import it.
"""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bulletnav.benchmark.metrics import RATE_METRICS
from bulletnav.files import write_bytes

DrawLayout = Callable[..., None]
"""``draw_layout(ax, layout, obstacle=colour, wall=colour)``: draws a
:class:`~bulletnav.sim.layout.Layout` on Matplotlib axes, every obstacle and the walls in the
given colours (:func:`bulletnav.viz.plots.draw_layout`)."""

PALETTE = {
    "success": "#0072B2",
    "collision": "#D55E00",
    "timeout": "#CC79A7",
    "goal": "#009E73",
    "start": "#000000",
    "obstacle": "#B4B4B4",
    "wall": "#4D4D4D",
    "forklift": "#F0E442",
    "worker": "#56B4E9",
}
"""Okabe-Ito colours of everything drawn on a map (the walls and racks in greys)."""
COLOUR_NAMES = {
    "success": "blue", "collision": "vermillion", "timeout": "reddish purple", "goal": "bluish green",
    "start": "black", "obstacle": "grey", "wall": "dark grey", "forklift": "yellow", "worker": "sky blue",
}
"""The words the legend uses for :data:`PALETTE`'s colours."""
OUTCOME = {k: PALETTE[k] for k in ("success", "collision", "timeout")}
"""Colour of a path by the episode's outcome."""
PATH_STYLE = {"success": "-", "collision": "-", "timeout": (0, (3, 1.5))}
"""Matplotlib line style of a path by outcome: a time-out's is dashed."""
END_MARK = {"collision": "X", "timeout": "s"}
"""Matplotlib marker where a failed episode's path ends: a cross at a collision, a square at a time-out."""
GOAL_ALPHA = 0.35
"""Opacity of the goal zone's fill (its outline is opaque)."""
MOVER_EDGE = "#000000"
"""Outline of a mover's footprint."""
ROUTE_ALPHA = 0.55
"""Opacity of a mover's dashed route (black)."""
GALLERY = 3
"""First failures shown per world and controller."""
PICTURED = 3
"""Episodes drawn per world (the first ones; every controller on the same ones)."""
MAP_IN = 4.4
"""Width (inches) of one map; drawn at :data:`MAP_DPI`, shown at least 320 px wide."""
MAP_DPI = 110

CSS = """
:root { --fg:#1b1b1f; --muted:#55565c; --line:#d0d3d9; --bg:#ffffff; --alt:#f3f5f8; --accent:#0072B2; --best:#e7f1fa; }
* { box-sizing: border-box; }
html { -webkit-text-size-adjust: 100%; }
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg); background: var(--bg);
       margin: 0 auto; max-width: 1320px; padding: 16px; overflow-wrap: anywhere; }
h1 { font-size: 1.5rem; margin: 0 0 4px; } h2 { font-size: 1.2rem; margin: 24px 0 8px; } h3 { font-size: 1.05rem; }
p.meta, .note { color: var(--muted); font-size: 0.9rem; }
.scroll { overflow-x: auto; -webkit-overflow-scrolling: touch; max-width: 100%; }
.hint { display: none; color: var(--muted); font-size: 0.85rem; margin: 4px 0; }
table { border-collapse: collapse; margin: 8px 0 16px; }
th, td { border: 1px solid var(--line); padding: 6px 8px; text-align: left; vertical-align: top; }
th { background: var(--alt); font-weight: 600; }
td.num { font-variant-numeric: tabular-nums; white-space: nowrap; }
td.best { background: var(--best); }
.ci { color: var(--muted); font-size: 0.85em; }
#headline { width: 100%; table-layout: fixed; }
#headline th[scope=row] { width: 13em; }
#headline td { white-space: normal; }
#headline .line { display: block; white-space: nowrap; }
#headline .star { font-weight: 600; }
table.metrics td .ci { display: block; }
table.metrics th[scope=row] { position: sticky; left: 0; z-index: 1; }
[role=tablist] { display: flex; flex-wrap: wrap; gap: 4px; border-bottom: 2px solid var(--line); margin-top: 16px; }
[role=tab] { font: inherit; padding: 8px 14px; border: 1px solid var(--line); border-bottom: none; background: var(--alt);
             color: var(--fg); cursor: pointer; border-radius: 6px 6px 0 0; }
[role=tab][aria-selected=true] { background: var(--accent); color: #fff; border-color: var(--accent); }
[role=tab]:focus-visible { outline: 3px solid #E69F00; outline-offset: 2px; }
img { max-width: 100%; height: auto; border: 1px solid var(--line); display: block; }
.maps { display: grid; grid-template-columns: repeat(auto-fill, minmax(min(340px, 100%), 1fr)); gap: 12px; }
.maps figure { margin: 0; border: 1px solid var(--line); padding: 8px; background: var(--alt); min-width: 0; }
.maps figure img { width: 100%; cursor: zoom-in; }
.maps figure.zoom { grid-column: 1 / -1; }
.maps figure.zoom img { width: auto; max-width: 100%; margin: 0 auto; cursor: zoom-out; }
figcaption { font-size: 0.9rem; margin-top: 6px; }
details { margin: 8px 0; } summary { cursor: pointer; font-weight: 600; }
code { font-size: 0.8rem; background: var(--alt); padding: 1px 4px; }
code.cmd { display: block; overflow-x: auto; white-space: normal; overflow-wrap: normal; word-break: normal; padding: 4px 6px;
           margin-top: 4px; }
code.cmd > span { white-space: pre; }
.charts { display: grid; grid-template-columns: repeat(auto-fill, minmax(min(300px, 100%), 1fr)); gap: 8px 16px; }
.charts figure { margin: 0; min-width: 0; } .charts figcaption { font-weight: 600; margin: 0 0 2px; }
.charts svg { width: 100%; height: auto; display: block; font-size: 11px; fill: var(--fg); }
.charts .tick { fill: var(--muted); font-size: 10px; }
ul.legend { list-style: none; padding: 0; margin: 8px 0; display: flex; flex-wrap: wrap; gap: 4px 18px; font-size: 0.9rem; }
ul.legend li { display: flex; align-items: center; gap: 6px; }
ul.legend svg { flex: none; }
@media (max-width: 760px) {
  body { padding: 10px; font-size: 14px; }
  .hint { display: block; }
  #headline, #headline tbody, #headline tr, #headline th, #headline td { display: block; width: 100%; }
  #headline thead { position: absolute; width: 1px; height: 1px; overflow: hidden; clip: rect(0 0 0 0); }
  #headline tr { border: 1px solid var(--line); margin: 0 0 12px; }
  #headline th[scope=row], #headline td { border: none; border-top: 1px solid var(--line); }
  #headline th[scope=row] { width: 100%; }
  #headline td::before { content: attr(data-world); display: block; font-weight: 600; }
}
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
document.querySelectorAll('.maps figure img').forEach(function (img) {
  img.addEventListener('click', function () { img.parentElement.classList.toggle('zoom'); });
});
"""


def _png(fig: Any) -> str:
    """A figure as a ``data:`` URI (PNG, its colours reduced to a 64-entry palette: maps are
    flat colours), closed after."""
    import matplotlib.pyplot as plt
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=MAP_DPI, bbox_inches="tight", pad_inches=0.02)
    plt.close(fig)
    buf.seek(0)
    image = Image.open(buf).convert("RGB").quantize(colors=64)
    out = io.BytesIO()
    image.save(out, format="PNG", optimize=True)
    return "data:image/png;base64," + base64.b64encode(out.getvalue()).decode()


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


def shell_words(command: str) -> list[str]:
    """``command`` (a POSIX shell line, as :func:`shlex.join` writes it) cut at its unquoted
    blanks, each word as written (quotes kept): ``" ".join`` gives the line back when its
    words are one blank apart."""
    words: list[str] = []
    word: list[str] = []
    quote = ""
    escaped = False
    for ch in command:
        if escaped:
            word.append(ch)
            escaped = False
        elif ch == "\\" and quote != "'":
            word.append(ch)
            escaped = True
        elif quote:
            word.append(ch)
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            word.append(ch)
            quote = ch
        elif ch.isspace():
            if word:
                words.append("".join(word))
                word = []
        else:
            word.append(ch)
    if word:
        words.append("".join(word))
    return words


def command_html(command: str) -> str:
    """A shell command as ``<code class=cmd>``: one ``white-space: pre`` span per argument, one
    blank between them, so the browser breaks the line only between arguments and the copied
    text is the command on one line."""
    spans = " ".join(f"<span>{html.escape(w)}</span>" for w in shell_words(command))
    return f"<code class=cmd>{spans}</code>"


# ------------------------------------------------------------------ maps

@dataclass(frozen=True)
class EpisodeScene:
    """What a map of one episode needs from its seeded reset."""

    layout: Any
    start: tuple[float, float, float]
    goals: tuple[tuple[float, float], ...]
    goal_radius: float
    mover_specs: tuple[Any, ...]
    """The episode's movers (:class:`~bulletnav.sim.specs.ForkliftSpec` / ``WorkerSpec``); none in static worlds."""
    control_dt: float
    robot_radius: float


class Scenes:
    """Seeded resets of the suite's worlds, one env per world, each episode's scene kept."""

    def __init__(self) -> None:
        self.envs: dict[str, Any] = {}
        self.cache: dict[tuple[str, int], EpisodeScene] = {}

    def get(self, world: dict[str, Any], seed: int) -> EpisodeScene:
        key = (world["name"], seed)
        if key not in self.cache:
            import gymnasium as gym

            import bulletnav  # noqa: F401

            env = self.envs.get(world["name"])
            if env is None:
                env = self.envs[world["name"]] = gym.make(world["env"], **world["kwargs"])
            _, info = env.reset(seed=seed)
            scene = env.unwrapped.scene
            goals = tuple(tuple(g) for g in (info.get("goals") or (scene.goal,)))
            self.cache[key] = EpisodeScene(scene.layout, tuple(scene.start), goals, float(scene.goal_radius),
                                           tuple(scene.mover_specs), float(scene.control_dt), float(scene.geometry.radius))
        return self.cache[key]

    def close(self) -> None:
        for env in self.envs.values():
            env.close()
        self.envs.clear()


def robot_track(row: dict[str, Any]) -> list[tuple[float, float]]:
    """The robot's centre during each control step of ``row``'s episode (``steps`` points), from
    its recorded ``path`` (every ``max(1, (steps + 1) // 200)``-th pose from the reset on),
    linearly interpolated between the recorded poses."""
    import numpy as np

    path = np.asarray(row["path"], dtype=float)
    steps = int(row["steps"])
    stride = max(1, (steps + 1) // 200)
    at = np.arange(len(path)) * stride
    k = np.arange(steps)
    return list(zip(np.interp(k, at, path[:, 0]).tolist(), np.interp(k, at, path[:, 1]).tolist()))


def outcome_of(row: dict[str, Any]) -> str:
    return "success" if row["success"] else ("collision" if row["collision"] else "timeout")


OUTCOME_WORDS = {"success": "success", "collision": "collision", "timeout": "time-out"}
"""How captions name an outcome (the legend's words)."""


def draw_episode(ax: Any, scene: EpisodeScene, row: dict[str, Any] | None, draw_layout: DrawLayout | None) -> None:
    """One episode's map on Matplotlib axes: the layout (racks grey), the goal zone(s), the
    start, the robot's path in its outcome's colour and style with its end mark, and each mover
    at the episode's end with its dashed route."""
    from matplotlib.patches import Circle, Polygon

    from bulletnav.sim.movers import box_corners, kinematic_poses
    from bulletnav.sim.specs import ForkliftSpec

    if draw_layout is not None:
        draw_layout(ax, scene.layout, obstacle=PALETTE["obstacle"], wall=PALETTE["wall"])
    for g in scene.goals:
        ax.add_patch(Circle(g, scene.goal_radius, facecolor=PALETTE["goal"], alpha=GOAL_ALPHA, edgecolor="none", zorder=2,
                            gid="goal"))
        ax.add_patch(Circle(g, scene.goal_radius, fill=False, edgecolor=PALETTE["goal"], lw=1.4, zorder=2, gid="goal"))
    path = row.get("path") if row is not None else None
    if scene.mover_specs and path and "steps" in row:
        poses = kinematic_poses(scene.mover_specs, robot_track(row), scene.control_dt, scene.robot_radius)
        for spec, track in zip(scene.mover_specs, poses):
            route = spec.route if isinstance(spec, ForkliftSpec) else spec.waypoints
            if len(route) >= 2:
                xs, ys = zip(*route)
                ax.plot(xs, ys, color="black", lw=0.8, ls=(0, (3, 2)), alpha=ROUTE_ALPHA, zorder=2.2, gid="mover_route")
            x, y, yaw = track[-1]
            if isinstance(spec, ForkliftSpec):
                patch = Polygon(box_corners((x, y), yaw, spec.size[0], spec.size[1]), closed=True,
                                facecolor=PALETTE["forklift"], edgecolor=MOVER_EDGE, lw=0.8, zorder=2.6, gid="forklift")
            else:
                patch = Circle((x, y), spec.radius, facecolor=PALETTE["worker"], edgecolor=MOVER_EDGE, lw=0.8, zorder=2.6,
                               gid="worker")
            ax.add_patch(patch)
    if path:
        xs, ys = zip(*path)
        outcome = outcome_of(row)
        ax.plot(xs, ys, color=OUTCOME[outcome], ls=PATH_STYLE[outcome], lw=1.8, zorder=3, gid=f"path_{outcome}")
        if outcome in END_MARK:
            ax.plot(xs[-1], ys[-1], ls="", marker=END_MARK[outcome], ms=8, mfc=OUTCOME[outcome], mec="white", mew=0.8,
                    zorder=4, gid=f"end_{outcome}")
    sx, sy, syaw = scene.start
    ax.plot([sx, sx + 0.5 * math.cos(syaw)], [sy, sy + 0.5 * math.sin(syaw)], color=PALETTE["start"], lw=1.2, zorder=5)
    ax.plot(sx, sy, ls="", marker="o", ms=6, mfc="white", mec=PALETTE["start"], mew=1.2, zorder=5, gid="start")
    ax.tick_params(labelsize=6, length=2, pad=1)  # to scale, in the world's metres
    ax.set_xlabel("x (m)", fontsize=6, labelpad=1)
    ax.set_ylabel("y (m)", fontsize=6, labelpad=1)


def _map(scene: EpisodeScene, row: dict[str, Any] | None, draw_layout: DrawLayout | None) -> str:
    """One episode's map as a PNG data URI, :data:`MAP_IN` inches wide."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hx, hy = scene.layout.half_extents if scene.layout is not None else (1.0, 1.0)
    fig, ax = plt.subplots(figsize=(MAP_IN, max(1.5, MAP_IN * hy / hx)))
    draw_episode(ax, scene, row, draw_layout)
    fig.subplots_adjust(0.1, 0.1, 0.99, 0.99)  # room for the metre ticks
    return _png(fig)


def _svg(key: str) -> str:
    """The legend's sample of :data:`PALETTE` entry ``key``, drawn as the maps draw it."""
    c = PALETTE[key]
    box = "<svg width=30 height=16 viewBox='0 0 30 16' aria-hidden=true>{}</svg>"
    if key in OUTCOME:
        dash = " stroke-dasharray='5 2.5'" if key == "timeout" else ""
        mark = {"collision": f"<path d='M19 3 L29 13 M29 3 L19 13' fill='none' stroke='{c}' stroke-width=3 />",
                "timeout": f"<rect x=20 y=4 width=8 height=8 fill='{c}' stroke='none' />"}.get(key, "")
        return box.format(f"<line x1=1 y1=8 x2={18 if mark else 29} y2=8 fill='none' stroke='{c}' stroke-width=3{dash} />{mark}")
    if key == "goal":
        return box.format(f"<circle cx=15 cy=8 r=7 fill='{c}' fill-opacity='{GOAL_ALPHA}' stroke='{c}' stroke-width=1.5 />")
    if key == "start":
        return box.format(f"<circle cx=12 cy=8 r=4 fill='#ffffff' stroke='{c}' stroke-width=1.5 />"
                          f"<line x1=16 y1=8 x2=26 y2=8 fill='none' stroke='{c}' stroke-width=1.5 />")
    if key == "obstacle":
        return box.format(f"<rect x=3 y=2 width=24 height=12 fill='{c}' stroke='{PALETTE['wall']}' stroke-width=0.8 />")
    if key == "forklift":
        return box.format(f"<rect x=6 y=3 width=18 height=10 fill='{c}' stroke='{MOVER_EDGE}' stroke-width=1 />")
    if key == "worker":
        return box.format(f"<circle cx=15 cy=8 r=6 fill='{c}' stroke='{MOVER_EDGE}' stroke-width=1 />")
    raise KeyError(key)


LEGEND_TEXT = {
    "success": "{} line: success",
    "collision": "{} line, &#10005; at its end: collision",
    "timeout": "{} dashed line, &#9632; at its end: time-out",
    "goal": "{} disc: goal zone",
    "start": "white dot with a {} tick: start and heading",
    "obstacle": "{}: racks, walls and obstacles",
    "forklift": "{} box: a forklift where it was when the episode ended",
    "worker": "{} disc: a worker where they were when the episode ended",
}
"""Each legend entry's text; ``{}`` is the colour's name (:data:`COLOUR_NAMES`)."""


def legend_html(movers: bool) -> str:
    """The maps' legend: a sample drawn in each :data:`PALETTE` colour and its name; the movers'
    entries with ``movers``."""
    keys = [k for k in LEGEND_TEXT if movers or k not in ("forklift", "worker")]
    items = "".join(f"<li data-key={k}>{_svg(k)}<span>{LEGEND_TEXT[k].format(COLOUR_NAMES[k])}</span></li>" for k in keys)
    route = ("<li data-key=route><svg width=30 height=16 viewBox='0 0 30 16' aria-hidden=true><line x1=1 y1=8 x2=29 y2=8 "
             f"fill='none' stroke='#000000' stroke-opacity='{ROUTE_ALPHA}' stroke-width=1.2 stroke-dasharray='4 2.5' /></svg>"
             "<span>thin black dashes: a mover's route</span></li>") if movers else ""
    return f"<ul class=legend aria-label='map legend'>{items}{route}</ul>"


# ------------------------------------------------------------------ the page

def render_report(results: dict[str, Any], results_name: str = "results.json",
                  draw_layout: DrawLayout | None = None, plots: dict[str, Path] | None = None,
                  pair_plots: dict[str, list[Path]] | None = None) -> str:
    """The HTML page of ``results`` (a ``results.json`` record); ``draw_layout`` draws the maps
    under the pictured paths (None: paths on blank axes); ``plots``: each BARN group's per-world
    metric plot (a PNG beside the page: shown and linked); ``pair_plots``: each BARN group's
    per-world success plots of a DWA run here beside BARN's DWA rows (shown and linked too)."""
    suite = results["suite"]
    worlds = [w for w in suite["worlds"] if not w.get("group")]  # a BARN group's worlds share one tab
    barn = results.get("barn", [])
    controllers = [c["name"] for c in suite["controllers"]]
    cells = {(c["world"], c["controller"]): c["summary"] for c in results["cells"]}
    rows_by_world: dict[str, dict[tuple[str, int], dict]] = {w["name"]: {} for w in suite["worlds"]}
    for row in results["episodes"]:
        rows_by_world[row["world"]][(row["controller"], row["episode"])] = row
    out = _page_head(results, results_name, controllers, worlds, barn)
    out += _headline(worlds, controllers, cells, best_controllers(results), barn)
    scenes = Scenes()
    try:
        for i, w in enumerate(worlds):  # one tab per world
            out += _world_panel(i, w, controllers, cells, rows_by_world[w["name"]], results["metrics"], suite["seed"],
                                draw_layout, scenes)
    finally:
        scenes.close()
    for i, section in enumerate(barn):  # one tab per BARN group
        out += _barn_panel(i, section, results["episodes"], (plots or {}).get(section["group"]),
                           (pair_plots or {}).get(section["group"], []))
    esc = html.escape
    definitions = "".join(f"<dt><b>{esc(k)}</b></dt><dd>{esc(v)}</dd>" for k, v in results["metrics"].items())
    out.append(f"<h2>Metrics</h2><dl>{definitions}</dl>")
    out.append(f"<script>{SCRIPT}</script></body></html>")
    return "\n".join(out)


def _mixed_commits(prov: dict[str, Any]) -> str:
    """A sentence naming the checkouts that ran each controller's rows, where a resumed run
    mixes several (``provenance.row_commits``); empty where one ran them all."""
    by_commit: dict[str, list[str]] = {}
    for controller, counts in (prov.get("row_commits") or {}).items():
        for commit, n in counts.items():
            by_commit.setdefault(commit, []).append(f"{controller} ({n})")
    if len(by_commit) < 2:
        return ""
    esc = html.escape
    parts = "; ".join(f"<code>{esc(commit[:12])}</code>: {esc(', '.join(names))}" for commit, names in by_commit.items())
    return f" The rows come from more than one checkout: {parts}."


def _page_head(results: dict[str, Any], results_name: str, controllers: list[str], worlds: list[dict[str, Any]],
               barn: list[dict[str, Any]]) -> list[str]:
    """The page's lines up to its tab list: title, the run's provenance and one tab per view
    (the headline, each of ``worlds``, each BARN group of ``barn``)."""
    suite = results["suite"]
    prov = results.get("provenance", {})
    esc = html.escape
    out = ["<!doctype html><html lang=en><head><meta charset=utf-8>",
           "<meta name=viewport content='width=device-width, initial-scale=1'>",
           f"<title>bulletnav benchmark: {esc(suite['name'])}</title><style>{CSS}</style></head><body>",
           f"<h1>bulletnav benchmark: <code>{esc(suite['name'])}</code></h1>",
           f"<p class=meta>{sum(w['episodes'] for w in suite['worlds']) * len(controllers)} episodes: "
           f"{len(suite['worlds'])} worlds x {len(controllers)} controllers; episode k of a world is "
           f"<code>env.reset(seed={suite['seed']} + k)</code> for every controller. "
           f"Commit {esc(str(prov.get('git_commit', '?'))[:12])}{' (dirty)' if prov.get('dirty') else ''}, "
           f"{esc(str(prov.get('machine', '?')))}, {prov.get('workers', '?')} workers, "
           f"{prov.get('wall_time_s', '?')} s. Raw data: <a href='{esc(results_name)}'>{esc(results_name)}</a>. "
           f"Command: {command_html(str(prov.get('command', '')))}{_mixed_commits(prov)}</p>",
           "<div role=tablist aria-label='Benchmark views'>",
           "<button role=tab id=tab-headline aria-controls=panel-headline aria-selected=true>Headline</button>"]
    for i, w in enumerate(worlds):
        out.append(f"<button role=tab id=tab-w{i} aria-controls=panel-w{i} aria-selected=false tabindex=-1>"
                   f"{esc(w['name'])}</button>")
    for i, section in enumerate(barn):
        out.append(f"<button role=tab id=tab-barn{i} aria-controls=panel-barn{i} aria-selected=false tabindex=-1>"
                   f"BARN: {esc(section['group'])}</button>")
    out.append("</div>")
    return out


def _success_chart(w: dict[str, Any], controllers: list[str], cells: dict[tuple[str, str], Any],
                   best: dict[str, str]) -> str:
    """World ``w``'s success rate of every controller as a dot with its 95 % interval (inline SVG,
    0-100 %), the best starred."""
    esc = html.escape
    left, right, row, top = 128, 298, 20, 8
    height = top + row * len(controllers) + 22

    def x(rate: float) -> float:
        return left + (right - left) * rate

    parts = [f"<line x1={x(t):.1f} y1={top - 4} x2={x(t):.1f} y2={height - 20} stroke='#d0d3d9' />"
             f"<text x={x(t):.1f} y={height - 6} text-anchor=middle class=tick>{t * 100:.0f} %</text>" for t in (0, 0.5, 1)]
    for i, c in enumerate(controllers):
        y = top + row * i + row / 2
        s = cells.get((w["name"], c))
        star = "&#9733; " if best.get(w["name"]) == c else ""
        parts.append(f"<text x={left - 8} y={y + 4:.1f} text-anchor=end>{star}{esc(c)}</text>")
        if not s or not s["episodes"] or s["success"]["mean"] is None:
            continue
        cell = s["success"]
        if cell.get("lo") is not None:
            parts.append(f"<line x1={x(cell['lo']):.1f} y1={y:.1f} x2={x(cell['hi']):.1f} y2={y:.1f} "
                         f"stroke='{PALETTE['success']}' stroke-width=2.5 />")
        parts.append(f"<circle cx={x(cell['mean']):.1f} cy={y:.1f} r=4 fill='{PALETTE['success']}'>"
                     f"<title>{esc(c)}: {cell['mean'] * 100:.1f} %</title></circle>")
    return (f"<figure><figcaption>{esc(w['name'])}: success</figcaption><svg viewBox='0 0 320 {height}' role=img "
            f"aria-label='success of every controller in {esc(w['name'], quote=True)}'>{''.join(parts)}</svg></figure>")


def _headline(worlds: list[dict[str, Any]], controllers: list[str], cells: dict[tuple[str, str], Any],
              best: dict[str, str], barn: list[dict[str, Any]] | None = None) -> list[str]:
    """The headline tab's lines: a row per controller, a column per world, each cell its
    success, collisions and SPL with their intervals; the best of each world starred. Then
    each BARN group's overall table (:func:`_barn_overall`)."""
    esc = html.escape
    head = "<section role=tabpanel id=panel-headline aria-labelledby=tab-headline>"
    tables = [head] + [line for section in barn or [] for line in _barn_overall(section, True)]
    if not worlds:
        return tables + ["</section>"]
    out = [tables[0] + "".join(tables[1:]) +
           "<h2>Headline: success, collisions and SPL (95 % bootstrap intervals)</h2>"
           "<div class=charts>" + "".join(_success_chart(w, controllers, cells, best) for w in worlds) + "</div>"
           "<p class=note>Dots: success rate; bars: its 95 % interval.</p>"
           "<table id=headline><thead><tr><th scope=col>controller</th>"]
    for w in worlds:
        out.append(f"<th scope=col>{esc(w['name'])}<br><span class=ci>{esc(w['env'])}"
                   f"{' ' + esc(str(w['kwargs'])) if w['kwargs'] else ''}, {w['episodes']} episodes</span></th>")
    out.append("</tr></thead><tbody>")
    for c in controllers:
        out.append(f"<tr data-controller='{esc(c, quote=True)}'><th scope=row>{esc(c)}</th>")
        for w in worlds:
            s = cells.get((w["name"], c))
            mark = best.get(w["name"]) == c
            body = ("&ndash;" if not s or not s["episodes"] else
                    f"<span class=line>success {_fmt(s['success'], 'success')}</span>"
                    f"<span class=line>collisions {_fmt(s['collision'], 'collision')}</span>"
                    f"<span class=line>SPL {_fmt(s['spl'], 'spl')}</span>")
            star = "<span class='line star'>&#9733; best</span>" if mark else ""
            out.append(f"<td class='num{' best' if mark else ''}' data-world='{esc(w['name'], quote=True)}'>{star}{body}</td>")
        out.append("</tr>")
    out.append("</tbody></table><p class=note>&#9733; best: highest success, then fewest collisions, then "
               "highest SPL. Every world's tab has all the metrics, maps of the first episodes and the failures.</p>"
               "</section>")
    return out


def _barn_note(rows: dict[tuple[str, int], dict]) -> str:
    """A note under a world's metrics when ``barn_score`` says little more than success there:
    most successes reach its cap of 0.5 (every time under 2 t_opt is clipped to 2 t_opt)."""
    wins = [r for r in rows.values() if r["success"] and "barn_score" in r]
    if not wins:
        return ""
    capped = sum(r["barn_score"] >= 0.5 - 1e-9 for r in wins) / len(wins)
    if capped < 0.5:
        return ""
    return (f"<p class=note>barn_score is at most 0.5 (a time under 2 t_opt counts as 2 t_opt), and "
            f"{capped * 100:.0f} % of this world's successful episodes reach that cap: here it is about success / 2 "
            f"and ranks the controllers as success does.</p>")


def _world_panel(i: int, w: dict[str, Any], controllers: list[str], cells: dict[tuple[str, str], Any],
                 rows: dict[tuple[str, int], dict], metrics: dict[str, str], seed: int,
                 draw_layout: DrawLayout | None, scenes: Scenes) -> list[str]:
    """World ``i``'s tab: every metric of every controller, the first episodes' maps and the
    failure gallery."""
    esc = html.escape
    out = [f"<section role=tabpanel id=panel-w{i} aria-labelledby=tab-w{i} hidden>"
           f"<h2>{esc(w['name'])} ({esc(w['env'])}, {w['episodes']} episodes)</h2>"
           "<p class=hint>&#8596; The table scrolls sideways.</p>"
           f"<div class=scroll><table class=metrics><thead><tr><th scope=col>metric</th>"]
    out += [f"<th scope=col>{esc(c)}</th>" for c in controllers]
    out.append("</tr></thead><tbody>")
    for name, definition in metrics.items():
        out.append(f"<tr><th scope=row title='{esc(definition, quote=True)}'>{esc(name)}</th>")
        out += [f"<td class=num>{_fmt((cells.get((w['name'], c)) or {}).get(name), name)}</td>" for c in controllers]
        out.append("</tr>")
    out.append("</tbody></table></div>")
    out.append(_barn_note(rows))
    shown = min(PICTURED, w["episodes"])
    movers = any(scenes.get(w, seed + k).mover_specs for k in range(shown))
    out.append("<h3>Maps</h3>" + legend_html(movers))
    if movers:
        out.append("<p class=note>Movers are re-created from the episode's seed and the robot's recorded path. Pallets "
                   "that appear or vanish during an episode are not drawn.</p>")
    out.append("<p class=note>Click a map to enlarge it.</p><h3>The first episodes, every controller</h3>")
    for k in range(shown):
        scene = scenes.get(w, seed + k)
        out.append(f"<details{' open' if k == 0 else ''}><summary>Episode {k} (seed {seed + k})</summary><div class=maps>")
        for c in controllers:
            row = rows.get((c, k))
            what = f"{OUTCOME_WORDS[outcome_of(row)]} after {row['time_s']:.1f} s" if row is not None else "no row"
            out.append(f"<figure><img alt='{esc(c, quote=True)}, episode {k}: {what}' "
                       f"src='{_map(scene, row, draw_layout)}'><figcaption>{esc(c)}: {what}</figcaption></figure>")
        out.append("</div></details>")
    out.append("<h3>Failure gallery</h3>")
    out += _failure_gallery(w, controllers, rows, draw_layout, scenes)
    out.append("</section>")
    return out


def _failure_gallery(w: dict[str, Any], controllers: list[str], rows: dict[tuple[str, int], dict],
                     draw_layout: DrawLayout | None, scenes: Scenes) -> list[str]:
    """The first :data:`GALLERY` failed episodes of each controller in world ``w``, each a
    map with its outcome and replay command."""
    esc = html.escape
    failures = [r for r in sorted(rows.values(), key=lambda r: (controllers.index(r["controller"]), r["episode"]))
                if not r["success"]]
    shown = []
    for c in controllers:
        shown += [r for r in failures if r["controller"] == c][:GALLERY]
    if not shown:
        return ["<p class=note>No failures.</p>"]
    out = ["<div class=maps>"]
    for r in shown:
        outcome = OUTCOME_WORDS[outcome_of(r)]
        replay = f" Replay: {command_html(r['replay'])}" if r.get("replay") else ""
        out.append(f"<figure><img alt='{esc(r['controller'], quote=True)} {outcome} seed {r['seed']}' "
                   f"src='{_map(scenes.get(w, r['seed']), r, draw_layout)}'><figcaption>{esc(r['controller'])}: {outcome} "
                   f"after {r['time_s']:.1f} s (episode {r['episode']}, seed {r['seed']}).{replay}</figcaption></figure>")
    out.append("</div>")
    return out


def write_report(results: dict[str, Any], path: Path, draw_layout: DrawLayout | None = None) -> Path:
    """Write :func:`render_report` to ``path`` atomically (:func:`bulletnav.files.write_bytes`),
    and beside it each BARN group's per-world metric plot, ``barn_metric_<group>.png``
    (:func:`bulletnav.benchmark.barn.plot_metric`), and for each DWA run here its per-world
    success beside BARN's DWA rows, ``barn_success_<group>_<k>.png`` (k: its place among the
    group's controllers; :func:`bulletnav.benchmark.barn.plot_success_pair`)."""
    from bulletnav.benchmark.barn import DWA_NAME, plot_metric, plot_success_pair

    sections = results.get("barn", [])
    plots = {s["group"]: plot_metric(s, path.parent / f"barn_metric_{s['group']}.png") for s in sections}
    pairs = {s["group"]: [plot_success_pair(s, e["name"], DWA_NAME, path.parent / f"barn_success_{s['group']}_{i}.png")
                          for i, e in enumerate(s["controllers"]) if e.get("agreement")] for s in sections}
    write_bytes(path, render_report(results, draw_layout=draw_layout, plots=plots, pair_plots=pairs).encode())
    return path


# ------------------------------------------------------------------ BARN groups

BARN_DIFFERS = ("The same worlds, start, goal, rules (success, any contact a collision, the 100 s clock from the first "
                "0.1 m) and score as BARN's run.py and report_test.py, not the same simulator: bulletnav runs PyBullet "
                "with its Jackal-sized model (0.508 x 0.430 m, 2 m/s, a 270-degree lidar seen as 72 rays), BARN runs "
                "Gazebo with Clearpath's Jackal. The DWA row is BARN's published res/dwa_out.txt over the same worlds: ")
"""What the BARN tab says about the comparison (the DWA note follows)."""


def _barn_overall(section: dict[str, Any], short: bool = False) -> list[str]:
    """A BARN group's overall table: a row per controller and DWA's, report_test.py's five figures
    with their intervals."""
    esc = html.escape
    out = [f"<h2>BARN: {esc(section['group'])} ({len(section['worlds'])} worlds x {section['runs']} runs), as BARN's "
           "report_test.py summarises</h2><div class=scroll><table class=metrics data-barn-overall><thead><tr>"
           "<th scope=col>controller</th><th scope=col>worlds</th><th scope=col>success</th>"
           "<th scope=col>collisions</th><th scope=col>time-outs</th><th scope=col>BARN time (s)</th>"
           "<th scope=col>BARN metric</th></tr></thead><tbody>"]
    for entry in section["controllers"]:
        o = entry["overall"]
        dwa = entry["source"] == "published"
        name = f"{esc(entry['name'])}<br><span class=ci>published, {esc(entry['note'])}</span>" if dwa \
            else esc(entry["name"])
        out.append(f"<tr{' data-dwa' if dwa else ''}><th scope=row>{name}</th><td class=num>{o['worlds']}</td>"
                   + "".join(f"<td class=num>{_fmt(o[f], f)}</td>" for f in ("success", "collision", "timeout",
                                                                           "time_s", "metric")) + "</tr>")
    out.append(f"</tbody></table></div><p class=note>Each figure is a mean over worlds of the per-world means, as "
               f"report_test.py computes it (BARN time: over the worlds with a success). Intervals: "
               f"{esc(section['intervals'])}. Metric: {esc(section['metric'])}. DWA over all 50 test worlds "
               f"(its 500 rows): <code>{esc(section['dwa_all_line'])}</code>.</p>")
    out += _barn_agreement(section)
    if not short:
        lines = "".join(f"<li>{esc(e['name'])}: <code>{esc(e['overall']['line'] or 'no runs')}</code></li>"
                        for e in section["controllers"])
        out.append(f"<details><summary>report_test.py's lines</summary><ul>{lines}</ul></details>")
    return out


def _barn_agreement(section: dict[str, Any]) -> list[str]:
    """The agreement of each DWA run here with BARN's DWA rows (:func:`bulletnav.benchmark.barn.agreement`)."""
    esc = html.escape
    rows = []
    for entry in section["controllers"]:
        a = entry.get("agreement")
        if not a:
            continue
        ratio = "&ndash;" if a["time_ratio"] is None else f"{a['time_ratio']:.2f}"
        rows.append(f"<tr><th scope=row>{esc(entry['name'])}</th><td class=num>{a['success_points']:+.1f}</td>"
                    f"<td class=num>{ratio}</td><td class=num>{a['worlds_within']} of {a['worlds']} "
                    f"(need {a['worlds_needed']})</td><td>{'yes' if a['agrees'] else 'no'}</td></tr>")
    if not rows:
        return []
    return ["<h3>DWA here against DWA in Gazebo (BARN's rows)</h3><div class=scroll><table class=metrics data-agreement>"
            "<thead><tr><th scope=col>controller</th><th scope=col>success, points</th>"
            "<th scope=col>mean time of successes, ratio</th><th scope=col>worlds with success within 0.3</th>"
            "<th scope=col>agrees</th></tr></thead><tbody>", *rows,
            "</tbody></table></div><p class=note>Agreement: success within 10 points, time within 30 %, per-world "
            "success within 0.3 in 35 of 50 worlds (scaled to the worlds both ran).</p>"]


def _barn_panel(i: int, section: dict[str, Any], rows: list[dict[str, Any]], plot: Path | None,
                pair_plots: list[Path] = ()) -> list[str]:
    """BARN group ``i``'s tab: the overall table, the per-world plots (the metric of every
    controller, and each DWA run's success beside BARN's DWA rows), each controller's per-world
    table and its failures' replay commands."""
    from bulletnav.benchmark.barn import DWA_NOTE

    esc = html.escape
    out = [f"<section role=tabpanel id=panel-barn{i} aria-labelledby=tab-barn{i} hidden>",
           f"<p class=note>{esc(BARN_DIFFERS)}{esc(DWA_NOTE)}.</p>", *_barn_overall(section)]
    if plot is not None and plot.is_file():
        uri = "data:image/png;base64," + base64.b64encode(plot.read_bytes()).decode()
        out.append(f"<h3>BARN metric per world</h3><figure class=barn-plot><a href='{esc(plot.name, quote=True)}'>"
                   f"<img alt='BARN metric per world of every controller and DWA' src='{uri}'></a>"
                   f"<figcaption>{esc(plot.name)} (click for the file)</figcaption></figure>")
    for pair in pair_plots:
        if pair.is_file():
            uri = "data:image/png;base64," + base64.b64encode(pair.read_bytes()).decode()
            out.append(f"<figure class=barn-plot><a href='{esc(pair.name, quote=True)}'><img alt='success per world of "
                       f"a DWA run here beside BARN&#39;s DWA rows' src='{uri}'></a><figcaption>{esc(pair.name)} (click "
                       "for the file)</figcaption></figure>")
    out.append("<h3>Per world</h3>")
    for entry in section["controllers"]:
        body = "".join(f"<tr><th scope=row>{p['world']}</th><td class=num>{p['runs']}</td>"
                       + "".join(f"<td class=num>{_fmt(p[f], f)}</td>" for f in ("success", "collision", "timeout",
                                                                               "time_s", "metric")) + "</tr>"
                       for p in entry["per_world"])
        note = f" (published, {esc(entry['note'])})" if entry["source"] == "published" else ""
        out.append(f"<details><summary>{esc(entry['name'])}{note}</summary><div class=scroll><table class=metrics>"
                   "<thead><tr><th scope=col>world</th><th scope=col>runs</th><th scope=col>success</th>"
                   "<th scope=col>collisions</th><th scope=col>time-outs</th><th scope=col>BARN time (s)</th>"
                   f"<th scope=col>BARN metric</th></tr></thead><tbody>{body}</tbody></table></div></details>")
    failed = [r for r in rows if r.get("world_idx") is not None and not r["success"] and r.get("replay")]
    if failed:
        items = "".join(f"<li>{esc(r['controller'])}, world {r['world_idx']}, run {r['episode']}: "
                        f"{OUTCOME_WORDS[outcome_of(r)]} after {r['barn_time_s']:.1f} s. {command_html(r['replay'])}</li>"
                        for r in failed[:GALLERY * 10])
        out.append(f"<details><summary>Failures ({len(failed)}; the first {min(len(failed), GALLERY * 10)} with the "
                   f"command that replays each)</summary><ul>{items}</ul></details>")
    out.append("</section>")
    return out


SCREENSHOT_WIDTHS = (1400, 390)
"""Viewport widths (px) of the ``report_<width>.png`` screenshots: a laptop and a phone."""


def screenshots(report: Path, out: Path, tab: int = 0, width: int = 1280) -> list[Path]:
    """PNG screenshots of a report in Debian's Chromium (Playwright), full page: ``headline.png``
    and the world tab ``tab`` (``world.png``) at ``width`` pixels, and the headline at each of
    :data:`SCREENSHOT_WIDTHS` (``report_1400.png``, ``report_390.png``).

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
            for w in SCREENSHOT_WIDTHS:
                page.set_viewport_size({"width": w, "height": 900})
                page.click("#tab-headline")
                paths.append(out / f"report_{w}.png")
                write_bytes(paths[-1], page.screenshot(full_page=True))
        finally:
            browser.close()
    return paths
