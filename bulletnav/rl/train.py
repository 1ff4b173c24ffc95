"""``bulletnav train``: Stable-Baselines3 on ``bulletnav/Warehouse-v0`` with periodic evaluation,
atomic checkpoints, resume, run metadata and a learning curve."""

from __future__ import annotations

import json
import logging
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav import ENV_ID
from bulletnav.errors import ConfigError, ModelError, RunError
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.provenance import git_commit, machine
from bulletnav.rl.common import (
    EVAL_SEED_BASE,
    SB3Policy,
    algo_class,
    atomic_save_model,
    atomic_save_vecnormalize,
    atomic_write_json,
    evaluation_env_kwargs,
    load_hyperparams,
    make_env_fn,
    sidecar_path,
    vecnormalize_path,
)

log = logging.getLogger(__name__)

_ENV_KEYS = {"policy", "n_envs", "env_kwargs", "collision_terminal", "normalize", "action_noise"}


@dataclass(frozen=True)
class TrainConfig:
    algo: str
    timesteps: int
    out: Path
    seed: int = 0
    n_envs: int | None = None
    """Parallel envs (SubprocVecEnv); None takes the hyperparameter file's value."""
    resume: bool = False
    eval_freq: int = 25_000
    """Evaluate every this many timesteps (summed over envs)."""
    eval_episodes: int = 20
    checkpoint_freq: int = 25_000
    progress_bar: bool = True
    vec_env: str = "subproc"
    """'subproc' (one process per env) or 'dummy' (all in this process)."""
    env_overrides: dict | None = None
    """Extra env keyword arguments on top of the hyperparameter file's."""
    hyperparams: Path | None = None
    """A hyperparameter YAML file to use instead of ``rl/hyperparams/<algo>.yml`` (same format)."""
    command: str = ""


def _make_vec_env(cfg: TrainConfig, hp: dict[str, Any], env_kwargs: dict[str, Any], n_envs: int):
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    fns = [make_env_fn(env_kwargs, bool(hp.get("collision_terminal", False))) for _ in range(n_envs)]
    venv = SubprocVecEnv(fns, start_method="forkserver") if cfg.vec_env == "subproc" and n_envs > 1 else DummyVecEnv(fns)
    venv.seed(cfg.seed)
    venv = VecMonitor(venv)
    return venv


def linear_schedule(initial: float):
    """RL Zoo's ``lin_<value>``: the value decays linearly from ``initial`` to 0 over training."""

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _model_kwargs(hp: dict[str, Any], n_actions: int) -> dict[str, Any]:
    import copy

    # a copy: SB3 adds entries to the dicts it is given (A2C puts its optimizer class into
    # policy_kwargs), which must not leak into the recorded hyperparameters
    kwargs = copy.deepcopy({k: v for k, v in hp.items() if k not in _ENV_KEYS})
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str) and value.startswith("lin_"):
            kwargs[key] = linear_schedule(float(value[4:]))
    policy_kwargs = kwargs.get("policy_kwargs") or {}
    for key in ("features_extractor_class", "activation_fn"):
        if isinstance(policy_kwargs.get(key), str):  # "package.module.Name" in the YAML file
            policy_kwargs[key] = _import_name(policy_kwargs[key])
    noise = hp.get("action_noise")
    if noise:
        from stable_baselines3.common.noise import NormalActionNoise

        kwargs["action_noise"] = NormalActionNoise(np.zeros(n_actions), float(noise["sigma"]) * np.ones(n_actions))
    return kwargs


def _import_name(dotted: str):
    """``"package.module.Name"`` -> the object, for classes named in hyperparameter files."""
    import importlib

    module, _, name = dotted.rpartition(".")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ConfigError(f"hyperparameters name {dotted!r}, which cannot be imported ({exc})") from exc


