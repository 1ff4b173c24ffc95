"""Score a saved model on seeded episodes: the library side of ``bulletnav evaluate``, used
where no report is printed (a sweep's held-out metric)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bulletnav import ENV_ID
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.rl.compat import check_model_fits
from bulletnav.rl.envs import EVALUATE_OBSTACLES, evaluation_env_kwargs, make_env
from bulletnav.rl.io import load_model
from bulletnav.rl.policy import SB3Policy


def evaluate_model(path: str | Path, env_id: str = ENV_ID, episodes: int = 200, seed: int = 1000,
                   env_overrides: dict[str, Any] | None = None, shield: bool = False,
                   algo: str | None = None) -> dict[str, Any]:
    """The summary (:func:`~bulletnav.evaluation.summarize`) of ``episodes`` deterministic
    episodes of the model at ``path``, episode ``k`` seeded ``seed + k``, on ``env_id`` with
    the model's evaluation settings (its training env options minus the learning-only ones;
    on ``Warehouse-v0`` the benchmark's 31 obstacles), as ``bulletnav evaluate`` scores it.

    Raises:
        ModelError: the model or its sidecar cannot be read.
    """
    import bulletnav  # noqa: F401  (registers the envs in a fresh worker)

    model, meta, vecnorm = load_model(path, algo=algo)
    env_kwargs = evaluation_env_kwargs(meta.get("env_kwargs", {}))
    if env_id == ENV_ID:
        env_kwargs["num_obstacles"] = EVALUATE_OBSTACLES
    env_kwargs.update(env_overrides or {})
    env = make_env(env_id, env_kwargs, shield)
    try:
        check_model_fits(model, env, path, env_id)
        results = run_episodes(env, SB3Policy(model, vecnorm), episodes, seed)
    finally:
        env.close()
    return summarize(results)
