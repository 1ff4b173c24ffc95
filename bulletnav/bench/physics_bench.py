"""Physics settings: what each costs and what it does to driving, contacts and the policy.

Two tables. :func:`bench_physics` (solver settings): for every candidate
:class:`PhysicsConfig`, in the same run,
- the mean time of one physics step in a 31-obstacle warehouse with the robot driving
  (best of ``repeats``, alternating settings so machine drift hits all alike);
- the driving checks of the robot tests: distance and sideways drift after 3 s at
  0.4 m/s, and the yaw rate commanded at 1.0 rad/s.

:func:`bench_rates` (physics rates at 24 Hz control), each through a real
``gym.make("bulletnav/Warehouse-v0", physics_hz=...)``:
- the wall time of one env step under fixed seeded random actions (rates alternated in
  blocks, resets not timed);
- straight, turn-in-place and arc manoeuvres from rest, compared with the same commands at
  the reference rate (240 Hz): final distance, heading change, end point, in percent;
- tunnelling: full speed (0.5 m/s) into a 2 cm static plate: whether the env reports the
  collision, how deep the robot is in, and whether it gets through while pushing on;
- wheel slip: encoder distance against the true path over an acceleration and two turns;
- a trained policy (the shipped ``Warehouse-v0`` PPO) on the same seeded episodes.
"""

from __future__ import annotations

import logging
import math
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p
import yaml

from bulletnav.config import PhysicsConfig, SamplerConfig
from bulletnav.geometry import robot_geometry
from bulletnav.sim.layout import Layout, generate_warehouse
from bulletnav.sim.sampler import FreeSpace, sample_start_goal
from bulletnav.sim.simulation import Simulation

log = logging.getLogger(__name__)

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


# ---------------------------------------------------------------------------------------
# Physics rates at the env's control rate

RATES: tuple[int, ...] = (240, 120, 96, 48)
"""Physics rates (Hz) the rate table compares; the first is the reference."""

RATE_CONTROL_HZ = 24
"""Control rate (Hz) of every row of the rate table (the env's default)."""

POLICY_MODEL = "models/ppo_warehouse.zip"
"""The policy the rate table evaluates at each rate (the shipped ``Warehouse-v0`` PPO)."""

POLICY_SEED = 1_000_000
"""First episode seed of the policy check (the model card's 200 episodes: seeds 1,000,000 on)."""

QUALIFY = {"driving_error_pct": 1.0, "success_points": 2.0, "collision_points": 2.0}
"""A rate qualifies as a fast profile when every driving error (straight, turn, arc) against
the reference rate is at most 1 %, the policy's success rate is at most 2 points below the
reference's, its collision rate at most 2 points above, and the plate collision registers."""

PLATE_THICKNESS = 0.02
"""Thickness of the tunnelling test's plate (m)."""

_TEST_WORLD = {
    # an open 12 x 12 m room with one 2 cm plate across x = 2 m (tunnelling); the driving
    # manoeuvres run in the other half
    "name": "physics bench",
    "size": [12.0, 12.0],
    "obstacles": [{"type": "box", "center": [2.0, 0.0], "size": [PLATE_THICKNESS, 3.0, 1.0], "yaw": 0.0,
                   "label": "plate"}],
}
_PLATE_FACE = 2.0 - PLATE_THICKNESS / 2  # x of the plate's near face (m)
_FAR_GOAL = (5.0, 5.0)  # never reached by the manoeuvres (goal radius 0.5 m)

_MANOEUVRES: dict[str, list[tuple[float, float, float]]] = {
    # name -> [(v m/s, w rad/s, seconds)], each from rest at (-4, -4, 0)
    "straight": [(0.4, 0.0, 3.0)],
    "turn": [(0.0, 1.0, 3.0)],
    "arc": [(0.3, 0.8, 4.0)],
    "slip": [(0.5, 0.0, 1.5), (0.5, 1.5, 2.0), (0.2, -1.5, 1.0), (0.0, 0.0, 1.0)],
}


def _make(physics_hz: int, **kwargs: Any):
    import gymnasium as gym

    import bulletnav  # noqa: F401  (registers the env)

    return gym.make("bulletnav/Warehouse-v0", physics_hz=physics_hz, control_hz=RATE_CONTROL_HZ, **kwargs)


