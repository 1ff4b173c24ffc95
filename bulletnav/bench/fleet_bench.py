"""Fleet scaling: wall time per control step for N = 1, 2, 4, 8, 16 robots.

Every controller is timed at every size (``independent``: PID + A* on each robot's lidar map;
``coordinated``: prioritized space-time planning; ``policy``: the shipped single-robot model
on every robot, one forward pass for all). A step's time is the fleet env's step (physics,
every robot's lidar seeing the others, contacts, tasks) plus the controller's. Each N is
timed on the same seeded episode start (a static aisle warehouse), after a warm-up of
``warmup`` steps (the numba kernels, the first plans); ``steps`` steps are timed, each split
into the controller's share and the env's. ``per_robot_ratio`` is the time per robot per step
relative to N = 1 with the same controller (1.0: linear scaling; below 1: robots share
costs), ``env_per_robot_ratio`` the same for the env's share alone.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from bulletnav.fleet.controllers import CONTROLLERS, DEFAULT_FLEET_MODEL, make_controller, model_env_kwargs
from bulletnav.fleet.env import FleetEnv

SIZES = (1, 2, 4, 8, 16)
"""Fleet sizes timed."""


def time_fleet(controller_name: str, n: int, steps: int, warmup: int, seed: int) -> dict[str, Any]:
    """One row: ``steps`` timed control steps of ``n`` robots driven by ``controller_name``."""
    model = DEFAULT_FLEET_MODEL if controller_name == "policy" else None
    kwargs = dict(model_env_kwargs(model)) if model else {}
    env = FleetEnv(num_robots=n, duration_s=3600.0, **kwargs)
    hz = env.config.physics.control_hz
    try:
        controller = make_controller(controller_name, env, model=model)
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
    return {"controller": controller_name, "robots": n, "step_ms": float(total.mean() * 1e3),
            "step_ms_median": float(np.median(total) * 1e3), "env_ms": float(env_s.mean() * 1e3),
            "controller_ms": float(ctl_s.mean() * 1e3), "per_robot_ms": float(total.mean() * 1e3 / n),
            "env_per_robot_ms": float(env_s.mean() * 1e3 / n), "realtime_factor": float((1.0 / hz) / total.mean()),
            "control_hz": hz}


def bench_fleet(sizes: tuple[int, ...] = SIZES, steps: int = 480, warmup: int = 48, seed: int = 0,
                controllers: tuple[str, ...] = CONTROLLERS) -> dict[str, Any]:
    """Time ``steps`` control steps at each fleet size with each controller (see the module docstring)."""
    rows = [time_fleet(name, n, steps, warmup, seed) for name in controllers for n in sizes]
    for name in controllers:
        mine = [r for r in rows if r["controller"] == name]
        base = next((r for r in mine if r["robots"] == 1), None)
        for row in mine:
            row["per_robot_ratio"] = row["per_robot_ms"] / base["per_robot_ms"] if base else None
            row["env_per_robot_ratio"] = row["env_per_robot_ms"] / base["env_per_robot_ms"] if base else None
    return {"benchmark": "fleet_scaling", "controllers": list(controllers),
            "world": "WarehouseAisles-v0 settings, static", "seed": seed, "steps": steps, "warmup": warmup,
            "sizes": rows}


__all__ = ["SIZES", "bench_fleet", "time_fleet"]
