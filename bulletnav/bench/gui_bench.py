"""GUI frame rate with the sensor dashboard: throttled (the article's fix), unthrottled, none.

Needs an X display (``xvfb-run -a bulletnav bench gui`` on a headless machine). The A*
navigator drives; frames per second are env steps per wall-clock second with real-time
pacing off, so the figure is what the GUI and the dashboard cost, not the pacing.
"""

from __future__ import annotations

import os
from dataclasses import asdict
from typing import Any

import gymnasium as gym


def bench_gui(steps: int = 100, repeats: int = 3, seed: int = 0) -> dict[str, Any]:
    """Median FPS over ``repeats`` interleaved runs of ``steps`` steps for each dashboard setting.

    Raises:
        DisplayError: no X display to open the GUI on.
    """
    import bulletnav  # noqa: F401
    from bulletnav.control.navigator import Navigator, NavigatorConfig
    from bulletnav.viz import DashboardConfig, compare_gui_fps

    env = gym.make("bulletnav/Warehouse-v0", render_mode="human")
    try:
        fps = compare_gui_fps(env, Navigator(NavigatorConfig(planner="astar")), steps, seed=seed, repeats=repeats)
    finally:
        env.close()
    return {
        "benchmark": "gui",
        "steps": steps,
        "repeats": repeats,
        "fps_throttled": round(fps["throttled"], 2),
        "fps_unthrottled": round(fps["unthrottled"], 2),
        "fps_no_dashboard": round(fps["no_dashboard"], 2),
        "throttled_vs_unthrottled": round(fps["throttled"] / fps["unthrottled"], 2),
        "throttles": asdict(DashboardConfig()),
        "display": os.environ.get("DISPLAY", ""),
    }
