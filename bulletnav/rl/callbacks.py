"""Training callbacks: evaluation on unseen episodes, and atomic checkpoints."""

from __future__ import annotations

import json
import logging
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnvWrapper

from bulletnav import ENV_ID
from bulletnav.errors import ModelError
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.files import move, write_json
from bulletnav.rl.envs import EVAL_SEED_BASE, evaluation_env_kwargs, make_env
from bulletnav.rl.io import atomic_save_model, atomic_save_vecnormalize
from bulletnav.rl.policy import SB3Policy
from bulletnav.rl.sidecar import vecnormalize_path

log = logging.getLogger(__name__)

EVAL_KEYS = ("success_rate", "collision_rate", "mean_reward", "std_reward", "mean_length", "spl")
"""Summary entries each evaluation row keeps."""


CHECKPOINT_NAMES = (vecnormalize_path("last.zip").name, "last.json", "last.zip")
"""The files of a checkpoint in ``out/checkpoints/``: one set, committed together."""

_PENDING, _COMMIT = ".pending", "COMMIT"


def save_checkpoint(model: Any, out: Path, vecnorm: Any, extra: dict[str, Any] | None = None) -> None:
    """``out/checkpoints/last.zip`` (+ normalisation statistics, step count and ``extra``, such
    as the curriculum's state, in ``last.json``), as one set.

    The three files must match (statistics of another step than the weights would skew every
    observation after a resume), and a run can be killed between any two writes. So the set is
    written whole into ``checkpoints/.pending/``, then a ``COMMIT`` file naming it is written
    (atomically: from here the new set counts), then the files are moved into place and the
    folder dropped. A run killed mid-way leaves either no ``COMMIT`` (the old set stands; the
    partial one is dropped) or a ``COMMIT`` that :func:`finish_checkpoint` completes before any
    resume reads the set.
    """
    folder = out / "checkpoints"
    pending = folder / _PENDING
    finish_checkpoint(out)
    pending.mkdir(parents=True, exist_ok=True)
    atomic_save_model(model, pending / "last.zip")
    names = ["last.json", "last.zip"]
    if vecnorm is not None:
        stats = vecnormalize_path(pending / "last.zip")
        atomic_save_vecnormalize(vecnorm, stats)
        names.insert(0, stats.name)
    write_json(pending / "last.json", {"timesteps": int(model.num_timesteps), **(extra or {})})
    write_json(pending / _COMMIT, {"files": names, "timesteps": int(model.num_timesteps)})
    finish_checkpoint(out, interrupted=False)


