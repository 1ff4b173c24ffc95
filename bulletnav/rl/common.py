"""Shared pieces of training and evaluation: algorithms, hyperparameters, envs, atomic I/O."""

from __future__ import annotations

import io
import json
import os
import tempfile
import zipfile
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import yaml

from bulletnav import ENV_ID
from bulletnav.errors import ConfigError, ModelError

ALGOS = ("ppo", "sac", "td3", "a2c")

EVAL_SEED_BASE = 10_000_000
"""Evaluation during training uses seeds from here up: training only seeds its first resets
with ``seed + rank`` (small numbers), so these episodes are never trained on."""


def algo_class(name: str):
    from stable_baselines3 import A2C, PPO, SAC, TD3

    try:
        return {"ppo": PPO, "sac": SAC, "td3": TD3, "a2c": A2C}[name]
    except KeyError:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {', '.join(ALGOS)}") from None


def load_hyperparams(algo: str, env_id: str = ENV_ID, path: str | Path | None = None) -> dict[str, Any]:
    """The hyperparameters for ``algo`` on ``env_id`` from ``path`` (default
    ``rl/hyperparams/<algo>.yml``).

    Raises:
        ConfigError: the file is missing, not YAML, or lacks the env id (the message names
            file and key).
    """
    if path is None:
        path = Path(str(resources.files("bulletnav").joinpath("rl", "hyperparams", f"{algo}.yml")))
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read hyperparameter file ({exc.strerror or exc})") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from exc
    if not isinstance(data, dict) or env_id not in data:
        raise ConfigError(f"{path}: no hyperparameters for env id {env_id!r}")
    if not isinstance(data[env_id], dict):
        raise ConfigError(f"{path}: {env_id!r} must map hyperparameter names to values")
    return dict(data[env_id])


class CollisionIsTerminal(gym.Wrapper):
    """For learning only: a collision ends the episode as a terminal state.

    The env reports a collision as a truncation (the article's rule), and SB3 bootstraps a
    truncated episode from the value of its last state, as if the robot could drive on; a
    crash is a real end, so the learner sees it as terminal. Evaluation uses the plain env.
    """

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if info.get("collision") and not terminated:
            terminated, truncated = True, False
        return obs, reward, terminated, truncated, info


def make_env_fn(env_kwargs: dict[str, Any], collision_terminal: bool = False) -> Callable[[], gym.Env]:
    """A thunk building one training env; it pins torch to one thread in its process."""

    def _thunk() -> gym.Env:
        import torch

        import bulletnav  # noqa: F401  (registers the env in a fresh worker)

        torch.set_num_threads(1)
        env = gym.make(ENV_ID, **env_kwargs)
        return CollisionIsTerminal(env) if collision_terminal else env

    return _thunk


def evaluation_env_kwargs(env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """The env settings a model is evaluated with: its training settings minus the reward
    overrides (``reward_*``), so every agent is scored on the env's own reward."""
    return {k: v for k, v in env_kwargs.items() if not k.startswith("reward_")}


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``: a reader (or a
    crash) never sees a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; shipped files should be readable
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_save_model(model, path: str | Path) -> None:
    """Save an SB3 model zip atomically."""
    buffer = io.BytesIO()
    model.save(buffer)
    atomic_write_bytes(path, buffer.getvalue())


def atomic_save_vecnormalize(vecnorm, path: str | Path) -> None:
    import pickle

    atomic_write_bytes(path, pickle.dumps(vecnorm))


def atomic_write_json(path: str | Path, data: Any) -> None:
    atomic_write_bytes(path, (json.dumps(data, indent=2, default=_json_default) + "\n").encode())


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, type):
        return f"{o.__module__}.{o.__qualname__}"
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def sidecar_path(model_path: str | Path) -> Path:
    """``model.zip`` -> ``model.json``: the algorithm and env settings a model needs."""
    p = Path(model_path)
    return p.with_suffix(".json")


def vecnormalize_path(model_path: str | Path) -> Path:
    p = Path(model_path)
    return p.with_name(p.stem + "_vecnormalize.pkl")


def load_model(path: str | Path, algo: str | None = None):
    """Load a model saved by ``bulletnav train`` with its sidecar metadata.

    Returns ``(model, meta, vecnorm)``; ``vecnorm`` is the saved ``VecNormalize`` or None.

    Raises:
        ModelError: the file is missing, not a zip, truncated, not an SB3 model, or of another
            algorithm than its sidecar says.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: model file not found")
    meta: dict[str, Any] = {}
    side = sidecar_path(path)
    if side.is_file():
        try:
            meta = json.loads(side.read_text())
        except json.JSONDecodeError as exc:
            raise ModelError(f"{side}: model metadata is not valid JSON ({exc})") from exc
    algo = algo or meta.get("algo")
    if not zipfile.is_zipfile(path):
        raise ModelError(f"{path}: not a model archive (not a zip file; truncated or another kind of file?)")
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            if "data" not in names or "policy.pth" not in names:
                raise ModelError(f"{path}: zip file is not a Stable-Baselines3 model (no 'data' / 'policy.pth')")
            bad = zf.testzip()
            if bad is not None:
                raise ModelError(f"{path}: corrupt model archive (member {bad!r} fails its CRC)")
            data = json.loads(zf.read("data"))
    except (zipfile.BadZipFile, OSError, json.JSONDecodeError, KeyError) as exc:
        raise ModelError(f"{path}: corrupt model archive ({exc})") from exc
    if algo is None:
        algo = _guess_algo(data)
    if algo is None:
        raise ModelError(f"{path}: cannot tell the algorithm; pass --algo or keep the .json beside the model")
    cls = algo_class(algo)
    try:
        model = cls.load(path, device="cpu")
    except Exception as exc:  # SB3 raises many kinds on a mismatched or broken archive
        raise ModelError(f"{path}: cannot load as {algo.upper()} ({type(exc).__name__}: {exc})") from exc
    if not isinstance(model, cls):
        raise ModelError(f"{path}: expected a {algo.upper()} model, got {type(model).__name__}")
    vecnorm = None
    vn = vecnormalize_path(path)
    if vn.is_file():
        import pickle

        with open(vn, "rb") as f:
            vecnorm = pickle.load(f)
    return model, meta, vecnorm


def _guess_algo(data: dict[str, Any]) -> str | None:
    text = json.dumps(data.get("policy_class", {}))
    for name in ALGOS:
        if f"{name}.policies" in text.lower():
            return name
    return None


class SB3Policy:
    """Adapter from an SB3 model to the :class:`bulletnav.evaluation.Policy` interface."""

    def __init__(self, model, vecnorm=None, deterministic: bool = True) -> None:
        self.model = model
        self.vecnorm = vecnorm
        self.deterministic = deterministic

    def reset(self, env, rng) -> None:
        pass

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.vecnorm is not None and getattr(self.vecnorm, "norm_obs", False):
            obs = self.vecnorm.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=self.deterministic)
        return action
