"""``bulletnav fleet-train``: parameter-shared PPO fine-tuning of a single-robot model in the fleet.

Every robot of every fleet is one slot of a :class:`~bulletnav.fleet.vec.FleetVecEnv`; one
policy (the model's weights, shared) acts for all and learns from all their transitions.

- Start: the weights of ``init_from`` (read through the safe format,
  :func:`bulletnav.rl.io.load_model`: nothing is unpickled) and its reward-normalisation
  statistics; hyperparameters from a ``bulletnav train`` hyperparameter file (default
  ``rl/hyperparams/ppo_dynamic_finetune_movers.yml``, the shipped dynamic model's last stage).
- Env: the fleet made with the model's env settings (:func:`~bulletnav.fleet.controllers.model_env_kwargs`,
  so observations mean what they meant in training) plus the file's reward weights
  (``reward_*``: the collision price, -40 per counted collision, robot-robot included). The
  fleet's collision rule applies: a collision stops the robot for ``collision_penalty_s``;
  nothing terminates; all robots truncate together after ``duration_s``.
- Files (``out/``): ``checkpoints/last.zip`` (+ ``last_vecnormalize.json``, ``last.json``)
  every ``checkpoint_freq`` steps, atomically; ``model.zip`` and its safe files
  (``model.safetensors``, sidecar ``model.json``, ``model_vecnormalize.json``); ``config.json``
  (the settings, kept by ``resume``); ``episodes.json`` (per fleet episode: errands, legs,
  collisions by kind, reward); ``run.json`` (command, seed, commit, machine, versions, wall
  time, throughput).

Steps are agent steps (one robot, one control period), as SB3 counts them over the slots.
"""

from __future__ import annotations

import json
import logging
import platform
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from bulletnav.errors import ConfigError, ModelError
from bulletnav.provenance import git_commit, machine

log = logging.getLogger(__name__)

HYPERPARAMS_ENV_ID = "bulletnav/WarehouseDynamic-v0"
"""The entry of the hyperparameter file a fleet run takes (its algorithm settings and reward weights)."""
FLEET_ENV_ID = "bulletnav/fleet_v0"
"""What the run record names as the env trained on."""


def default_hyperparams() -> Path:
    """``rl/hyperparams/ppo_dynamic_finetune_movers.yml``: the shipped dynamic model's last fine-tuning stage."""
    return Path(str(resources.files("bulletnav").joinpath("rl", "hyperparams", "ppo_dynamic_finetune_movers.yml")))


@dataclass(frozen=True)
class FleetTrainConfig:
    """One fleet fine-tuning run."""

    init_from: Path
    """The single-robot model to start from (weights, normalisation statistics, env settings)."""
    out: Path
    """Run directory."""
    timesteps: int
    """Total agent steps (summed over every robot of every fleet)."""
    seed: int = 0
    """Seeds PPO and the fleets' first resets (fleet ``k``: ``seed + k``)."""
    num_robots: int = 4
    """Robots per fleet."""
    dynamic: bool = False
    """Forklifts, workers and pallet events (``WarehouseDynamic-v0``'s) on the floor."""
    fleets: int = 1
    """Fleets stepped one after the other in this process (each robot one slot)."""
    duration_s: float = 60.0
    """Seconds of simulated time per training episode (then every robot truncates)."""
    hyperparams: Path | None = None
    """Hyperparameter YAML (``bulletnav train``'s format); None: :func:`default_hyperparams`."""
    env_overrides: dict[str, Any] | None = None
    """Fleet env keyword arguments on top (e.g. ``{"reward_collision": -60.0}``)."""
    resume: bool = False
    """Continue from ``out/checkpoints/last.zip`` with the settings in ``out/config.json``."""
    checkpoint_freq: int = 20_000
    """Agent steps between checkpoints."""
    command: str = ""
    """The command line, for the run record."""
    progress_bar: bool = False
    """SB3's progress bar."""

    def __post_init__(self) -> None:
        for name in ("timesteps", "num_robots", "fleets", "checkpoint_freq"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"fleet training: {name} must be a whole number >= 1, got {value!r}")
        if not self.duration_s > 0:
            raise ConfigError(f"fleet training: duration_s must be positive, got {self.duration_s!r}")


