"""A* against RRT: planning cost on standard problems, and navigation on the same episodes.

The second part reproduces the article's experiment: the same PID follower, the same lidar
map, the same ``bulletnav/Warehouse-v0`` episodes (seed ``S + k``), only the planner differs.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.planning import bench_planners, warmup


def bench_navigation(episodes: int = 50, seed: int = 1000, num_obstacles: int = 31) -> dict[str, Any]:
    import bulletnav  # noqa: F401

    warmup()
    micro = bench_planners(seed=0, n=200)
    rows = {}
    for planner in ("astar", "rrt"):
        env = gym.make("bulletnav/Warehouse-v0", num_obstacles=num_obstacles)
        try:
            results = run_episodes(env, Navigator(NavigatorConfig(planner=planner)), episodes, seed)
        finally:
            env.close()
        s = summarize(results)
        rows[planner] = {
            "success_rate": s["success_rate"],
            "collision_rate": s["collision_rate"],
            "spl": round(s["spl"], 4),
            "plan_ms_median": round(s["plan_ms_median"], 4),
            "plan_ms_p95": round(s["plan_ms_p95"], 4),
            "plan_calls": s["plan_calls"],
            "replans_per_episode": round(s["replans_mean"], 2),
            "sim_time_to_goal_s": round(s["mean_sim_time_success"], 3),
            "path_length_m": round(s["mean_path_length_success"], 3),
            "mean_steps": round(s["mean_length"], 1),
            "_results": results,
        }
    # paired comparison on the episodes both planners solved
    a, r = rows["astar"].pop("_results"), rows["rrt"].pop("_results")
    paired = [(x, y) for x, y in zip(a, r) if x.success and y.success]
    comparison = {
        "episodes_both_succeeded": len(paired),
        "rrt_minus_astar_sim_time_s": round(float(np.mean([y.sim_time - x.sim_time for x, y in paired])), 3) if paired else None,
        "rrt_minus_astar_path_m": round(float(np.mean([y.path_length - x.path_length for x, y in paired])), 3) if paired else None,
        "rrt_faster_to_goal_fraction": round(float(np.mean([y.sim_time < x.sim_time for x, y in paired])), 3) if paired else None,
    }
    return {"benchmark": "planners", "episodes": episodes, "seed": seed, "num_obstacles": num_obstacles,
            "standard_problems": micro, "navigation": rows, "paired": comparison}
