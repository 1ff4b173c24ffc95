"""Hyperparameter files (RL Zoo's format, one YAML per algorithm keyed by env id) and
their translation into SB3 constructor arguments."""

from __future__ import annotations

import copy
import difflib
import importlib
import logging
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav import ENV_ID
from bulletnav.errors import ConfigError
from bulletnav.filekinds import wrong_kind
from bulletnav.yamlfile import read_yaml, show

log = logging.getLogger(__name__)

ENV_KEYS = frozenset({"policy", "n_envs", "n_timesteps", "env_kwargs", "normalize", "action_noise", "noise_type",
                      "noise_std", "randomize", "curriculum"})
"""Keys of a hyperparameter entry that set up the envs and the run, not the algorithm's
constructor. ``n_timesteps``, ``noise_type``/``noise_std`` and a dotted ``policy`` are RL Zoo's
(one file serves ``bulletnav train`` and ``python -m rl_zoo3.train``); ``randomize`` and
``curriculum`` are this project's (RL Zoo would hand them to the algorithm: files that use
them are for ``bulletnav train`` only)."""


def load_hyperparams(algo: str, env_id: str = ENV_ID, path: str | Path | None = None) -> dict[str, Any]:
    """The hyperparameters for ``algo`` on ``env_id`` from ``path`` (default
    ``rl/hyperparams/<algo>.yml``).

    Raises:
        ConfigError: the file is missing, not YAML, or lacks the env id (the message names
            file and key).
    """
    if path is None:
        path = Path(str(resources.files("bulletnav").joinpath("rl", "hyperparams", f"{algo}.yml")))
    other = wrong_kind(path, "hyperparams")  # a world, a suite or a model given as hyperparameters
    if other:
        raise ConfigError(other)
    data = read_yaml(path, "hyperparameter file", ConfigError)
    if not isinstance(data, dict) or env_id not in data:
        raise ConfigError(f"{path}: no hyperparameters for env id {show(env_id)}")
    if not isinstance(data[env_id], dict):
        raise ConfigError(f"{path}: {show(env_id)} must map hyperparameter names to values")
    entry = data[env_id]
    odd = [k for k in entry if not isinstance(k, str) or not k.isidentifier()]
    if odd:  # they become keyword arguments of the algorithm's constructor
        raise ConfigError(f"{path}: {env_id} has hyperparameter names that are not identifiers: {show(odd)}")
    for key in ("n_envs", "n_timesteps"):
        value = entry.get(key, 1)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ConfigError(f"{path}: {env_id}.{key} must be an integer >= 1, got {show(value)}")
    for key in ("env_kwargs", "normalize", "policy_kwargs", "action_noise"):
        value = data[env_id].get(key)
        if value is not None and value is not False and not isinstance(value, dict):  # train does **value
            raise ConfigError(f"{path}: {env_id}.{key} must be a mapping, got {show(value)}")
    hp = upgrade_hyperparams(dict(data[env_id]), str(path))
    check_hyperparams(hp, algo, env_id, str(path))
    if hp.get("randomize"):  # checked now: a typo fails before any env starts
        from bulletnav.envs.randomization import parse_randomize

        try:
            parse_randomize(hp["randomize"], where=f"{path}: {env_id}.randomize")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    if hp.get("curriculum"):
        from bulletnav.rl.curriculum import Curriculum

        try:
            Curriculum.from_spec(hp["curriculum"], where=f"{path}: {env_id}.curriculum")
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    return hp


GYM_MAKE_KEYS = frozenset({"max_episode_steps", "disable_env_checker", "order_enforce", "autoreset"})
"""``env_kwargs`` that ``gym.make`` itself takes (not the env's)."""
VECNORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon", "norm_obs_keys")
"""What a ``normalize:`` mapping may set (SB3's ``VecNormalize`` arguments)."""


def _unknown(where: str, what: str, key: Any, known: Any) -> ConfigError:
    near = difflib.get_close_matches(str(key), sorted(known), n=1)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return ConfigError(f"{where}: unknown {what} {show(key)}{hint}")


def _init_params(cls: type) -> dict[str, Any]:
    """The named ``__init__`` parameters of ``cls``, following ``**kwargs`` up its bases (a
    subclass that passes them on takes its parents' too)."""
    import inspect

    params: dict[str, Any] = {}
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        sig = inspect.signature(klass.__init__)
        for name, p in sig.parameters.items():
            if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL):
                params.setdefault(name, p)
        if not any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
            break
    return params


