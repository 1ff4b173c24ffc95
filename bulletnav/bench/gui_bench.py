"""GUI frame rate with the sensor dashboard: throttled (the article's fix), unthrottled, none.

Needs an X display (``xvfb-run -a bulletnav bench gui`` on a headless machine). The A*
navigator drives; frames per second are env steps per wall-clock second with real-time
pacing off, so the figure is what the GUI and the dashboard cost, not the pacing.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import asdict
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.policy import Policy
from bulletnav.viz.dashboard import Dashboard, DashboardConfig

log = logging.getLogger(__name__)


def gui_fps(env: Any, policy: Policy, steps: int, config: DashboardConfig | None = DashboardConfig(),
            seed: int = 0, real_time: bool = False, warmup: int = 10) -> float:
    """Env steps per wall-clock second in the GUI, with a dashboard (``config=None``: without).

    The env is reset with ``seed`` first (and ``seed + k`` when an episode ends; resets are
    not timed). ``policy`` follows :class:`~bulletnav.policy.Policy`; its ``path``
    attribute, when present, is drawn.

    Args:
        steps: timed env steps.
        real_time: keep the env's real-time pacing (at most ``control_hz`` steps/s). False
            switches it off (``env.unwrapped.pace_gui``) for the measurement, so the figure
            is the cost of simulating and drawing, not the pacing cap.
        warmup: untimed steps first; the default (10) covers the first draw, which creates
            the debug items (~0.1-0.2 s each under Xvfb, once per scene), so the figure is
            the steady state.
    """
    u = env.unwrapped
    if u.render_mode != "human":
        raise ValueError("gui_fps needs an env made with render_mode='human'")
    paced = u.pace_gui
    u.pace_gui = real_time
    try:
        episode = 0

        def start() -> tuple[Any, dict]:
            obs, info = env.reset(seed=seed + episode)
            policy.reset(info)
            return obs, info

        obs, info = start()
        dash = Dashboard(env, config) if config is not None else None
        elapsed = 0.0
        for k in range(warmup + steps):
            t0 = time.perf_counter()
            obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
            if dash is not None:
                dash.on_step(getattr(policy, "path", None))
            if k >= warmup:
                elapsed += time.perf_counter() - t0
            if terminated or truncated:
                episode += 1
                obs, info = start()
                if dash is not None:
                    dash.on_reset()
        return steps / elapsed
    finally:
        u.pace_gui = paced


def compare_gui_fps(env: Any, policy: Policy, steps: int, seed: int = 0, real_time: bool = False,
                    repeats: int = 1) -> dict[str, float]:
    """Median :func:`gui_fps` without a dashboard, with the default throttled one, and unthrottled.

    The three run interleaved ``repeats`` times (seeds ``seed, seed + 1, ...``), so that a
    change in machine load does not favour one of them.
    """
    configs = {"no_dashboard": None, "throttled": DashboardConfig(), "unthrottled": DashboardConfig.unthrottled()}
    runs: dict[str, list[float]] = {name: [] for name in configs}
    for r in range(repeats):
        for name, cfg in configs.items():
            runs[name].append(gui_fps(env, policy, steps, cfg, seed + r, real_time))
    log.info("gui fps runs: %s", runs)
    return {name: float(np.median(v)) for name, v in runs.items()}


def bench_gui(steps: int = 100, repeats: int = 3, seed: int = 0) -> dict[str, Any]:
    """Median FPS over ``repeats`` interleaved runs of ``steps`` steps for each dashboard setting.

    Raises:
        DisplayError: no X display to open the GUI on.
    """
    import bulletnav  # noqa: F401
    from bulletnav.control.navigator import Navigator, NavigatorConfig

    env = gym.make("bulletnav/Warehouse-v0", render_mode="human")
    try:
        nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner="astar"))
        fps = compare_gui_fps(env, nav, steps, seed=seed, repeats=repeats)
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
