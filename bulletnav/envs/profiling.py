"""Where an env step's time goes, timed part by part on one env (``bulletnav bench env
--physics kinematic`` prints it beside the steps/s): the env's own module, since it reaches
into the scene it times."""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym


def step_parts(env_id: str, physics: str, steps: int = 6000, seed: int = 0) -> dict[str, Any]:
    """Where a step of ``env_id`` (``gym.make``, default wrappers, ``physics``) goes, in
    microseconds per step over ``steps`` steps of uniform random actions with resets: the
    resets, the simulation's step (drive and contacts), the lidar's cast of its rays, and the
    rest (task, reward, observation, ``info``, the sensors' noise and reading, Gymnasium's
    wrappers); the four add up to the step, a reset's own scan counted as the lidar's. The two
    inner calls are timed by wrapping them on this one env's instances, so their figures carry
    the timer's own small cost (the total is timed the same way). The lidar
    part is the kinematic profile's closed-form cast; under PyBullet it reads 0 and the rays are
    in ``rest``."""
    import bulletnav  # noqa: F401  (registers the env)

    env = gym.make(env_id, physics=physics)
    spent = {"sim": 0.0, "lidar": 0.0}
    try:
        env.action_space.seed(seed)
        env.reset(seed=seed)
        actions = [env.action_space.sample() for _ in range(steps)]
        scene = env.unwrapped._scene  # this module is the env's own: it times the scene's parts

        def timed(obj: Any, name: str, key: str) -> None:
            inner = getattr(obj, name)

            def wrapper(*args: Any, **kwargs: Any) -> Any:
                t = time.perf_counter()
                try:
                    return inner(*args, **kwargs)
                finally:
                    spent[key] += time.perf_counter() - t
            setattr(obj, name, wrapper)

        timed(scene.sim, "step", "sim")
        timed(scene.sensors.lidar, "_shape_fractions", "lidar")
        resets_s, resets = 0.0, 0
        t0 = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                t, cast = time.perf_counter(), spent["lidar"]
                env.reset()
                # the reset's own scan is the lidar's part, not the reset's: each second in one part only
                resets_s += time.perf_counter() - t - (spent["lidar"] - cast)
                resets += 1
        total = time.perf_counter() - t0
    finally:
        env.close()
    us = 1e6 / steps
    return {
        "steps": steps, "episodes": resets, "us_per_step": round(total * us, 1), "resets_us": round(resets_s * us, 1),
        "sim_us": round(spent["sim"] * us, 1), "lidar_us": round(spent["lidar"] * us, 1),
        "rest_us": round((total - resets_s - spent["sim"] - spent["lidar"]) * us, 1),
        "note": "per step, averaged over all steps, each second in one part: resets (the reset calls but their "
                "scan), sim (the simulation's step: drive and contacts), lidar (the cast of the lidar's rays, in the "
                "steps and resets), rest (task, reward, observation, info, sensor noise and reading, Gymnasium's "
                "wrappers)",
    }