def check_hyperparams(hp: dict[str, Any], algo: str, env_id: str, where: str) -> None:
    """Check an entry whole before anything starts (no env, no worker, no model): every
    algorithm key against the algorithm's constructor, ``normalize`` against ``VecNormalize``,
    ``policy_kwargs`` against the policy class, ``env_kwargs`` against the env id's own
    keywords (for bulletnav's single-robot ids), and the types of numbers. Each error names
    the file, the env id block, the key and the nearest valid key.

    Raises:
        ConfigError: one line, as above.
    """
    from bulletnav.rl.algos import algo_class

    block = f"{where}: {env_id}"
    cls = algo_class(algo)
    params = _init_params(cls)
    accepted = set(params) - {"self", "policy", "env"}
    for key, value in hp.items():
        if key in ENV_KEYS:
            continue
        if key not in accepted:
            raise _unknown(block, f"{algo.upper()} hyperparameter", key, accepted | ENV_KEYS)
        default = params[key].default
        schedule = key in ("learning_rate", "clip_range") and isinstance(value, str) and value.startswith("lin_")
        if isinstance(default, bool):
            ok = isinstance(value, bool)
        elif isinstance(default, (int, float)) and default is not None:
            ok = schedule or (isinstance(value, (int, float)) and not isinstance(value, bool)) or (
                key in ("train_freq",) and isinstance(value, (list, tuple)))
        else:
            ok = True
        if not ok:
            raise ConfigError(f"{block}.{key} must be {'true or false' if isinstance(default, bool) else 'a number'}"
                              f"{' or lin_<value>' if key in ('learning_rate', 'clip_range') else ''}, got {show(value)}")
    normalize = hp.get("normalize")
    if isinstance(normalize, dict):
        for key in normalize:
            if key not in VECNORMALIZE_KEYS:
                raise _unknown(f"{block}.normalize", "VecNormalize key", key, VECNORMALIZE_KEYS)
    policy = hp.get("policy", "MlpPolicy")
    if not isinstance(policy, str):
        raise ConfigError(f"{block}.policy must name a policy class (MlpPolicy or a dotted name), got {show(policy)}")
    policy_kwargs = hp.get("policy_kwargs")
    if isinstance(policy_kwargs, dict):
        policy = policy_class(hp)
        if isinstance(policy, str):
            policy = cls.policy_aliases.get(policy)
        if policy is None:
            raise ConfigError(f"{block}.policy: unknown policy {show(hp.get('policy'))}; "
                              f"{algo.upper()} has {', '.join(sorted(cls.policy_aliases))}")
        taken = set(_init_params(policy)) - {"self", "observation_space", "action_space", "lr_schedule"}
        for key in policy_kwargs:
            if key not in taken:
                raise _unknown(f"{block}.policy_kwargs", f"argument of {policy.__name__}", key, taken)
    env_kwargs = hp.get("env_kwargs")
    if isinstance(env_kwargs, dict):
        check_env_kwargs(env_id, env_kwargs, f"{block}.env_kwargs")


def check_env_kwargs(env_id: str, env_kwargs: dict[str, Any], where: str) -> None:
    """``env_kwargs`` of a bulletnav single-robot id checked as the env will take them, without
    building it (its config is made and dropped); other ids are left to their env.

    Raises:
        ConfigError: an unknown keyword (with the nearest) or a bad value, in one line.
    """
    import gymnasium as gym

    from bulletnav.envs.warehouse import known_kwargs, make_config

    try:
        spec = gym.spec(env_id)
    except gym.error.Error:
        return
    entry = spec.entry_point if isinstance(spec.entry_point, str) else ""
    barn = entry.endswith(":BarnEnv")
    if not (entry.endswith(":WarehouseEnv") or barn):
        return
    kwargs = {k: v for k, v in env_kwargs.items() if k not in GYM_MAKE_KEYS}
    known = set(known_kwargs()) - {"config", "render_mode"}
    if barn:
        from bulletnav.barn.env import check_barn_kwargs

        known.add("world_idx")
        try:
            check_barn_kwargs(kwargs)
        except TypeError as exc:
            raise ConfigError(f"{where}: {exc}") from None
    for key in kwargs:
        if key not in known:
            raise _unknown(where, f"keyword of {env_id}", key, known | GYM_MAKE_KEYS)
    base = {k: v for k, v in (spec.kwargs or {}).items() if k not in ("render_mode", "config")}
    try:
        make_config(None, **{**base, **{k: v for k, v in kwargs.items() if k != "world_idx"}})
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}: {' '.join(str(exc).split())}") from None


