"""Training callbacks: evaluation on unseen episodes, and atomic checkpoints."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback

from bulletnav import ENV_ID
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.rl.envs import EVAL_SEED_BASE, evaluation_env_kwargs, make_env
from bulletnav.rl.io import atomic_save_model, atomic_save_vecnormalize, atomic_write_json, vecnormalize_path
from bulletnav.rl.policy import SB3Policy

log = logging.getLogger(__name__)

EVAL_KEYS = ("success_rate", "collision_rate", "mean_reward", "std_reward", "mean_length", "spl")
"""Summary entries each evaluation row keeps."""


def save_checkpoint(model: Any, out: Path, vecnorm: Any, extra: dict[str, Any] | None = None) -> None:
    """``out/checkpoints/last.zip`` (+ normalisation statistics, step count and ``extra``, such
    as the curriculum's state, in ``last.json``), atomically."""
    ckpt = out / "checkpoints" / "last.zip"
    atomic_save_model(model, ckpt)
    if vecnorm is not None:
        atomic_save_vecnormalize(vecnorm, vecnormalize_path(ckpt))
    atomic_write_json(out / "checkpoints" / "last.json", {"timesteps": int(model.num_timesteps), **(extra or {})})


def _vecnorm(model: Any) -> Any:
    from stable_baselines3.common.vec_env import VecNormalize

    env = model.get_env()
    return env if isinstance(env, VecNormalize) else None


class CheckpointCallback(BaseCallback):
    """Every ``every`` timesteps (summed over envs): :func:`save_checkpoint` into ``out``."""

    def __init__(self, out: Path, every: int, state: Callable[[], dict[str, Any]] | None = None) -> None:
        super().__init__()
        self.out = out
        self.every = every
        self.next_at = 0
        self.state = state
        """Extra state for ``last.json`` (the curriculum's), asked at each checkpoint."""

    def _on_training_start(self) -> None:
        self.next_at = (self.num_timesteps // self.every + 1) * self.every

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_at:
            self.next_at += self.every
            save_checkpoint(self.model, self.out, _vecnorm(self.model), self.state() if self.state else None)
        return True


class EvaluationCallback(BaseCallback):
    """Every ``every`` timesteps: run the model deterministically on ``episodes`` unseen
    episodes (seeds from :data:`~bulletnav.rl.envs.EVAL_SEED_BASE`) of the env with its
    evaluation settings; append a row to ``history``, log it to TensorBoard and write
    ``out/eval_history.json``.

    Args:
        out: run directory.
        every: timesteps between evaluations.
        episodes: episodes per evaluation.
        env_kwargs: the training env settings (evaluation drops the training-only ones).
        history: rows so far (a resumed run passes its earlier rows).
        env_id: the env to evaluate on.
        started: ``time.time()`` when the run (or its first part) began; rows record the
            wall time since.
        shield: evaluate behind the safety shield (a run trained with ``--shield``).
        on_row: called with each new row (a sweep reports it to Ray Tune).
    """

    def __init__(self, out: Path, every: int, episodes: int, env_kwargs: dict[str, Any],
                 history: list[dict[str, Any]], env_id: str = ENV_ID, started: float | None = None,
                 shield: bool = False, on_row: Callable[[dict[str, Any]], None] | None = None) -> None:
        super().__init__()
        self.on_row = on_row
        self.out = out
        self.every = every
        self.episodes = episodes
        self.env_kwargs = env_kwargs
        self.env_id = env_id
        self.shield = shield
        self.history = history
        self.started = time.time() if started is None else started
        self.next_at = 0
        self.eval_env: gym.Env | None = None

    def _on_training_start(self) -> None:
        self.next_at = (self.num_timesteps // self.every + 1) * self.every

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.next_at:
            self.next_at += self.every
            self.evaluate(self.model)
        return True

    def evaluate(self, model: Any) -> dict[str, Any]:
        """Evaluate ``model`` now and record the row (also callable after training)."""
        if self.eval_env is None:
            import bulletnav  # noqa: F401

            self.eval_env = make_env(self.env_id, evaluation_env_kwargs(self.env_kwargs), self.shield)
        results = run_episodes(self.eval_env, SB3Policy(model, _vecnorm(model)), self.episodes, EVAL_SEED_BASE)
        s = summarize(results)
        row = {"timesteps": int(model.num_timesteps), "wall_time": time.time() - self.started,
               **{k: s[k] for k in EVAL_KEYS}}
        self.history.append(row)
        try:
            logger = model.logger
        except AttributeError:  # no learn() ran yet: nothing to log to
            logger = None
        if logger is not None:
            for k in ("success_rate", "collision_rate", "mean_reward", "mean_length", "spl"):
                logger.record(f"eval/{k}", row[k])
            logger.dump(model.num_timesteps)
        atomic_write_json(self.out / "eval_history.json", self.history)
        log.info("eval at %d: success %.2f collisions %.2f reward %.1f", row["timesteps"],
                 row["success_rate"], row["collision_rate"], row["mean_reward"])
        if self.on_row is not None:
            self.on_row(dict(row))
        return row

    def close(self) -> None:
        if self.eval_env is not None:
            self.eval_env.close()
            self.eval_env = None
