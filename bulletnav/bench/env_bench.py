"""Env throughput against a raw PyBullet loop doing the same physics and sensor queries.

The raw loop is what a minimal hand-written PyBullet env has to ask PyBullet for to produce
the same observation and episode end, with no Python around it: the wheel motor command,
``substeps`` physics steps, the lidar's ray batch, the robot's base pose and velocity (IMU,
heading, distance), the wheel joint states (odometry) and its contact points (collision
check). The headline ``ratio`` is env steps/s over raw steps/s, so ``1 - ratio`` is the share
of a step the env's own Python costs. ``ratio_physics_and_rays`` keeps the earlier, stricter
reference (motors, physics and rays only: no state queries) for comparison.

Same physics, exactly: the raw loops run in the env's own physics client on the env's own
robot. Before each block of ``block`` env steps the bench saves PyBullet's state
(``saveState``, also at each episode reset inside the block); after it, it restores the
block's first state and the raw loops replay the env's commands from there, restoring the
saved state at each reset, so they step the very same bodies through the very same contacts
(``replay_exact`` is the fraction of blocks whose replay ended at the env's pose to the bit).
Finally the state the env left is restored, and the env goes on as if nothing happened.
Alternating blocks make the machine's speed drifting over the run (these machines are
noisy) hit both loops alike; ratios are medians over blocks of (raw time / env time),
robust to bursts of load from other processes. Resets and state restores are not timed
(the env's mean reset time is reported apart).
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
from bulletnav.sensors.lidar import ray_angles
from bulletnav.sim.world import STATIC_GROUP


class _RawLoop:
    """The env's PyBullet work per step written directly against PyBullet, on the env's robot."""

    def __init__(self, cfg: EnvConfig, cid: int, body: int, half_wheelbase: float, wheel_radius: float) -> None:
        self.cid, self.body = cid, body
        joints, links = {}, {}
        for j in range(p.getNumJoints(body, physicsClientId=cid)):
            info = p.getJointInfo(body, j, physicsClientId=cid)
            joints[info[1].decode()], links[info[12].decode()] = j, j
        self.joints = [joints["left_wheel_joint"], joints["right_wheel_joint"]]
        self.link = links["lidar_link"]
        self.torque = [cfg.robot.max_wheel_torque] * 2
        self.half, self.r = half_wheelbase, wheel_radius
        lidar = cfg.sensors.lidar
        angles = ray_angles(lidar.num_rays, lidar.fov)
        self.ray_from = [[0.0, 0.0, 0.0]] * lidar.num_rays
        self.ray_to = [[lidar.max_range * math.cos(a), lidar.max_range * math.sin(a), 0.0] for a in angles]
        self.substeps = cfg.physics.substeps

    def run(self, commands: list[tuple[float, float]], state_queries: bool = True) -> float:
        """Seconds for the steps of ``commands`` ((v, w) pairs); ``state_queries=False`` leaves
        out the robot state and contact queries (the physics-and-rays reference)."""
        cid, body, link = self.cid, self.body, self.link
        half, r, joints, torque, substeps = self.half, self.r, self.joints, self.torque, self.substeps
        step_sim, motors, rays = p.stepSimulation, p.setJointMotorControlArray, p.rayTestBatch
        pose, velocity, wheels, contacts = (p.getBasePositionAndOrientation, p.getBaseVelocity, p.getJointStates,
                                            p.getContactPoints)
        t0 = time.perf_counter()
        for v, w in commands:
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

    def base_pose(self) -> tuple[float, ...]:
        return p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)[0]


RATIO_GUARD = 0.85
"""Regression guard on the env/raw step ratio: a benchmark result below it (``ratio_ok`` false)
means the env's own Python per step has grown. A guard in the benchmark's JSON, never a test:
timings are too noisy on shared machines to fail a build on."""

STATIC_REFERENCE = {"bulletnav/WarehouseDynamic-v0": "bulletnav/WarehouseAisles-v0"}
"""Env ids benchmarked against another id rather than the raw loop: the same worlds without movers."""


def bench_env(steps: int = 6000, block: int = 100, seed: int = 0, config: EnvConfig | None = None,
              env_id: str = "bulletnav/Warehouse-v0") -> dict[str, Any]:
    """Steps per second of ``env_id`` (as made by ``gym.make``) and of the raw loop, with
    their ratio. Random uniform actions, headless, lidar-only observation. An id with a
    static reference (:data:`STATIC_REFERENCE`) is timed against that id instead
    (:func:`bench_env_pair`)."""
    import bulletnav  # noqa: F401  (registers the env)

    if env_id in STATIC_REFERENCE:
        return bench_env_pair(env_id, STATIC_REFERENCE[env_id], steps=steps, block=block, seed=seed)
    if env_id != "bulletnav/Warehouse-v0":
        raise ValueError(f"bench env knows bulletnav/Warehouse-v0 and {sorted(STATIC_REFERENCE)}, got {env_id!r}")

    cfg = replace(config or EnvConfig(), layouts_every=10**9)  # one warehouse for the whole run
    env = gym.make("bulletnav/Warehouse-v0", config=cfg)
    env.reset(seed=seed)
    scene = env.unwrapped.scene
    cid = scene.client
    raw = _RawLoop(cfg, cid, scene.robot_body, scene.geometry.wheelbase / 2, scene.geometry.wheel_radius)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(env.action_space.low, env.action_space.high, size=(steps, 2)).astype(np.float32)
    commands = [env.unwrapped.command(a) for a in actions]  # what the env sends to the motors
    env_time = raw_time = lean_time = reset_time = 0.0
    episodes = exact = 0
    block_ratios, lean_ratios = [], []
    for b in range(0, steps, block):
        chunk = actions[b:b + block]
        t_env, t_reset, segments = _time_env_block(env, chunk, cid)
        reset_time += t_reset
        episodes += len(segments) - 1
        t_raw, t_lean, replayed = _time_raw_block(raw, commands[b:b + block], segments, cid)
        exact += replayed
        env_time += t_env
        raw_time += t_raw
        lean_time += t_lean
        block_ratios.append(t_raw / t_env)
        lean_ratios.append(t_lean / t_env)
    env.close()
    blocks = len(block_ratios)
    return {
        "benchmark": "env",
        "steps": steps,
        "block": block,
        "env_steps_per_s": round(steps / env_time, 1),
        "raw_steps_per_s": round(steps / raw_time, 1),
        "ratio": round(float(np.median(block_ratios)), 4),
        "ratio_guard": RATIO_GUARD,
        "ratio_ok": bool(np.median(block_ratios) >= RATIO_GUARD),
        "ratio_of_totals": round(raw_time / env_time, 4),
        "ratio_physics_and_rays": round(float(np.median(lean_ratios)), 4),
        "physics_and_rays_steps_per_s": round(steps / lean_time, 1),
        "env_overhead_us_per_step": round((env_time - raw_time) / steps * 1e6, 1),
        "replay_exact": round(exact / blocks, 4),
        "episodes": episodes,
        "reset_ms_mean": round(reset_time / max(episodes, 1) * 1e3, 2),
        "physics_hz": cfg.physics.physics_hz,
        "control_hz": cfg.physics.control_hz,
        "solver_iterations": cfg.physics.solver_iterations,
        "lidar_rays": cfg.sensors.lidar.num_rays,
    }


def _time_env_block(env: gym.Env, chunk: np.ndarray, cid: int) -> tuple[float, float, list[tuple[int, int]]]:
    """Step ``env`` through the actions of ``chunk``, timed per segment between resets (as the
    raw loop is), with the simulation state saved before each segment. Returns (seconds
    stepping, seconds in ``reset()``, the segments' (first step, saved state))."""
    clock, save = time.perf_counter, p.saveState
    segments = [(0, save(physicsClientId=cid))]  # (first step, state before it)
    t_env = reset_time = 0.0
    t0 = clock()
    for i, a in enumerate(chunk):
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            t1 = clock()
            t_env += t1 - t0
            env.reset()
            reset_time += clock() - t1
            segments.append((i + 1, save(physicsClientId=cid)))
            t0 = clock()
    t_env += clock() - t0
    return t_env, reset_time, segments


def _time_raw_block(raw: _RawLoop, commands: list[tuple[float, float]], segments: list[tuple[int, int]],
                    cid: int) -> tuple[float, float, bool]:
    """Replay ``commands`` on the raw loop from each segment's saved state, with and without the
    state queries, then restore where the env ended and drop the saved states. Returns (seconds
    with queries, seconds without, whether the lean replay ended where the env did)."""
    restore, remove = p.restoreState, p.removeState
    env_end = raw.base_pose()
    after = p.saveState(physicsClientId=cid)
    bounds = [s for s, _ in segments[1:]] + [len(commands)]
    t_raw = t_lean = 0.0
    exact = False
    for queries in (True, False):
        for (first, state), last in zip(segments, bounds):
            restore(state, physicsClientId=cid)
            t = raw.run(commands[first:last], state_queries=queries)
            t_raw, t_lean = (t_raw + t, t_lean) if queries else (t_raw, t_lean + t)
        exact = queries is False and raw.base_pose() == env_end
    restore(after, physicsClientId=cid)
    for state in [after, *(s for _, s in segments)]:
        remove(state, physicsClientId=cid)
    return t_raw, t_lean, exact



def step_with_resets(env: gym.Env, actions: np.ndarray) -> tuple[float, float, int]:
    """Step ``env`` through ``actions``, resetting at every episode end as training does.
    Returns (wall seconds in all, seconds of that inside ``reset()``, episodes ended)."""
    clock = time.perf_counter
    in_reset = 0.0
    episodes = 0
    t0 = clock()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            t1 = clock()
            env.reset()
            in_reset += clock() - t1
            episodes += 1
    return clock() - t0, in_reset, episodes


def bench_env_pair(env_id: str, reference_id: str, steps: int = 6000, block: int = 100, seed: int = 0) -> dict[str, Any]:
    """Step cost of ``env_id`` as a ratio to ``reference_id``'s, timed in the same run.

    Both envs keep one seeded world for the whole run (``layouts_every`` very large), get the
    same random actions in alternating blocks of ``block`` steps, and are timed per segment
    between resets (resets are timed apart). ``cost_ratio`` is the median over blocks of
    (env time / reference time): 1.3 means a step costs 30 % more than the static one.
    """
    import bulletnav  # noqa: F401
    from bulletnav import BARN_ENV_ID

    def make(name: str) -> gym.Env:  # BARN-v0 keeps one world anyway: world 0, as docs/barn-and-maps.md measured it
        return gym.make(name, world_idx=0) if name == BARN_ENV_ID else gym.make(name, layouts_every=10**9)

    envs = {name: make(name) for name in (env_id, reference_id)}
    for env in envs.values():
        env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    space = envs[env_id].action_space
    actions = rng.uniform(space.low, space.high, size=(steps, 2)).astype(np.float32)
    times = {name: 0.0 for name in envs}
    resets = {name: [0, 0.0] for name in envs}
    ratios = []
    for b in range(0, steps, block):
        chunk = actions[b:b + block]
        block_time = {}
        for name, env in envs.items():
            wall, in_reset, episodes = step_with_resets(env, chunk)
            resets[name][0] += episodes
            resets[name][1] += in_reset
            t_env = wall - in_reset
            block_time[name] = t_env
            times[name] += t_env
        ratios.append(block_time[env_id] / block_time[reference_id])
    movers = len(envs[env_id].unwrapped.scene.movers)
    for env in envs.values():
        env.close()
    return {
        "benchmark": "env_pair",
        "env_id": env_id,
        "reference_id": reference_id,
        "steps": steps,
        "block": block,
        "env_steps_per_s": round(steps / times[env_id], 1),
        "reference_steps_per_s": round(steps / times[reference_id], 1),
        "cost_ratio": round(float(np.median(ratios)), 4),
        "cost_ratio_of_totals": round(times[env_id] / times[reference_id], 4),
        "movers_at_end": movers,
        "episodes": resets[env_id][0],
        "reset_ms_mean": round(resets[env_id][1] / max(resets[env_id][0], 1) * 1e3, 2),
        "reference_reset_ms_mean": round(resets[reference_id][1] / max(resets[reference_id][0], 1) * 1e3, 2),
    }


def bench_profile(physics: str, env_id: str = "bulletnav/Warehouse-v0", steps: int = 6000, block: int = 500,
                  seed: int = 0, reference: str = "default", parts: bool = False) -> dict[str, Any]:
    """Steps per second of ``env_id`` made by ``gym.make`` (its default wrappers and kwargs: a new
    world at every reset where the id draws one) with ``physics=physics``, beside the same id with
    ``physics=reference`` in the same run. Uniform random actions from a seeded action space,
    drawn before each block is timed (as the other modes draw theirs: the sampler's cost is not
    the env's); episodes end by the env's own rules and the reset that follows is timed with the
    steps. The two envs run alternating blocks of ``block`` steps, so load from other processes
    hits both alike; ``ratio`` is the median over block pairs of (profile steps/s / reference
    steps/s). ``parts`` adds :func:`~bulletnav.envs.profiling.step_parts` of the profile's env, measured
    in a run of its own after the timed blocks.
    """
    import bulletnav  # noqa: F401  (registers the env)

    envs = {name: gym.make(env_id, physics=name) for name in (physics, reference)}
    timing: dict[str, list[float]] = {name: [] for name in envs}
    episodes = dict.fromkeys(envs, 0)
    try:
        for env in envs.values():
            env.action_space.seed(seed)
            env.reset(seed=seed)
        rounds = max(1, steps // block)
        for _ in range(rounds):
            for name, env in envs.items():
                step, reset = env.step, env.reset
                actions = [env.action_space.sample() for _ in range(block)]
                t0 = time.perf_counter()
                for action in actions:
                    _, _, terminated, truncated, _ = step(action)
                    if terminated or truncated:
                        reset()
                        episodes[name] += 1
                timing[name].append(time.perf_counter() - t0)
    finally:
        for env in envs.values():
            env.close()
    rates = {name: [block / t for t in ts] for name, ts in timing.items()}
    ratios = [a / b for a, b in zip(rates[physics], rates[reference])]
    from bulletnav.envs.profiling import step_parts

    extra = {"parts": step_parts(env_id, physics, steps=rounds * block, seed=seed)} if parts else {}
    return {
        "benchmark": "env_profile", "env_id": env_id, "physics": physics, "reference": reference,
        "steps": rounds * block, "block": block, "seed": seed,
        "steps_per_s": float(np.median(rates[physics])), "reference_steps_per_s": float(np.median(rates[reference])),
        "episodes": episodes[physics], "reference_episodes": episodes[reference],
        "ratio": float(np.median(ratios)),
        "note": "resets included; uniform random actions (drawn before each block's timing); episodes ended by the "
                "env's own rules; medians over blocks",
        **extra,
    }
