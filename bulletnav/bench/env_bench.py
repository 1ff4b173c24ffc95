"""Env throughput against a raw PyBullet loop doing the same physics and sensor queries.

The raw loop is what a minimal hand-written PyBullet env has to ask PyBullet for to produce
the same observation and episode end, with no Python around it: the wheel motor command,
``substeps`` physics steps, the lidar's ray batch, the robot's base pose and velocity (IMU,
heading, distance), the wheel joint states (odometry) and its contact points (collision
check). The headline ``ratio`` is env steps/s over raw steps/s, so ``1 - ratio`` is the share
of a step the env's own Python costs. ``ratio_physics_and_rays`` keeps the earlier, stricter
reference (motors, physics and rays only: no state queries) for comparison.

All loops live in one process, in the same warehouse, fed the same random actions. They
run in alternating blocks of ``block`` steps, so that the machine's speed drifting over
the run (these machines are noisy) hits them alike; ratios are medians over blocks of
(raw time / env time), robust to bursts of load from other processes. Episode resets of
the env are mirrored in the raw loops (teleporting their robot to the same start) and are
left out of all step timings (their mean is reported apart).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

from bulletnav.config import EnvConfig
from bulletnav.sim.client import connect
from bulletnav.sim.robot import Robot
from bulletnav.sim.world import STATIC_GROUP, World


class _RawLoop:
    """The env's physics work written directly against PyBullet: motors, substeps, one ray batch."""

    def __init__(self, cfg: EnvConfig, layout, start) -> None:
        self.cid = cid = connect()
        World(cid, cfg.physics).build(layout)
        self.robot = robot = Robot(cid, cfg.robot)
        robot.load(start)
        self.joints = [robot.left_joint, robot.right_joint]
        self.torque = [cfg.robot.max_wheel_torque] * 2
        self.half, self.r = robot.wheelbase / 2, robot.wheel_radius
        lidar = cfg.sensors.lidar
        angles = np.arange(lidar.num_rays) * (2 * math.pi / lidar.num_rays)
        self.ray_from = [[0.0, 0.0, 0.0]] * lidar.num_rays
        self.ray_to = [[lidar.max_range * math.cos(a), lidar.max_range * math.sin(a), 0.0] for a in angles]
        self.substeps = cfg.physics.substeps

    def run(self, actions: np.ndarray, state_queries: bool = True) -> float:
        """Seconds for the steps of ``actions``; ``state_queries=False`` leaves out the robot
        state and contact queries (the physics-and-rays reference)."""
        cid, body, link = self.cid, self.robot.body, self.robot.lidar_link
        half, r, joints, torque, substeps = self.half, self.r, self.joints, self.torque, self.substeps
        step_sim, motors, rays = p.stepSimulation, p.setJointMotorControlArray, p.rayTestBatch
        pose, velocity, wheels, contacts = (p.getBasePositionAndOrientation, p.getBaseVelocity, p.getJointStates,
                                            p.getContactPoints)
        t0 = time.perf_counter()
        for v, w in actions.tolist():
            motors(body, joints, p.VELOCITY_CONTROL, targetVelocities=[(v - w * half) / r, (v + w * half) / r],
                   forces=torque, physicsClientId=cid)
            for _ in range(substeps):
                step_sim(physicsClientId=cid)
            if state_queries:
                pose(body, physicsClientId=cid)
                velocity(body, physicsClientId=cid)
                wheels(body, joints, physicsClientId=cid)
                contacts(bodyA=body, physicsClientId=cid)
            rays(self.ray_from, self.ray_to, parentObjectUniqueId=body, parentLinkIndex=link,
                 collisionFilterMask=STATIC_GROUP, physicsClientId=cid)
        return time.perf_counter() - t0

    def close(self) -> None:
        p.disconnect(physicsClientId=self.cid)


def bench_env(steps: int = 6000, block: int = 100, seed: int = 0, config: EnvConfig | None = None) -> dict[str, Any]:
    """Steps per second of ``bulletnav/Warehouse-v0`` (as made by ``gym.make``) and of the raw
    loop, with their ratio. Random uniform actions, headless, lidar-only observation."""
    import bulletnav  # noqa: F401  (registers the env)

    cfg = replace(config or EnvConfig(), layouts_every=10**9)  # one warehouse for the whole run
    env = gym.make("bulletnav/Warehouse-v0", config=cfg)
    env.reset(seed=seed)
    raw = _RawLoop(cfg, env.unwrapped.scene.layout, env.unwrapped.scene.start)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(env.action_space.low, env.action_space.high, size=(steps, 2)).astype(np.float32)
    env_time = raw_time = lean_time = reset_time = 0.0
    episodes = 0
    block_ratios, lean_ratios = [], []
    clock = time.perf_counter
    for b in range(0, steps, block):
        chunk = actions[b:b + block]
        chunk_start = env.unwrapped.scene.pose  # both raw replays start where the env's robot stands
        pending: list[tuple[int, tuple]] = []
        t_env = 0.0
        for i, a in enumerate(chunk):
            t0 = clock()
            _, _, terminated, truncated, _ = env.step(a)
            t_env += clock() - t0
            if terminated or truncated:
                t0 = clock()
                env.reset()
                reset_time += clock() - t0
                episodes += 1
                pending.append((i + 1, env.unwrapped.scene.start))
        # The raw loops replay the chunk, teleporting where the env reset (untimed).
        t_raw = t_lean = 0.0
        for queries in (True, False):
            start = 0
            raw.robot.reset_pose(chunk_start)
            for end, pose in [*pending, (len(chunk), None)]:
                t = raw.run(chunk[start:end], state_queries=queries)
                t_raw, t_lean = (t_raw + t, t_lean) if queries else (t_raw, t_lean + t)
                if pose is not None:
                    raw.robot.reset_pose(pose)
                start = end
        env_time += t_env
        raw_time += t_raw
        lean_time += t_lean
        block_ratios.append(t_raw / t_env)
        lean_ratios.append(t_lean / t_env)
    env.close()
    raw.close()
    return {
        "benchmark": "env",
        "steps": steps,
        "block": block,
        "env_steps_per_s": round(steps / env_time, 1),
        "raw_steps_per_s": round(steps / raw_time, 1),
        "ratio": round(float(np.median(block_ratios)), 4),
        "ratio_of_totals": round(raw_time / env_time, 4),
        "ratio_physics_and_rays": round(float(np.median(lean_ratios)), 4),
        "physics_and_rays_steps_per_s": round(steps / lean_time, 1),
        "env_overhead_us_per_step": round((env_time - raw_time) / steps * 1e6, 1),
        "episodes": episodes,
        "reset_ms_mean": round(reset_time / max(episodes, 1) * 1e3, 2),
        "physics_hz": cfg.physics.physics_hz,
        "control_hz": cfg.physics.control_hz,
        "solver_iterations": cfg.physics.solver_iterations,
        "lidar_rays": cfg.sensors.lidar.num_rays,
    }
