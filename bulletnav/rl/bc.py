"""Behaviour cloning from a Minari dataset: ``bulletnav train --algo bc --dataset NAME``.

The network is the PPO policy of the dataset's env id (``rl/hyperparams/ppo.yml``'s entry: its
policy class, feature extractor, architecture and ``log_std_init``) in the env PPO trains in
(the entry's ``env_kwargs`` over the dataset's; the expert's actions are mapped linearly onto
that env's action scale when only the scale differs, e.g. physical units onto ``[-1, 1]``),
built by SB3's own constructor, and its actor is fitted by maximum likelihood: each minibatch of the dataset's
(observation, action) pairs raises the log-probability the policy's Gaussian gives the expert's
action (``policy.evaluate_actions``), the Adam optimizer, a held-out tenth of the episodes to
watch. The Gaussian's spread is held at PPO's ``log_std_init`` by default (``fit_std``): fitted
too, it shrinks to the expert's small scatter (log std -2.5 and -2.1 on the aisle A* dataset),
and PPO fine-tuned from it barely explores (measured: docs/datasets.md). The result is saved as
every model is (``model.zip`` plus the pickle-free ``model.safetensors`` and sidecar,
algorithm ``ppo``), so ``evaluate`` runs it and ``train --algo ppo --init-from RUN/model.zip``
fine-tunes it with PPO. A short PyTorch loop, not a library: the imitation library pins other
SB3 and Gymnasium versions.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import BulletnavError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BCConfig:
    """One behaviour-cloning run."""

    dataset: str
    """Minari dataset id (local store: ``MINARI_DATASETS_PATH``)."""
    out: Path
    """Run directory (``model.zip`` and its safe files, ``run.json``, ``history.json``)."""
    epochs: int = 20
    """Passes over the training episodes."""
    batch_size: int = 256
    """(observation, action) pairs per gradient step."""
    learning_rate: float = 3e-4
    """Adam's step size."""
    seed: int = 0
    """Seeds the network's initialisation, the split and the minibatch order."""
    validation: float = 0.1
    """Share of the episodes held out to report the validation loss (at least one when there are two)."""
    fit_std: bool = False
    """Fit the Gaussian's log std as well; False (default) holds it at PPO's ``log_std_init``,
    so the mean alone is fitted (the same fit as least squares) and PPO fine-tuning from the
    model explores as a fresh PPO does."""
    command: str = ""
    """The command line, for the record."""


def _load(dataset_id: str) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
    """The dataset, its observations and actions (one row per step: the observation the action
    was taken in) and each row's episode index."""
    import minari

    try:
        ds = minari.load_dataset(dataset_id)
    except (FileNotFoundError, ValueError) as exc:
        raise BulletnavError(f"--dataset {dataset_id}: no such local Minari dataset ({exc})") from exc
    obs, acts, owner = [], [], []
    for k, ep in enumerate(ds.iterate_episodes()):
        o = np.asarray(ep.observations)
        if not isinstance(ep.observations, np.ndarray) or o.ndim != 2:
            raise BulletnavError(f"--dataset {dataset_id}: behaviour cloning needs flat vector observations")
        obs.append(o[:-1])
        acts.append(np.asarray(ep.actions))
        owner.append(np.full(len(ep.actions), k))
    if not obs:
        raise BulletnavError(f"--dataset {dataset_id}: no episodes")
    return ds, np.concatenate(obs).astype(np.float32), np.concatenate(acts).astype(np.float32), np.concatenate(owner)


def train_bc(cfg: BCConfig) -> dict[str, Any]:
    """Fit, save and return the run record (also ``out/run.json``)."""
    import torch

    import bulletnav  # noqa: F401  (registers the envs the dataset's spec names)
    from bulletnav.files import write_json
    from bulletnav.provenance import git_commit, machine
    from bulletnav.rl.hyperparams import load_hyperparams
    from bulletnav.rl.io import atomic_save_model
    from bulletnav.rl.safe import save_safe
    from bulletnav.rl.sidecar import sidecar_path

    if cfg.epochs < 1 or cfg.batch_size < 1 or not cfg.learning_rate > 0 or not 0 <= cfg.validation < 1:
        raise BulletnavError(f"behaviour cloning needs epochs >= 1, batch_size >= 1, learning_rate > 0 and "
                             f"0 <= validation < 1; got {cfg}")
    torch.set_num_threads(1)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    ds, obs, acts, owner = _load(cfg.dataset)
    spec = ds.spec.env_spec
    if spec is None:
        raise BulletnavError(f"--dataset {cfg.dataset}: the dataset carries no env spec to build the policy for")
    hp = load_hyperparams("ppo", env_id=spec.id)
    # the network is PPO's for this env id, in the env PPO trains in (the hyperparameter file's
    # env settings over the dataset's): a BC model then fine-tunes with train --init-from
    env_kwargs = {k: v for k, v in {**dict(spec.kwargs), **hp.get("env_kwargs", {})}.items() if k != "render_mode"}
    model = _ppo_model(cfg, spec.id, hp, env_kwargs, obs.shape[1:], acts.shape[1:])
    acts = _in_action_scale(acts, ds.action_space, model.action_space)
    policy = model.policy
    policy.set_training_mode(True)
    if not cfg.fit_std and hasattr(policy, "log_std"):
        policy.log_std.requires_grad_(False)
    episodes = np.unique(owner)
    held = _held_out(rng, episodes, cfg.validation)
    val = np.isin(owner, held)
    x_tr, a_tr = torch.as_tensor(obs[~val]), torch.as_tensor(acts[~val])
    x_va, a_va = torch.as_tensor(obs[val]), torch.as_tensor(acts[val])
    t0 = time.time()
    history = _fit(cfg, policy, rng, (x_tr, a_tr), (x_va, a_va))
    wall = time.time() - t0
    policy.set_training_mode(False)
    if hasattr(policy, "log_std"):
        policy.log_std.requires_grad_(True)  # a fine-tuning run trains it
    cfg.out.mkdir(parents=True, exist_ok=True)
    final = cfg.out / "model.zip"
    commit = git_commit()
    atomic_save_model(model, final)
    meta = {"algo": "ppo", "trained_by": "bc", "env_id": spec.id, "env_kwargs": env_kwargs, "shield": False,
            "seed": cfg.seed, "timesteps": 0, "dataset": cfg.dataset, "git_commit": commit, "command": cfg.command}
    write_json(sidecar_path(final), save_safe(model, final, None, meta))
    record = {"command": cfg.command, "algo": "bc", "dataset": cfg.dataset, "env_id": spec.id,
              "env_kwargs": env_kwargs, "episodes": int(len(episodes)), "validation_episodes": int(len(held)),
              "samples": int(len(x_tr)), "epochs": cfg.epochs, "batch_size": cfg.batch_size,
              "learning_rate": cfg.learning_rate, "seed": cfg.seed, "wall_time_s": round(wall, 1), "fit_std": cfg.fit_std,
              "log_std": [round(float(v), 4) for v in policy.log_std.detach()] if hasattr(policy, "log_std") else None,
              "final": history[-1], "git_commit": commit, "machine": machine(),
              "network": {"policy": str(hp.get("policy", "MlpPolicy")), "policy_kwargs": str(hp.get("policy_kwargs", {}))}}
    write_json(cfg.out / "history.json", history)
    write_json(cfg.out / "run.json", json.loads(json.dumps(record, default=str)))
    return record