def _callback(cfg: TrainConfig, env_kwargs: dict[str, Any], history: list[dict[str, Any]], vecnorm_ref: list):
    from stable_baselines3.common.callbacks import BaseCallback

    class EvalAndCheckpoint(BaseCallback):
        """Every ``eval_freq`` steps: evaluate on unseen seeds and log; every
        ``checkpoint_freq`` steps: write ``checkpoints/last.zip`` atomically."""

        def __init__(self) -> None:
            super().__init__()
            self.next_eval = 0
            self.next_ckpt = 0
            self.eval_env = None

        def _on_training_start(self) -> None:
            self.next_eval = (self.num_timesteps // cfg.eval_freq + 1) * cfg.eval_freq
            self.next_ckpt = (self.num_timesteps // cfg.checkpoint_freq + 1) * cfg.checkpoint_freq

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_ckpt:
                self.next_ckpt += cfg.checkpoint_freq
                save_checkpoint(self.model, cfg.out, vecnorm_ref[0])
            if self.num_timesteps >= self.next_eval:
                self.next_eval += cfg.eval_freq
                self.evaluate()
            return True

        def evaluate(self) -> dict[str, Any]:
            if self.eval_env is None:
                import bulletnav  # noqa: F401

                self.eval_env = gym.make(ENV_ID, **evaluation_env_kwargs(env_kwargs))
            results = run_episodes(self.eval_env, SB3Policy(self.model, vecnorm_ref[0]), cfg.eval_episodes,
                                   EVAL_SEED_BASE)
            s = summarize(results)
            row = {"timesteps": int(self.num_timesteps), "wall_time": time.time() - t_start[0],
                   **{k: s[k] for k in ("success_rate", "collision_rate", "mean_reward", "std_reward",
                                        "mean_length", "spl")}}
            history.append(row)
            logger = getattr(self.model, "_logger", None)  # absent when no learn() ran
            if logger is not None:
                for k in ("success_rate", "collision_rate", "mean_reward", "mean_length", "spl"):
                    logger.record(f"eval/{k}", row[k])
                logger.dump(self.num_timesteps)
            atomic_write_json(cfg.out / "eval_history.json", history)
            log.info("eval at %d: success %.2f collisions %.2f reward %.1f", row["timesteps"],
                     row["success_rate"], row["collision_rate"], row["mean_reward"])
            return row

        def close(self) -> None:
            if self.eval_env is not None:
                self.eval_env.close()
                self.eval_env = None

    t_start = [time.time()]
    return EvalAndCheckpoint(), t_start


def save_checkpoint(model, out: Path, vecnorm) -> None:
    ckpt = out / "checkpoints" / "last.zip"
    atomic_save_model(model, ckpt)
    if vecnorm is not None:
        atomic_save_vecnormalize(vecnorm, vecnormalize_path(ckpt))
    atomic_write_json(out / "checkpoints" / "last.json", {"timesteps": int(model.num_timesteps)})


def train(cfg: TrainConfig) -> dict[str, Any]:
    """Train, evaluate and save; returns the run record (also written to ``out/run.json``)."""
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # 2 cores: more threads slow PPO down and starve the env workers
    hp = load_hyperparams(cfg.algo, path=cfg.hyperparams)
    env_kwargs = {**hp.get("env_kwargs", {}), **(cfg.env_overrides or {})}
    recorded = cfg.out / "config.json"
    if cfg.resume and recorded.is_file():  # a resumed run keeps the settings it started with
        original = json.loads(recorded.read_text())
        hp, env_kwargs = original["hyperparams"], original["env_kwargs"]
    n_envs = int(cfg.n_envs or hp.get("n_envs", 4))
    cfg.out.mkdir(parents=True, exist_ok=True)
    venv = _make_vec_env(cfg, hp, env_kwargs, n_envs)
    normalize = hp.get("normalize") or None
    cls = algo_class(cfg.algo)
    ckpt = cfg.out / "checkpoints" / "last.zip"
    history: list[dict[str, Any]] = []
    start_steps = 0
    if cfg.resume:
        if not ckpt.is_file():
            raise ModelError(f"{ckpt}: no checkpoint to resume from")
        if normalize:
            venv = VecNormalize.load(str(vecnormalize_path(ckpt)), venv)
        model = cls.load(ckpt, env=venv, device="cpu")
        start_steps = int(model.num_timesteps)
        hist_file = cfg.out / "eval_history.json"
        if hist_file.is_file():
            history = [row for row in json.loads(hist_file.read_text()) if row["timesteps"] <= start_steps]
    else:
        if normalize:
            venv = VecNormalize(venv, **normalize)
        model = cls(hp["policy"], venv, seed=cfg.seed, device="cpu", verbose=0,
                    tensorboard_log=str(cfg.out / "tb"), **_model_kwargs(hp, venv.action_space.shape[0]))
    vecnorm_ref = [venv if isinstance(venv, VecNormalize) else None]
    callback, t_start = _callback(cfg, env_kwargs, history, vecnorm_ref)
    record: dict[str, Any] = {
        "command": cfg.command, "algo": cfg.algo, "env_id": ENV_ID, "seed": cfg.seed, "timesteps": cfg.timesteps,
        "n_envs": n_envs, "vec_env": cfg.vec_env, "hyperparams": hp, "env_kwargs": env_kwargs,
        "git_commit": git_commit(), "machine": machine(), "torch_threads": torch.get_num_threads(),
        "resumed_from": start_steps or None,
        "versions": _versions(),
    }
    atomic_write_json(cfg.out / "config.json", record)
    t0 = time.time()
    remaining = max(cfg.timesteps - start_steps, 0)
    if remaining:
        model.learn(total_timesteps=remaining, callback=callback, progress_bar=cfg.progress_bar,
                    reset_num_timesteps=not cfg.resume, tb_log_name=cfg.algo)
    wall = time.time() - t0
    save_checkpoint(model, cfg.out, vecnorm_ref[0])
    final_path = cfg.out / "model.zip"
    atomic_save_model(model, final_path)
    if vecnorm_ref[0] is not None:
        atomic_save_vecnormalize(vecnorm_ref[0], vecnormalize_path(final_path))
    if not history or history[-1]["timesteps"] != model.num_timesteps:
        callback.model = model
        callback.num_timesteps = model.num_timesteps
        callback.evaluate()
    callback.close()
    venv.close()
    record.update(wall_time_s=round(wall, 1), total_timesteps=int(model.num_timesteps),
                  final_eval=history[-1] if history else None, eval_seeds=f"{EVAL_SEED_BASE}..")
    atomic_write_json(sidecar_path(final_path), {"algo": cfg.algo, "env_id": ENV_ID, "env_kwargs": env_kwargs,
                                                 "seed": cfg.seed, "timesteps": int(model.num_timesteps),
                                                 "git_commit": record["git_commit"], "command": cfg.command})
    atomic_write_json(cfg.out / "run.json", record)
    if history:
        plot_learning_curve(history, cfg.out / "learning_curve.png", title=f"{cfg.algo.upper()} seed {cfg.seed}")
    return record


def _versions() -> dict[str, str]:
    import gymnasium
    import pybullet  # noqa: F401
    import stable_baselines3
    import torch

    return {"python": platform.python_version(), "torch": torch.__version__, "stable_baselines3": stable_baselines3.__version__,
            "gymnasium": gymnasium.__version__, "numpy": np.__version__}


def plot_learning_curve(history: list[dict[str, Any]], path: Path, title: str = "") -> None:
    """Success rate and mean evaluation reward against timesteps, one PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [h["timesteps"] for h in history]
    fig, ax1 = plt.subplots(figsize=(7, 4), dpi=100)
    ax1.plot(steps, [h["success_rate"] for h in history], "o-", color="tab:green", label="success rate")
    ax1.plot(steps, [h["collision_rate"] for h in history], "s--", color="tab:red", label="collision rate")
    ax1.set_xlabel("timesteps")
    ax1.set_ylabel("rate")
    ax1.set_ylim(-0.02, 1.02)
    ax2 = ax1.twinx()
    ax2.plot(steps, [h["mean_reward"] for h in history], "^-", color="tab:blue", label="mean reward")
    ax2.set_ylabel("mean evaluation reward")
    lines = ax1.get_lines() + ax2.get_lines()
    ax1.legend(lines, [ln.get_label() for ln in lines], loc="lower right")
    ax1.grid(alpha=0.3)
    ax1.set_title(title)
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


REACH_SUCCESS = 0.8
"""Success rate whose first crossing ``compare`` reports as the sample-efficiency mark."""


def compare_runs(run_dirs: list[Path], out_png: Path) -> list[dict[str, Any]]:
    """Learning curves of several runs in one PNG (success rate against timesteps and
    against wall-clock time, mean reward against timesteps; one colour per algorithm, one
    line per seed) and one summary row per run: final and best evaluation, wall time, and
    when the in-training evaluation first reached :data:`REACH_SUCCESS`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = []
    fig, (ax1, ax3, ax2) = plt.subplots(1, 3, figsize=(15, 4), dpi=100)
    colours: dict[str, Any] = {}  # one colour per algorithm; its seeds share it
    for run in run_dirs:
        for name in ("eval_history.json", "run.json"):
            if not (run / name).is_file():
                raise RunError(f"{run}: not a finished training run (no {name})")
        history = json.loads((run / "eval_history.json").read_text())
        record = json.loads((run / "run.json").read_text())
        algo = record["algo"]
        first = algo not in colours
        colour = colours.setdefault(algo, f"C{len(colours) % 10}")
        label = algo.upper() if first else None
        steps = [h["timesteps"] for h in history]
        ax1.plot(steps, [h["success_rate"] for h in history], "o-", color=colour, alpha=0.8, ms=3, label=label)
        ax2.plot(steps, [h["mean_reward"] for h in history], "o-", color=colour, alpha=0.8, ms=3, label=label)
        ax3.plot([h["wall_time"] / 60 for h in history], [h["success_rate"] for h in history], "o-", color=colour,
                 alpha=0.8, ms=3, label=label)
        final = history[-1]
        best = max(history, key=lambda h: h["success_rate"])
        reached = next((h for h in history if h["success_rate"] >= REACH_SUCCESS), None)
        rows.append({"run": str(run), "algo": record["algo"], "seed": record["seed"],
                     "timesteps": record["total_timesteps"],
                     # a resumed run's record times only its last part; the history's clock runs from the start
                     "wall_time_s": max([record["wall_time_s"], *(h.get("wall_time", 0.0) for h in history)]),
                     "final_success": final["success_rate"], "final_collisions": final["collision_rate"],
                     "final_reward": round(final["mean_reward"], 2), "best_success": best["success_rate"],
                     "best_at": best["timesteps"],
                     "reached_at": reached["timesteps"] if reached else None,
                     "reached_wall_s": round(reached["wall_time"]) if reached else None})
    for ax, name in ((ax1, "success rate (20 unseen episodes)"), (ax2, "mean evaluation reward")):
        ax.set_xlabel("timesteps")
        ax.set_ylabel(name)
    ax3.set_xlabel("wall-clock time (min)")
    ax3.set_ylabel("success rate (20 unseen episodes)")
    for ax in (ax1, ax2, ax3):
        ax.grid(alpha=0.3)
    for ax in (ax1, ax3):
        ax.set_ylim(-0.02, 1.02)
    ax1.legend(loc="upper left")
    fig.tight_layout()
    out_png.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_png.with_name(f".{out_png.name}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, out_png)
    return rows