def upgrade_hyperparams(hp: dict[str, Any], where: str = "hyperparameters") -> dict[str, Any]:
    """Hyperparameters in today's form: the old ``collision_terminal: true`` (a wrapper) is
    the env option ``collision_terminates`` now, so runs recorded before still resume."""
    if "collision_terminal" not in hp:
        return hp
    hp = dict(hp)
    flag = bool(hp.pop("collision_terminal"))
    env_kwargs = dict(hp.get("env_kwargs") or {})
    env_kwargs.setdefault("collision_terminates", flag)
    hp["env_kwargs"] = env_kwargs
    log.warning("%s: 'collision_terminal' is now the env option env_kwargs.collision_terminates", where)
    return hp


def linear_schedule(initial: float):
    """RL Zoo's ``lin_<value>``: the value decays linearly from ``initial`` to 0 over training."""

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def model_kwargs(hp: dict[str, Any], n_actions: int) -> dict[str, Any]:
    """SB3 constructor arguments from a hyperparameter entry: ``lin_X`` schedules, classes
    named by dotted path, action noise."""
    # a copy: SB3 adds entries to the dicts it is given (A2C puts its optimizer class into
    # policy_kwargs), which must not leak into the recorded hyperparameters
    kwargs = copy.deepcopy({k: v for k, v in hp.items() if k not in ENV_KEYS})
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str) and value.startswith("lin_"):
            kwargs[key] = linear_schedule(float(value[4:]))
    policy_kwargs = kwargs.get("policy_kwargs") or {}
    for key in ("features_extractor_class", "activation_fn"):
        if isinstance(policy_kwargs.get(key), str):  # "package.module.Name" in the YAML file
            policy_kwargs[key] = import_name(policy_kwargs[key])
    noise = hp.get("action_noise")
    sigma = float(noise["sigma"]) if noise else None
    if hp.get("noise_type") is not None:  # RL Zoo's form: noise_type: normal, noise_std: 0.2
        if hp["noise_type"] != "normal":
            raise ConfigError(f"hyperparameters: noise_type {show(hp['noise_type'])} is not supported (only 'normal')")
        sigma = float(hp.get("noise_std", 0.1))
    if sigma:
        from stable_baselines3.common.noise import NormalActionNoise

        kwargs["action_noise"] = NormalActionNoise(np.zeros(n_actions), sigma * np.ones(n_actions))
    return kwargs


def policy_class(hp: dict[str, Any]) -> Any:
    """The entry's ``policy``: an SB3 alias (``"MlpPolicy"``) as is, a dotted name
    (``"bulletnav.rl.policies.ClearanceActorCriticPolicy"``, RL Zoo's form) imported."""
    policy = hp.get("policy", "MlpPolicy")
    return import_name(policy) if isinstance(policy, str) and "." in policy else policy


def apply_overrides(hp: dict[str, Any], overrides: dict[str, Any] | None, where: str = "overrides") -> dict[str, Any]:
    """A copy of ``hp`` with ``overrides`` set; a dotted key reaches into a mapping
    (``"env_kwargs.reward_collision"``, ``"policy_kwargs.log_std_init"``).

    Raises:
        ConfigError: a dotted key goes through something that is not a mapping.
    """
    out = copy.deepcopy(hp)
    for key, value in (overrides or {}).items():
        *parents, leaf = str(key).split(".")
        node = out
        for part in parents:
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError(f"{where}: {show(key)}: {show(part)} is {show(child)}, not a mapping")
            node = child
        node[leaf] = copy.deepcopy(value)
    return out


IMPORTABLE = ("bulletnav.", "stable_baselines3.", "sb3_contrib.", "torch.nn.", "torch.optim.")
"""Packages whose classes a hyperparameter (or sweep) file may name: a file never makes bulletnav
import or call anything else (a class of your own goes through the Python API instead)."""


def import_name(dotted: str) -> Any:
    """``"package.module.Name"`` -> the class, for classes named in hyperparameter files.

    Raises:
        ConfigError: a name outside :data:`IMPORTABLE`, one that cannot be imported, or not a class.
    """
    module, _, name = dotted.rpartition(".")
    if not (module + ".").startswith(IMPORTABLE):
        allowed = ", ".join(m.rstrip(".") for m in IMPORTABLE)
        raise ConfigError(f"hyperparameters name {show(dotted)}: a file may name classes of {allowed} only "
                          "(pass a class of your own through the Python API)")
    try:
        obj = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ConfigError(f"hyperparameters name {show(dotted)}, which cannot be imported ({exc})") from exc
    if not isinstance(obj, type):
        raise ConfigError(f"hyperparameters name {show(dotted)}, which is a {type(obj).__name__}, not a class")
    return obj