def finish_checkpoint(out: Path, interrupted: bool = True) -> bool:
    """Complete a checkpoint whose writing was interrupted (see :func:`save_checkpoint`): a
    committed set is moved into place (files of the older set it does not name are removed), an
    uncommitted one is dropped. Safe to repeat; returns whether a committed set was completed.
    ``interrupted`` off: :func:`save_checkpoint` completing its own set (no warning)."""
    folder = out / "checkpoints"
    pending = folder / _PENDING
    if not pending.is_dir():
        return False
    commit = pending / _COMMIT
    done = commit.is_file()
    if done:
        try:
            names = json.loads(commit.read_text())["files"]
            if not isinstance(names, list) or not set(names) <= set(CHECKPOINT_NAMES):
                raise ValueError(f"files must name checkpoint files among {CHECKPOINT_NAMES}")
        except (ValueError, KeyError, TypeError) as exc:
            raise ModelError(f"{commit}: not a checkpoint commit record ({exc})") from None
        for name in names:
            if (pending / name).is_file():
                move(pending / name, folder / name)
        for name in set(CHECKPOINT_NAMES) - set(names):
            (folder / name).unlink(missing_ok=True)
        commit.unlink()
        if interrupted:
            log.warning("%s: completed a checkpoint whose writing was interrupted", folder)
    shutil.rmtree(pending, ignore_errors=True)
    return done


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
        stop_at_success: stop training at the first evaluation whose success rate reaches this
            (``train --stop-at-success``); the model is then also evaluated before its first
            update, so a start that already succeeds (a fine-tuned one) stops at 0 steps.
    """

    def __init__(self, out: Path, every: int, episodes: int, env_kwargs: dict[str, Any],
                 history: list[dict[str, Any]], env_id: str = ENV_ID, started: float | None = None,
                 shield: bool = False, on_row: Callable[[dict[str, Any]], None] | None = None,
                 stop_at_success: float | None = None) -> None:
        super().__init__()
        self.stop_at_success = stop_at_success
        self.reached: dict[str, Any] | None = None
        """The first row that reached ``stop_at_success``, once one has."""
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
        self.seconds = 0.0
        """Wall time spent evaluating (s), for the run's time budget."""

    def _on_training_start(self) -> None:
        self.next_at = (self.num_timesteps // self.every + 1) * self.every
        if self.stop_at_success is not None and self.num_timesteps == 0:
            self._check(self.evaluate(self.model))

    def _on_step(self) -> bool:
        if self.reached is not None:
            return False
        if self.num_timesteps >= self.next_at:
            self.next_at += self.every
            self._check(self.evaluate(self.model))
        return self.reached is None

    def _check(self, row: dict[str, Any]) -> None:
        if self.stop_at_success is not None and self.reached is None and row["success_rate"] >= self.stop_at_success:
            self.reached = dict(row)
            log.info("success %.2f reached the target %.2f at %d steps, %.0f s: training stops",
                     row["success_rate"], self.stop_at_success, row["timesteps"], row["wall_time"])

    def evaluate(self, model: Any) -> dict[str, Any]:
        """Evaluate ``model`` now and record the row (also callable after training)."""
        t0 = time.perf_counter()
        try:
            return self._evaluate(model)
        finally:
            self.seconds += time.perf_counter() - t0

    def _evaluate(self, model: Any) -> dict[str, Any]:
        if self.eval_env is None:
            import bulletnav  # noqa: F401

            # in the training's own physics profile: cheap where training is (final scores: ``evaluate``, full physics)
            self.eval_env = make_env(self.env_id, evaluation_env_kwargs(self.env_kwargs, keep=("physics",)), self.shield)
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
        write_json(self.out / "eval_history.json", self.history)
        log.info("eval at %d: success %.2f collisions %.2f reward %.1f", row["timesteps"],
                 row["success_rate"], row["collision_rate"], row["mean_reward"])
        if self.on_row is not None:
            self.on_row(dict(row))
        return row

    def close(self) -> None:
        if self.eval_env is not None:
            self.eval_env.close()
            self.eval_env = None


class ThroughputCallback(BaseCallback):
    """Where a run's time goes: at every rollout's end, logs to SB3's logger (TensorBoard, beside
    SB3's own ``time/fps``) ``time/env_steps_per_s`` (env steps per second of wall time),
    ``time/env_share`` (share of wall time inside the vector env's ``reset``/``step``, i.e. the
    simulation: :class:`TimedVecEnv`), ``time/eval_share`` (in-training
    evaluations) and ``time/learner_share`` (the rest: policy inference and gradient updates).

    Args:
        timer: the :class:`TimedVecEnv` under the run's vector env.
        evaluation: the run's evaluation callback (its ``seconds``), or None.
    """

    def __init__(self, timer: Any, evaluation: EvaluationCallback | None = None) -> None:
        super().__init__()
        self.timer = timer
        self.evaluation = evaluation
        self._t0 = 0.0
        self._steps0 = 0

    def _on_training_start(self) -> None:
        self._t0 = time.perf_counter()
        self._steps0 = self.num_timesteps
        self.timer.seconds = 0.0
        if self.evaluation is not None:
            self.evaluation.seconds = 0.0

    def _on_step(self) -> bool:
        return True

    def summary(self) -> dict[str, float]:
        """Env steps per second and the shares of the wall time since learning started
        (``seconds``: that time)."""
        wall = max(time.perf_counter() - self._t0, 1e-9)
        env = self.timer.seconds
        evaluation = self.evaluation.seconds if self.evaluation is not None else 0.0
        return {"env_steps_per_s": round((self.num_timesteps - self._steps0) / wall, 1), "seconds": round(wall, 2),
                "env_share": round(env / wall, 4), "eval_share": round(evaluation / wall, 4),
                "learner_share": round(max(wall - env - evaluation, 0.0) / wall, 4)}

    def _on_rollout_end(self) -> None:
        for key, value in self.summary().items():
            if key != "seconds":
                self.logger.record(f"time/{key}", value)


class TimedVecEnv(VecEnvWrapper):
    """A transparent vector-env wrapper that adds up the wall time spent in ``reset`` and
    ``step`` (for subprocess envs: waiting for the workers) in :attr:`seconds`."""

    def __init__(self, venv: Any) -> None:
        super().__init__(venv)
        self.seconds = 0.0

    def _timed(self, call: Callable[..., Any], *args: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return call(*args)
        finally:
            self.seconds += time.perf_counter() - t0

    def reset(self):
        return self._timed(self.venv.reset)

    def step_async(self, actions) -> None:
        self._timed(self.venv.step_async, actions)

    def step_wait(self):
        return self._timed(self.venv.step_wait)
