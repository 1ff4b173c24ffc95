"""Solver settings: what each costs per physics step and what it does to driving accuracy.

For every candidate :class:`PhysicsConfig` this measures, in the same run:
- the mean time of one physics step in a 31-obstacle warehouse with the robot driving
  (best of ``repeats``, alternating settings so machine drift hits all alike);
- the driving checks of the robot tests: distance and sideways drift after 3 s at
  0.4 m/s, and the yaw rate commanded at 1.0 rad/s.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pybullet as p

from bulletnav.config import PhysicsConfig, SamplerConfig
from bulletnav.geometry import robot_geometry
from bulletnav.sim.layout import Layout, generate_warehouse
from bulletnav.sim.sampler import FreeSpace, sample_start_goal
from bulletnav.sim.simulation import Simulation

CANDIDATES: dict[str, PhysicsConfig] = {
    "pybullet default (50 iterations)": PhysicsConfig(solver_iterations=50),
    "20 iterations": PhysicsConfig(solver_iterations=20),
    "10 iterations": PhysicsConfig(solver_iterations=10),
    "5 iterations": PhysicsConfig(solver_iterations=5),
    "3 iterations": PhysicsConfig(solver_iterations=3),
    "10 iterations, residual 1e-4": PhysicsConfig(solver_iterations=10, solver_residual_threshold=1e-4),
    "10 iterations, pyramid friction": PhysicsConfig(solver_iterations=10, cone_friction=False),
}


def _step_time(physics: PhysicsConfig, layout: Layout, start, steps: int) -> float:
    sim = Simulation(physics=physics)
    try:
        sim.reset(layout, start)
        sim.robot.set_velocity(0.05, 1.0)  # tight circle: moving, in contact with the floor only
        cid = sim.cid
        for _ in range(50):
            p.stepSimulation(physicsClientId=cid)
        t0 = time.perf_counter()
        for _ in range(steps):
            p.stepSimulation(physicsClientId=cid)
        return (time.perf_counter() - t0) / steps
    finally:
        sim.close()


def _driving(physics: PhysicsConfig) -> dict[str, float]:
    sim = Simulation(physics=physics)
    flat = Layout((30.0, 30.0))
    try:
        out: dict[str, float] = {}
        drifts, dists = [], []
        for yaw in (0.0, 1.0, 2.0):
            sim.reset(flat, (0.0, 0.0, yaw))
            for _ in range(3 * physics.control_hz):
                sim.step(0.4, 0.0)
            x, y, _ = sim.robot.planar_pose()
            dists.append(x * math.cos(yaw) + y * math.sin(yaw))
            drifts.append(abs(-x * math.sin(yaw) + y * math.cos(yaw)))
        out["straight_3s_distance_m"] = round(float(np.mean(dists)), 4)
        out["straight_distance_error_pct"] = round(abs(np.mean(dists) - 1.2) / 1.2 * 100, 2)
        out["max_sideways_drift_mm"] = round(max(drifts) * 1000, 2)
        sim.reset(flat, (0.0, 0.0, 0.0))
        for _ in range(physics.control_hz // 2):
            sim.step(0.0, 1.0)
        yaws = []
        for _ in range(2 * physics.control_hz):
            sim.step(0.0, 1.0)
            yaws.append(sim.robot.planar_pose()[2])
        rate = (np.unwrap(yaws)[-1] - yaws[0]) / ((len(yaws) - 1) / physics.control_hz)
        out["yaw_rate_error_pct"] = round(abs(rate - 1.0) * 100, 2)
        return out
    finally:
        sim.close()


def bench_physics(steps: int = 3000, repeats: int = 3, seed: int = 0) -> dict[str, Any]:
    """Per-step cost and driving accuracy for each candidate solver setting."""
    layout = generate_warehouse(np.random.default_rng(seed))
    free = FreeSpace.build(layout, SamplerConfig(), robot_geometry().radius)
    start, _ = sample_start_goal(free, np.random.default_rng(seed), SamplerConfig())
    best = {name: math.inf for name in CANDIDATES}
    for _ in range(repeats):
        for name, physics in CANDIDATES.items():
            best[name] = min(best[name], _step_time(physics, layout, start, steps))
    reference = best["pybullet default (50 iterations)"]
    rows = []
    for name, physics in CANDIDATES.items():
        rows.append({
            "setting": name,
            "solver_iterations": physics.solver_iterations,
            "solver_residual_threshold": physics.solver_residual_threshold,
            "cone_friction": physics.cone_friction,
            "us_per_physics_step": round(best[name] * 1e6, 1),
            "speed_vs_pybullet_default": round(reference / best[name], 3),
            **_driving(physics),
        })
    return {"benchmark": "physics", "steps": steps, "repeats": repeats, "default": PhysicsConfig().solver_iterations,
            "settings": rows}
