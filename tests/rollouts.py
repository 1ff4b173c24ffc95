"""A saved model's evaluation episodes stepped by a loop written here, the independent re-score of
test_rl's and test_sweep's recorded evaluations: none of evaluate_model, run_episodes or summarize."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym

from bulletnav import ENV_ID
from bulletnav.rl.envs import EVALUATE_OBSTACLES, evaluation_env_kwargs
from bulletnav.rl.io import load_model


def episode_rows(model_path: str | Path, episodes: int, seed: int, env_id: str | None = None) -> list[dict]:
    """Episode k reset with ``seed + k``, the model's deterministic action on its observation
    (normalised when the model's statistics say so), until the env ends it; a row per episode
    with its seed, success, collision, reward sum and steps. ``env_id`` defaults to the model's."""
    model, meta, normalizer = load_model(model_path)
    env_id = env_id or meta["env_id"]
    kwargs = evaluation_env_kwargs(meta["env_kwargs"])
    if env_id == ENV_ID:
        kwargs["num_obstacles"] = EVALUATE_OBSTACLES  # the benchmark's warehouses, as `bulletnav evaluate` scores
    env = gym.make(env_id, **kwargs)
    rows = []
    try:
        for k in range(episodes):
            obs, info = env.reset(seed=seed + k)
            total, steps, done = 0.0, 0, False
            while not done:
                if normalizer is not None and normalizer.norm_obs:  # reward-only statistics leave obs alone
                    obs = normalizer.normalize_obs(obs)
                obs, reward, terminated, truncated, info = env.step(model.predict(obs, deterministic=True)[0])
                total, steps, done = total + reward, steps + 1, terminated or truncated
            rows.append({"seed": seed + k, "success": bool(info["is_success"]), "collision": bool(info["collision"]),
                         "reward": total, "steps": steps})
    finally:
        env.close()
    return rows