def _ppo_model(cfg: BCConfig, env_id: str, hp: dict[str, Any], env_kwargs: dict[str, Any], obs_shape: tuple[int, ...],
               act_shape: tuple[int, ...]) -> Any:
    """A new PPO model with the network of the hyperparameters, in the env ``env_id`` made with
    ``env_kwargs`` (closed again).

    Raises:
        BulletnavError: the dataset's observation or action shape does not fit that env.
    """
    import gymnasium as gym
    from stable_baselines3 import PPO

    from bulletnav.rl.hyperparams import model_kwargs, policy_class

    env = gym.make(env_id, **env_kwargs)
    try:
        target = env.action_space
        if env.observation_space.shape != obs_shape or target.shape != act_shape:
            raise BulletnavError(f"--dataset {cfg.dataset}: observations {obs_shape} / actions {act_shape} do not "
                                 f"fit PPO's env for {env_id} ({env.observation_space.shape} / {target.shape}); record the "
                                 "dataset with the env settings of rl/hyperparams/ppo.yml")
        return PPO(policy_class(hp), env, seed=cfg.seed, device="cpu", verbose=0, **model_kwargs(hp, target.shape[0]))
    finally:
        env.close()


def _in_action_scale(acts: np.ndarray, source: Any, target: Any) -> np.ndarray:
    """The dataset's actions (in ``source``'s box) as the same commands in ``target``'s box
    (physical units <-> [-1, 1], linearly); unchanged where the boxes are equal."""
    if np.array_equal(source.low, target.low) and np.array_equal(source.high, target.high):
        return acts
    return (target.low + (acts - source.low) / (source.high - source.low) * (target.high - target.low)).astype(np.float32)


def _held_out(rng: np.random.Generator, episodes: np.ndarray, validation: float) -> np.ndarray:
    """The episodes held out for validation: the fraction ``validation`` of them (at least one
    when it is above 0 and there are two or more), drawn from ``rng``."""
    n_held = int(round(validation * len(episodes)))
    if validation > 0 and len(episodes) > 1:
        n_held = max(n_held, 1)
    return rng.permutation(episodes)[:n_held]


def _fit(cfg: BCConfig, policy: Any, rng: np.random.Generator, train: tuple[Any, Any],
         validation: tuple[Any, Any]) -> list[dict[str, float]]:
    """Fit ``policy`` to the training (observations, actions) by the negative log-likelihood of
    the actions, ``cfg.epochs`` epochs of shuffled batches with Adam; one row per epoch (the
    training loss, and the validation loss and action error where there is a validation set)."""
    import torch

    (x_tr, a_tr), (x_va, a_va) = train, validation
    optimizer = torch.optim.Adam([q for q in policy.parameters() if q.requires_grad], lr=cfg.learning_rate)
    history = []
    for epoch in range(cfg.epochs):
        order = torch.as_tensor(rng.permutation(len(x_tr)))
        losses = []
        for start in range(0, len(order), cfg.batch_size):
            idx = order[start:start + cfg.batch_size]
            _, log_prob, _ = policy.evaluate_actions(x_tr[idx], a_tr[idx])
            loss = -log_prob.mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
        row = {"epoch": epoch + 1, "train_nll": float(np.mean(losses))}
        if len(x_va):
            with torch.no_grad():
                _, log_prob, _ = policy.evaluate_actions(x_va, a_va)
                mean = policy.get_distribution(x_va).distribution.mean
            row.update(val_nll=float(-log_prob.mean()), val_action_mse=float(((mean - a_va) ** 2).mean()))
        history.append(row)
        log.info("bc epoch %d: %s", epoch + 1, row)
    return history


__all__ = ["BCConfig", "train_bc"]