def fleet_env_kwargs(init_from: Path, hp: dict[str, Any], cfg: FleetTrainConfig) -> dict[str, Any]:
    """The fleet env settings of a run: the model's (:func:`~bulletnav.fleet.controllers.model_env_kwargs`),
    the hyperparameter file's reward weights, the fleet's own, then ``cfg.env_overrides``."""
    from bulletnav.fleet.controllers import model_env_kwargs

    rewards = {k: v for k, v in (hp.get("env_kwargs") or {}).items() if k.startswith("reward_")}
    return {**model_env_kwargs(init_from), **rewards, "num_robots": cfg.num_robots, "dynamic": cfg.dynamic,
            "duration_s": cfg.duration_s, **(cfg.env_overrides or {})}


def make_fleet_vec_env(env_kwargs: dict[str, Any], fleets: int, seed: int):
    """A seeded :class:`~bulletnav.fleet.vec.FleetVecEnv` of ``fleets`` fleets made with ``env_kwargs``."""
    from bulletnav.fleet import fleet_v0
    from bulletnav.fleet.vec import FleetVecEnv

    venv = FleetVecEnv([lambda: fleet_v0.parallel_env(**env_kwargs) for _ in range(fleets)])
    venv.seed(seed)
    return venv


class FleetEpisodeCallback(BaseCallback):
    """Records each finished fleet episode (summed over its robots: errands, legs, collisions
    by kind, reward) into ``history`` and ``out/episodes.json``."""

    KEYS = ("errands_completed", "legs_completed", "collisions_static", "collisions_mover", "collisions_person",
            "collisions_robot")

    def __init__(self, out: Path, slots: list[tuple[int, str]], history: list[dict[str, Any]]) -> None:
        super().__init__()
        self.out = out
        self.slots = slots
        self.history = history
        self.returns = np.zeros(len(slots))

    def _on_step(self) -> bool:
        from bulletnav.files import write_json

        self.returns += np.asarray(self.locals["rewards"], dtype=np.float64)
        dones, infos = self.locals["dones"], self.locals["infos"]
        if not np.any(dones):
            return True
        for k in sorted({self.slots[i][0] for i in np.flatnonzero(dones)}):
            idx = [i for i, (f, _) in enumerate(self.slots) if f == k]
            row: dict[str, Any] = {"timesteps": int(self.num_timesteps), "fleet": k}
            for key in self.KEYS:
                row[key] = int(sum(infos[i].get(key, 0) for i in idx))
            row["reward_per_robot"] = round(float(self.returns[idx].mean()), 2)
            self.returns[idx] = 0.0
            self.history.append(row)
            log.info("fleet %d episode at %d steps: %d errands, %d robot-robot collisions", k, row["timesteps"],
                     row["errands_completed"], row["collisions_robot"])
        write_json(self.out / "episodes.json", self.history)
        return True


def train_fleet(cfg: FleetTrainConfig) -> dict[str, Any]:
    """Fine-tune ``cfg.init_from`` in the fleet and save the result; returns the run record
    (also ``out/run.json``).

    Raises:
        ModelError: the model cannot be loaded, has no sidecar, or its spaces differ from the
            fleet's; ``resume`` without a checkpoint.
        ConfigError: a bad hyperparameter file or setting.
    """
    import torch
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from bulletnav.files import write_json
    from bulletnav.rl.callbacks import CheckpointCallback, ThroughputCallback, TimedVecEnv
    from bulletnav.rl.train import close_progress_bar, progress_bar_callback

    torch.set_num_threads(1)  # 2 cores: more threads slow PPO down
    out = Path(cfg.out)
    ckpt = out / "checkpoints" / "last.zip"
    recorded = out / "config.json"
    hp, env_kwargs, fleets, seed, init_from = _run_settings(cfg, ckpt, recorded)
    out.mkdir(parents=True, exist_ok=True)
    venv = VecMonitor(TimedVecEnv(make_fleet_vec_env(env_kwargs, fleets, seed)))
    slots = list(venv.unwrapped.slots)
    normalize = dict(hp.get("normalize") or {})
    start_steps, prior = 0, 0.0
    episodes: list[dict[str, Any]] = []
    if cfg.resume:
        model, venv, start_steps, prior, episodes = _resumed_model(out, ckpt, venv, normalize)
    else:
        model, venv = _fine_tune_model(cfg, init_from, venv, normalize, hp, seed)
    vecnorm = venv if isinstance(venv, VecNormalize) else None
    timer = venv.venv.venv if vecnorm is not None else venv.venv  # VecNormalize > VecMonitor > TimedVecEnv
    started = time.time() - prior

    def state() -> dict[str, Any]:
        return {"wall_time": round(time.time() - started, 1)}

    record: dict[str, Any] = {
        "command": cfg.command, "algo": "ppo", "env_id": FLEET_ENV_ID, "seed": seed, "timesteps": cfg.timesteps,
        "fleets": fleets, "slots": len(slots), "hyperparams": hp, "env_kwargs": env_kwargs,
        "init_from": str(init_from), "git_commit": git_commit(), "machine": machine(),
        "torch_threads": torch.get_num_threads(), "resumed_from": start_steps or None, "versions": versions(),
    }
    write_json(recorded, record)
    throughput = ThroughputCallback(timer)
    callbacks = [CheckpointCallback(out, cfg.checkpoint_freq, state), throughput,
                 FleetEpisodeCallback(out, slots, episodes)]
    t0 = time.time()
    remaining = max(cfg.timesteps - start_steps, 0)
    bar = progress_bar_callback() if cfg.progress_bar else None
    try:
        if remaining:
            model.learn(total_timesteps=remaining, callback=[*callbacks, *([bar] if bar else [])],
                        reset_num_timesteps=not cfg.resume)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the last checkpoint stands; the fleets' simulations end
        close_progress_bar(bar)
        venv.close()
        raise
    wall = time.time() - t0
    _save_final(cfg, model, venv, vecnorm, state(), env_kwargs, record)
    record.update(throughput=throughput.summary() if remaining else None, wall_time_s=round(wall, 1),
                  wall_time_total_s=round(prior + wall, 1), total_timesteps=int(model.num_timesteps),
                  episodes=len(episodes), last_episodes=episodes[-fleets * 3:])
    write_json(out / "run.json", record)
    return record


