"""Fleet scaling: wall time per control step for N = 1, 2, 4, 8, 16 robots.

The driver is fixed: every robot runs the independent controller (PID + A* on its own lidar
map, :func:`bulletnav.fleet.controllers.independent_controller`), so a step's time is the
fleet env's step (physics, every robot's lidar seeing the others, contacts, tasks) plus N
navigators. Each N is timed on the same seeded episode start (a static aisle warehouse),
after a warm-up of ``warmup`` steps (the numba kernels, the first plans); ``steps`` steps
are timed, each split into the controller's share and the env's. ``per_robot_ratio`` is the
time per robot per step relative to N = 1 (1.0: linear scaling; below 1: robots share costs).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from bulletnav.fleet.controllers import independent_controller
from bulletnav.fleet.env import FleetEnv

SIZES = (1, 2, 4, 8, 16)
"""Fleet sizes timed."""


def bench_fleet(sizes: tuple[int, ...] = SIZES, steps: int = 480, warmup: int = 48, seed: int = 0) -> dict[str, Any]:
    """Time ``steps`` control steps at each fleet size (see the module docstring)."""
    rows = []
    hz = 24
    for n in sizes:
        env = FleetEnv(num_robots=n, duration_s=3600.0)
        hz = env.config.physics.control_hz
        try:
            controller = independent_controller(env)
            obs, infos = env.reset(seed=seed)
            controller.reset(infos)
            for _ in range(warmup):
                obs, _, _, _, infos = env.step(controller.act(obs, infos))
            ctl_s = np.zeros(steps)
            env_s = np.zeros(steps)
            for k in range(steps):
                t0 = time.perf_counter()
                actions = controller.act(obs, infos)
                t1 = time.perf_counter()
                obs, _, _, _, infos = env.step(actions)
                t2 = time.perf_counter()
                ctl_s[k], env_s[k] = t1 - t0, t2 - t1
        finally:
            env.close()
        total = ctl_s + env_s
        rows.append({"robots": n, "step_ms": float(total.mean() * 1e3), "step_ms_median": float(np.median(total) * 1e3),
                     "env_ms": float(env_s.mean() * 1e3), "controller_ms": float(ctl_s.mean() * 1e3),
                     "per_robot_ms": float(total.mean() * 1e3 / n),
                     "realtime_factor": float((1.0 / hz) / total.mean())})
    base = rows[0]["per_robot_ms"] if rows and rows[0]["robots"] == 1 else None
    for row in rows:
        row["per_robot_ratio"] = row["per_robot_ms"] / base if base else None
    return {"benchmark": "fleet_scaling", "controller": "independent (PID + A* on each robot's lidar map)",
            "world": "WarehouseAisles-v0 settings, static", "seed": seed, "steps": steps, "warmup": warmup,
            "control_hz": hz, "sizes": rows}


__all__ = ["SIZES", "bench_fleet"]