def _step_cost(rates: Sequence[int], steps: int, block: int, seed: int) -> dict[int, dict[str, float]]:
    """Wall time of ``env.step`` at each rate: the same seeded random actions for all, rates
    alternated block by block (the starting rate rotating), resets done but not timed."""
    envs = {hz: _make(hz) for hz in rates}
    try:
        space = envs[rates[0]].action_space
        actions = np.random.default_rng(seed).uniform(space.low, space.high, (steps, 2)).astype(np.float32)
        for env in envs.values():
            env.reset(seed=seed)
        spent = dict.fromkeys(rates, 0.0)
        blocks: dict[int, list[float]] = {hz: [] for hz in rates}
        done = dict.fromkeys(rates, 0)
        perf = time.perf_counter
        for k in range(max(steps // block, 1)):
            order = [*rates[k % len(rates):], *rates[:k % len(rates)]]
            for hz in order:
                env, t_block = envs[hz], 0.0
                for i in range(done[hz], min(done[hz] + block, steps)):
                    t0 = perf()
                    _, _, terminated, truncated, _ = env.step(actions[i])
                    t_block += perf() - t0
                    if terminated or truncated:
                        env.reset()
                n = min(block, steps - done[hz])
                done[hz] += n
                spent[hz] += t_block
                blocks[hz].append(t_block / max(n, 1))
        ref = rates[0]
        out = {}
        for hz in rates:
            out[hz] = {
                "ms_per_env_step": round(spent[hz] / done[hz] * 1e3, 4),
                "speedup_vs_reference": round(spent[ref] / done[ref] / (spent[hz] / done[hz]), 3),
                # the same ratio block by block (paired, so machine drift cancels), median
                "speedup_median_of_blocks": round(float(np.median(np.array(blocks[ref]) / np.array(blocks[hz]))), 3),
                "steps_timed": done[hz],
            }
        return out
    finally:
        for env in envs.values():
            env.close()


def _manoeuvre(env, commands: list[tuple[float, float, float]], start: tuple[float, float, float]) -> dict[str, float]:
    """Drive ``commands`` from rest at ``start``; pose and heading change (unwrapped) at the end,
    the true path length and the wheel encoders' path length."""
    _, info = env.reset(seed=0, options={"start": start, "goal": _FAR_GOAL})
    scene = env.unwrapped.scene
    yaws = [scene.pose[2]]
    for v, w, seconds in commands:
        for _ in range(round(seconds * RATE_CONTROL_HZ)):
            _, _, terminated, truncated, info = env.step(np.array([v, w], dtype=np.float32))
            if terminated or truncated:
                raise RuntimeError(f"manoeuvre {commands} ended early ({info.get('end_reason')})")
            yaws.append(scene.pose[2])
    x, y, _ = scene.pose
    odometry = scene.sensors.odometry
    return {"x": x, "y": y, "heading_change": float(np.unwrap(yaws)[-1] - yaws[0]),
            "path_length": float(info["path_length"]),
            "encoder_distance": float(odometry.distance) if odometry is not None else math.nan}


def _rate_driving(physics_hz: int, world: str) -> dict[str, dict[str, float]]:
    env = _make(physics_hz, world=world)
    try:
        return {name: _manoeuvre(env, commands, (-4.0, -4.0, 0.0)) for name, commands in _MANOEUVRES.items()}
    finally:
        env.close()


def _tunnelling(physics_hz: int, world: str, push_s: float = 1.0) -> dict[str, Any]:
    """Full speed from 1.5 m before the plate straight into it; then keep pushing ``push_s``."""
    env = _make(physics_hz, world=world)
    try:
        env.reset(seed=0, options={"start": (0.5, 0.0, 0.0), "goal": _FAR_GOAL})
        base = env.unwrapped  # stepping on past the collision's truncation: the env itself, no wrappers
        scene = base.scene
        front = scene.geometry.nose
        rear = min(r.cx - r.half_x for r in scene.geometry.rectangles)
        full = np.array([base.action_space.high[0], 0.0], dtype=np.float32)
        dt = scene.control_dt
        first: int | None = None
        speed_before = 0.0
        prev_x = scene.pose[0]
        depth_at_report = max_depth = 0.0
        steps = 0
        while steps < round(6.0 / dt) and (first is None or steps < first + round(push_s / dt)):
            _, _, _, _, info = base.step(full)
            steps += 1
            x = scene.pose[0]
            depth = _contact_depth(scene)
            max_depth = max(max_depth, depth, x + front - _PLATE_FACE)
            if first is None:
                if info["collision"]:
                    first = steps
                    depth_at_report = max(depth, x + front - _PLATE_FACE)
                else:
                    speed_before = (x - prev_x) / dt
            prev_x = x
        x = scene.pose[0]
        return {
            "collision_registered": first is not None,
            "first_report_s": None if first is None else round(first * dt, 4),
            "impact_speed_m_s": round(speed_before, 4),
            "penetration_at_report_mm": round(depth_at_report * 1000, 2),
            "max_penetration_pushing_mm": round(max_depth * 1000, 2),
            "passed_through": bool(x + rear > _PLATE_FACE + PLATE_THICKNESS),
            "front_beyond_far_face_mm": round(max(0.0, x + front - _PLATE_FACE - PLATE_THICKNESS) * 1000, 2),
        }
    finally:
        env.close()


def _contact_depth(scene) -> float:
    """Deepest penetration (m, >= 0) of the robot into anything it touches sideways (contact
    normals within 60 degrees of horizontal: walls and the plate, not the floor)."""
    depth = 0.0
    for c in p.getContactPoints(bodyA=scene.robot_body, physicsClientId=scene.client):
        if abs(c[7][2]) < 0.5:
            depth = max(depth, -c[8])
    return depth


def _policy(physics_hz: int, model_path: str, episodes: int, seed: int) -> dict[str, Any]:
    """The model's deterministic actions on ``episodes`` seeded episodes at ``physics_hz``, with
    the env settings ``bulletnav evaluate`` uses (31 obstacles)."""
    from bulletnav.evaluation import run_episodes, summarize
    from bulletnav.rl.envs import EVALUATE_OBSTACLES, evaluation_env_kwargs
    from bulletnav.rl.io import load_model
    from bulletnav.rl.policy import SB3Policy

    path = Path(model_path)
    if not path.is_file() and not path.is_absolute():  # the shipped model, from outside the checkout
        packaged = Path(__file__).resolve().parents[2] / path
        path = packaged if packaged.is_file() else path
    model, meta, vecnorm = load_model(path)
    kwargs = {**evaluation_env_kwargs(meta.get("env_kwargs", {})), "num_obstacles": EVALUATE_OBSTACLES}
    kwargs.pop("physics_hz", None)
    kwargs.pop("physics", None)
    env = _make(physics_hz, **kwargs)
    try:
        t0 = time.perf_counter()
        results = run_episodes(env, SB3Policy(model, vecnorm), episodes, seed)
        wall = time.perf_counter() - t0
    finally:
        env.close()
    s = summarize(results)
    outcomes = ["success" if r.success else ("collision" if r.collision else "timeout") for r in results]
    return {"episodes": episodes, "seed": seed, "success_rate": s["success_rate"], "collision_rate": s["collision_rate"],
            "timeout_rate": s["timeout_rate"], "spl": round(s["spl"], 4), "mean_length": round(s["mean_length"], 2),
            "wall_time_s": round(wall, 1), "outcomes": outcomes}


def bench_rates(rates: Sequence[int] = RATES, steps: int = 6000, block: int = 250, seed: int = 0,
                model: str | None = POLICY_MODEL, policy_episodes: int = 200,
                policy_seed: int = POLICY_SEED) -> dict[str, Any]:
    """The rate table: cost, driving, tunnelling, slip and the policy at each physics rate.

    Args:
        rates: physics rates (Hz), each a multiple of 24; the first is the reference the
            errors and speed-ups are measured against.
        steps: env steps timed per rate; ``block``: steps per timing block.
        seed: seed of the random actions and the timing episodes.
        model: the policy to evaluate at each rate (None or ``policy_episodes=0``: skip).
        policy_episodes, policy_seed: episode ``k`` is ``reset(seed=policy_seed + k)``.

    Raises:
        ValueError: no rates, a rate twice, or a rate that 24 Hz control does not divide.
    """
    rates = tuple(int(r) for r in rates)
    if not rates or len(set(rates)) != len(rates):
        raise ValueError(f"rates must be distinct physics rates (Hz), got {list(rates)}")
    for hz in rates:
        PhysicsConfig(physics_hz=hz, control_hz=RATE_CONTROL_HZ)  # raises for a rate 24 Hz does not divide
    ref = rates[0]
    with tempfile.TemporaryDirectory(prefix="bulletnav-physics-") as tmp:
        world = str(Path(tmp) / "plate.yaml")
        Path(world).write_text(yaml.safe_dump(_TEST_WORLD))
        cost = _step_cost(rates, steps, block, seed)
        driving = {hz: _rate_driving(hz, world) for hz in rates}
        tunnel = {hz: _tunnelling(hz, world) for hz in rates}
    policy = {}
    if model and policy_episodes > 0:
        for hz in rates:
            log.info("policy %s at %d Hz: %d episodes", model, hz, policy_episodes)
            policy[hz] = _policy(hz, model, policy_episodes, policy_seed)
    rows = []
    for hz in rates:
        d, r = driving[hz], driving[ref]
        slip = d["slip"]
        row: dict[str, Any] = {
            "physics_hz": hz, "control_hz": RATE_CONTROL_HZ, "substeps": hz // RATE_CONTROL_HZ,
            **cost[hz],
            "straight_3s_distance_m": round(d["straight"]["x"] + 4.0, 5),
            "straight_error_pct": round(abs(d["straight"]["x"] - r["straight"]["x"]) / abs(r["straight"]["x"] + 4.0) * 100, 3),
            "turn_3s_heading_rad": round(d["turn"]["heading_change"], 5),
            "turn_error_pct": round(abs(d["turn"]["heading_change"] - r["turn"]["heading_change"])
                                    / abs(r["turn"]["heading_change"]) * 100, 3),
            "arc_heading_error_pct": round(abs(d["arc"]["heading_change"] - r["arc"]["heading_change"])
                                           / abs(r["arc"]["heading_change"]) * 100, 3),
            "arc_endpoint_error_pct": round(math.hypot(d["arc"]["x"] - r["arc"]["x"], d["arc"]["y"] - r["arc"]["y"])
                                            / r["arc"]["path_length"] * 100, 3),
            "slip_true_path_m": round(slip["path_length"], 4),
            "slip_encoder_path_m": round(slip["encoder_distance"], 4),
            "wheel_slip_pct": round((slip["encoder_distance"] - slip["path_length"]) / slip["path_length"] * 100, 3),
            "tunnelling": tunnel[hz],
        }
        row["driving_error_pct"] = max(row["straight_error_pct"], row["turn_error_pct"], row["arc_heading_error_pct"],
                                       row["arc_endpoint_error_pct"])
        if hz in policy:
            pol, pref = policy[hz], policy[ref]
            row["policy"] = pol
            row["success_points_vs_reference"] = round((pol["success_rate"] - pref["success_rate"]) * 100, 2)
            row["collision_points_vs_reference"] = round((pol["collision_rate"] - pref["collision_rate"]) * 100, 2)
            row["episodes_changed_vs_reference"] = sum(a != b for a, b in zip(pol["outcomes"], pref["outcomes"]))
        row["qualifies"] = _qualifies(row) if hz != ref else None
        rows.append(row)
    fast = [row["physics_hz"] for row in rows if row["qualifies"]]
    return {
        "benchmark": "physics_rates", "reference_hz": ref, "control_hz": RATE_CONTROL_HZ, "steps": steps,
        "block": block, "seed": seed, "policy_model": model if policy else None,
        "policy_episodes": policy_episodes if policy else 0, "policy_seed": policy_seed,
        "criteria": dict(QUALIFY), "rows": rows,
        "qualifying_hz": fast, "fastest_qualifying_hz": min(fast) if fast else None,
    }


def _qualifies(row: dict[str, Any]) -> bool | None:
    """Whether a row meets :data:`QUALIFY` (None without the policy check)."""
    if "policy" not in row:
        return None
    return bool(row["driving_error_pct"] <= QUALIFY["driving_error_pct"]
                and row["success_points_vs_reference"] >= -QUALIFY["success_points"]
                and row["collision_points_vs_reference"] <= QUALIFY["collision_points"]
                and row["tunnelling"]["collision_registered"])
