"""The safety shield's decision time per control step, against the env step it guards.

A driver runs behind :class:`~bulletnav.control.shield.Veto` in the chosen env (default
``WarehouseDynamic-v0``: lidar hits and movers to check): ``ram`` pushes forward (full speed
on 80 % of steps, random yaw rates), so the shield meets walls, racks and movers often,
replaces most commands and is stuck much of the time; ``navigator`` is PID + A*, a
controller that mostly drives where it is safe; ``policy`` is a trained model (``model``),
which among movers gets the shield stuck beside movers that wait for the robot, its slowest
path (every fallback checked, then the creep's no-closer test; timed apart as
``decision_creep_ms``). Each step's decision (read the scan, odometry and
movers, sweep, pick) and each ``env.step`` are timed apart with ``perf_counter``; the ratio
decision / env step is the machine-independent figure, the milliseconds the absolute one
(target: under 1 ms per step on average; the p99 and the maximum are reported beside it).
"""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.control.shield import ShieldConfig, Veto

DEFAULT_ENV = "bulletnav/WarehouseDynamic-v0"


def _stats(ms: list[float]) -> dict[str, float]:
    a = np.asarray(ms, dtype=np.float64)
    if not a.size:
        return {"n": 0, "mean": float("nan"), "median": float("nan"), "p99": float("nan"), "max": float("nan")}
    return {"n": int(a.size), "mean": float(a.mean()), "median": float(np.median(a)),
            "p99": float(np.percentile(a, 99)), "max": float(a.max())}


def bench_shield(steps: int = 3000, seed: int = 0, env_id: str = DEFAULT_ENV, driver: str = "ram",
                 config: ShieldConfig = ShieldConfig(), model: str | None = None) -> dict[str, Any]:
    """Time ``steps`` shield decisions and env steps (episodes reset with ``seed + k``);
    ``model`` (a trained model's path) drives with ``driver="policy"``."""
    import bulletnav  # noqa: F401  (registers the envs)
    from bulletnav.control.navigator import Navigator

    if driver not in ("ram", "navigator", "policy"):
        raise ValueError(f"bench shield driver must be 'ram', 'navigator' or 'policy', got {driver!r}")
    if (driver == "policy") != (model is not None):
        raise ValueError("bench shield: --model goes with --driver policy, and --driver policy needs --model")
    kwargs: dict[str, Any] = {}
    nav: Any = None
    if model is not None:
        from bulletnav.rl.envs import evaluation_env_kwargs
        from bulletnav.rl.io import load_model
        from bulletnav.rl.policy import SB3Policy

        loaded, meta, vecnorm = load_model(model)
        kwargs = evaluation_env_kwargs(meta.get("env_kwargs", {}))
        nav = SB3Policy(loaded, vecnorm)
    env = gym.make(env_id, **kwargs)
    try:
        veto = Veto(env, config)
        rng = np.random.default_rng(seed)
        low, high = env.action_space.low, env.action_space.high
        if driver == "navigator":
            nav = Navigator(env.unwrapped.scene)
        obs, info = env.reset(seed=seed)
        if nav is not None:
            nav.reset(info)
        episodes, collisions = 1, 0
        passed, vetoed, crept, stepped = [], [], [], []
        for _ in range(10):  # untimed: first calls allocate
            veto(env.action_space.sample())
        for _ in range(steps):
            if nav is not None:
                a = nav.act(obs, info)
            else:
                a = rng.uniform(low, high).astype(np.float32)
                if rng.random() < 0.8:
                    a[0] = high[0]
            t0 = time.perf_counter()
            action, decision = veto(a)
            t1 = time.perf_counter()
            obs, _, terminated, truncated, info = env.step(action)
            t2 = time.perf_counter()
            (vetoed if decision.intervened else passed).append((t1 - t0) * 1e3)
            if decision.creep:
                crept.append((t1 - t0) * 1e3)
            stepped.append((t2 - t1) * 1e3)
            if terminated or truncated:
                collisions += bool(info.get("collision"))
                obs, info = env.reset(seed=seed + episodes)
                if nav is not None:
                    nav.reset(info)
                episodes += 1
    finally:
        env.close()
    every = _stats(passed + vetoed)
    step = _stats(stepped)
    return {
        "benchmark": "shield", "env_id": env_id, "driver": driver, "steps": steps, "seed": seed, "episodes": episodes,
        "collisions": collisions, "intervention_rate": len(vetoed) / steps,
        "decision_ms": every, "decision_passed_ms": _stats(passed), "decision_vetoed_ms": _stats(vetoed),
        "decision_creep_ms": _stats(crept), "model": model,
        "env_step_ms": step, "ratio_decision_to_env_step": every["mean"] / step["mean"],
        "target_ms": 1.0, "meets_target": every["mean"] < 1.0,
    }
