"""Envs for training and evaluation: one thunk per worker, and the evaluation settings."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym

from bulletnav import ENV_ID, limits

EVAL_SEED_BASE = 10_000_000
"""Evaluation during training uses seeds from here up: training only seeds its first resets
with ``seed + rank`` (small numbers), so these episodes are never trained on."""

EVALUATE_OBSTACLES = 31
"""``num_obstacles`` that evaluation (``evaluate``, ``demo``, a sweep's held-out score) uses on
``bulletnav/Warehouse-v0`` unless told otherwise, whatever the model was trained with (the
benchmark's warehouses)."""

TRAINING_ONLY_KWARGS = ("collision_terminates", "randomize", "physics")
"""Env options that shape learning, not the benchmark: evaluation leaves them out (a shift to
evaluate under is chosen with ``--perturb``, a physics profile with ``--physics``: a model trained
where stepping is cheap, ``physics="kinematic"`` or ``"fast"``, is scored in full physics unless
asked otherwise). Leaving ``collision_terminates`` out gives each id
its own registered rule, since ``gym.make(id, **kwargs)`` lays ``kwargs`` over the id's
registered ones: a collision truncates on ``Warehouse-v0`` and terminates on the aisle, dynamic
and mission ids, whatever the model trained with (``tests/test_episode_rules.py``)."""


def make_env_fn(env_kwargs: dict[str, Any], env_id: str = ENV_ID, shield: bool = False) -> Callable[[], gym.Env]:
    """A thunk building one training env (behind the safety shield with ``shield``); it pins
    torch to one thread in its process."""

    def _thunk() -> gym.Env:
        import torch

        import bulletnav  # noqa: F401  (registers the env in a fresh worker)

        torch.set_num_threads(1)
        return make_env(env_id, env_kwargs, shield)

    return _thunk


def make_env(env_id: str, env_kwargs: dict[str, Any], shield: bool = False, **make_kwargs: Any) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``, wrapped in a :class:`~bulletnav.control.shield.ShieldWrapper` with ``shield``.

    Raises:
        LimitError: a ``max_episode_steps`` (Gymnasium's ``TimeLimit``, which the env itself
            never sees) above the ``episode_steps`` limit of :mod:`bulletnav.limits`.
    """
    for source in (env_kwargs, make_kwargs):
        if source.get("max_episode_steps") is not None:
            limits.check("episode_steps", source["max_episode_steps"], "max_episode_steps")
    env = gym.make(env_id, **env_kwargs, **make_kwargs)
    if shield:
        from bulletnav.control.shield import ShieldWrapper

        env = ShieldWrapper(env)
    return env


def evaluation_env_kwargs(env_kwargs: dict[str, Any], keep: tuple[str, ...] = ()) -> dict[str, Any]:
    """The env settings a model is evaluated with: its training settings minus the reward
    overrides (``reward_*``) and the learning-only options (:data:`TRAINING_ONLY_KWARGS`), so
    every agent is scored on the env's own reward and episode rules; ``keep`` names options to
    keep all the same (the in-training evaluation keeps the training's ``physics``). Give them to ``gym.make``
    (or :func:`make_env`) with the id: the id's registered kwargs fill in what is left out.

    Whether a collision terminates or truncates changes no evaluation figure: the episode ends
    at that step either way, and :func:`bulletnav.evaluation.run_episodes` scores from ``info``."""
    return {k: v for k, v in env_kwargs.items()
            if k in keep or (not k.startswith("reward_") and k not in TRAINING_ONLY_KWARGS)}