def _run_settings(cfg: FleetTrainConfig, ckpt: Path, recorded: Path) -> tuple[dict[str, Any], dict[str, Any], int, int, Path]:
    """A run's hyperparameters, fleet env settings, fleets, seed and initial model: the recorded
    ones of the run resumed (``resume``), else those of ``cfg``.

    Raises:
        ModelError: ``resume`` without a checkpoint.
    """
    from bulletnav.rl.callbacks import finish_checkpoint
    from bulletnav.rl.hyperparams import load_hyperparams, upgrade_hyperparams

    if cfg.resume:
        finish_checkpoint(Path(cfg.out))  # a run killed while writing its last checkpoint
        if not ckpt.is_file() or not recorded.is_file():
            raise ModelError(f"{ckpt}: no checkpoint to resume from")
        original = json.loads(recorded.read_text())
        hp = upgrade_hyperparams(original["hyperparams"], str(recorded))
        env_kwargs = dict(original["env_kwargs"])
        return hp, env_kwargs, int(original["fleets"]), int(original["seed"]), Path(original["init_from"])
    hp_path = cfg.hyperparams or default_hyperparams()
    hp = load_hyperparams("ppo", env_id=HYPERPARAMS_ENV_ID, path=hp_path)
    env_kwargs = fleet_env_kwargs(cfg.init_from, hp, cfg)
    return hp, env_kwargs, cfg.fleets, cfg.seed, Path(cfg.init_from)


