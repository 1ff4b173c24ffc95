"""The safety shield's decision time per control step, against the env step it guards.

A driver that pushes forward (full speed on 80 % of steps, random yaw rates) runs behind
:class:`~bulletnav.control.shield.ShieldWrapper`'s veto in the chosen env (default
``WarehouseDynamic-v0``: lidar hits and movers to check), so the shield meets walls, racks and
movers often and replaces many commands. Each step's decision (read the scan, odometry and
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


def bench_shield(steps: int = 3000, seed: int = 0, env_id: str = DEFAULT_ENV,
                 config: ShieldConfig = ShieldConfig()) -> dict[str, Any]:
    """Time ``steps`` shield decisions and env steps (episodes reset with ``seed + k``)."""
    import bulletnav  # noqa: F401  (registers the envs)

    env = gym.make(env_id)
    try:
        veto = Veto(env, config)
        rng = np.random.default_rng(seed)
        low, high = env.action_space.low, env.action_space.high
        env.reset(seed=seed)
        episodes, collisions = 1, 0
        passed, vetoed, stepped = [], [], []
        for _ in range(10):  # untimed: first calls allocate
            veto(env.action_space.sample())
        for _ in range(steps):
            a = rng.uniform(low, high).astype(np.float32)
            if rng.random() < 0.8:
                a[0] = high[0]
            t0 = time.perf_counter()
            action, decision = veto(a)
            t1 = time.perf_counter()
            _, _, terminated, truncated, info = env.step(action)
            t2 = time.perf_counter()
            (vetoed if decision.intervened else passed).append((t1 - t0) * 1e3)
            stepped.append((t2 - t1) * 1e3)
            if terminated or truncated:
                collisions += bool(info.get("collision"))
                env.reset(seed=seed + episodes)
                episodes += 1
    finally:
        env.close()
    every = _stats(passed + vetoed)
    step = _stats(stepped)
    return {
        "benchmark": "shield", "env_id": env_id, "steps": steps, "seed": seed, "episodes": episodes,
        "collisions": collisions, "intervention_rate": len(vetoed) / steps,
        "decision_ms": every, "decision_passed_ms": _stats(passed), "decision_vetoed_ms": _stats(vetoed),
        "env_step_ms": step, "ratio_decision_to_env_step": every["mean"] / step["mean"],
        "target_ms": 1.0, "meets_target": every["mean"] < 1.0,
    }