def _resumed_model(out: Path, ckpt: Path, venv: Any, normalize: dict[str, Any]) -> tuple[Any, Any, int, float, list[dict[str, Any]]]:
    """The model of the last checkpoint on ``venv`` (normalized with the checkpoint's
    statistics), the env it learns on, its timesteps, the wall time (s) before it and the
    episode rows up to it.

    Raises:
        ModelError: normalization without statistics beside the checkpoint.
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from bulletnav.rl.safe import apply_stats, load_stats, load_zip
    from bulletnav.rl.sidecar import vecnormalize_path

    stats = load_stats(ckpt, {})
    if normalize:
        if not isinstance(stats, dict):
            raise ModelError(f"{ckpt}: no normalization statistics beside it ({vecnormalize_path(ckpt).name})")
        venv = apply_stats(VecNormalize(venv, **normalize), stats)
    model = load_zip(ckpt, PPO, env=venv)
    start_steps = int(model.num_timesteps)
    last = json.loads(ckpt.with_suffix(".json").read_text()) if ckpt.with_suffix(".json").is_file() else {}
    prior = float(last.get("wall_time", 0.0))
    episodes = []
    if (out / "episodes.json").is_file():
        episodes = [r for r in json.loads((out / "episodes.json").read_text()) if r["timesteps"] <= start_steps]
    return model, venv, start_steps, prior, episodes


def _fine_tune_model(cfg: FleetTrainConfig, init_from: Path, venv: Any, normalize: dict[str, Any], hp: dict[str, Any],
                     seed: int) -> tuple[Any, Any]:
    """A new PPO model on ``venv`` with the weights (and normalization statistics) of the
    single-robot model ``init_from``, and the env it learns on.

    Raises:
        ModelError: not a PPO model, its spaces differ from the fleet's, or its weights do not
            fit the policy of the hyperparameters.
    """
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from bulletnav.rl.hyperparams import model_kwargs, policy_class
    from bulletnav.rl.io import load_model
    from bulletnav.rl.safe import apply_stats, load_stats

    init, init_meta, _ = load_model(init_from)
    if not isinstance(init, PPO):
        raise ModelError(f"{init_from}: fleet training fine-tunes PPO models, not {type(init).__name__}")
    for what, theirs, ours in (("observation", init.observation_space, venv.observation_space),
                               ("action", init.action_space, venv.action_space)):
        if theirs.shape != ours.shape or not (np.array_equal(theirs.low, ours.low) and np.array_equal(theirs.high, ours.high)):
            raise ModelError(f"{init_from}: its {what} space {theirs} differs from the fleet's {ours}")
    if normalize:
        venv = VecNormalize(venv, **normalize)
        stats = load_stats(init_from, init_meta)
        if isinstance(stats, dict):
            apply_stats(venv, stats)
        venv.training, venv.norm_reward = True, bool(normalize.get("norm_reward", True))
    model = PPO(policy_class(hp), venv, seed=seed, device="cpu", verbose=0, **model_kwargs(hp, venv.action_space.shape[0]))
    try:
        model.policy.load_state_dict(init.policy.state_dict(), strict=True)
    except RuntimeError as exc:
        raise ModelError(f"{init_from}: its weights do not fit the policy of {cfg.hyperparams or default_hyperparams()}: "
                         f"{str(exc)[:300]}") from None
    return model, venv


def _save_final(cfg: FleetTrainConfig, model: Any, venv: Any, vecnorm: Any, state: dict[str, Any],
                env_kwargs: dict[str, Any], record: dict[str, Any]) -> None:
    """Save the last checkpoint, then ``out/model.zip`` with its normalization statistics and its
    sidecar (the fleet settings in its own block), and close the env."""
    from bulletnav.files import write_json
    from bulletnav.rl.callbacks import save_checkpoint
    from bulletnav.rl.io import atomic_save_model, atomic_save_vecnormalize
    from bulletnav.rl.safe import save_safe
    from bulletnav.rl.sidecar import sidecar_path, vecnormalize_path

    out = Path(cfg.out)
    save_checkpoint(model, out, vecnorm, state)
    final = out / "model.zip"
    atomic_save_model(model, final)
    if vecnorm is not None:
        atomic_save_vecnormalize(vecnorm, vecnormalize_path(final))
    venv.close()
    fleet_block = {"num_robots": int(env_kwargs["num_robots"]), "dynamic": bool(env_kwargs["dynamic"]),
                   "duration_s": float(env_kwargs["duration_s"]), "fleets": record["fleets"]}
    single = {k: v for k, v in env_kwargs.items() if k not in ("num_robots", "dynamic", "duration_s")}
    meta = {"algo": "ppo", "env_id": HYPERPARAMS_ENV_ID if fleet_block["dynamic"] else "bulletnav/WarehouseAisles-v0",
            "env_kwargs": single, "fleet": fleet_block, "trained_in": FLEET_ENV_ID, "init_from": record["init_from"],
            "shield": False, "seed": record["seed"], "timesteps": int(model.num_timesteps), "git_commit": record["git_commit"],
            "command": cfg.command}
    write_json(sidecar_path(final), save_safe(model, final, vecnorm, meta))


def versions() -> dict[str, str]:
    """Versions of what a run's numbers depend on."""
    import gymnasium
    import pettingzoo
    import pybullet  # noqa: F401
    import stable_baselines3
    import torch

    return {"python": platform.python_version(), "torch": torch.__version__, "stable_baselines3": stable_baselines3.__version__,
            "gymnasium": gymnasium.__version__, "pettingzoo": pettingzoo.__version__, "numpy": np.__version__}


__all__ = ["FLEET_ENV_ID", "HYPERPARAMS_ENV_ID", "FleetEpisodeCallback", "FleetTrainConfig", "default_hyperparams",
           "fleet_env_kwargs", "make_fleet_vec_env", "train_fleet", "versions"]
