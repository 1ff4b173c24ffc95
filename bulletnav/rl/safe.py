"""Model files opened without running their code.

A Stable-Baselines3 zip stores some entries as cloudpickle (the policy class, its keyword
arguments, spaces, schedules, buffers) and ``VecNormalize.save`` is a plain pickle: loading
either the usual way runs whatever code the file's author put there. bulletnav never does.

- **The safe format** (what ``bulletnav train`` writes beside SB3's zip, and what every loader
  prefers): ``NAME.safetensors`` (the policy's weights, tensors only) and ``NAME.json`` (the
  sidecar: algorithm, spaces, policy class and keyword arguments by name, hyperparameters,
  normalization statistics; numbers and names only). :func:`save_safe` / :func:`load_safe`.
- **An SB3 zip without them** loads through SB3's ``custom_objects`` with *every* pickled entry
  replaced by an object rebuilt here from the zip's JSON text (:func:`zip_custom_objects`):
  classes only from an allow-list of names, spaces from their printed bounds, schedules from
  their printed values. A class name is read from a pickle's opcodes (``pickletools``), which
  never executes it. Tensors are read by SB3 with ``torch.load(weights_only=True)``.
- **Normalization statistics** come from the sidecar's ``normalization`` block,
  ``NAME_vecnormalize.json`` or ``NAME_vecnormalize.npz`` (:func:`load_stats`); a
  ``NAME_vecnormalize.pkl`` is opened only when the caller trusts pickles.

Anything that cannot be rebuilt this way raises :class:`UnsafeModelError` naming the file and
the entry, unless ``trust_pickle`` (the CLI's ``--trust-pickle``, which runs the file's code).
"""

from __future__ import annotations

import ast
import base64
import hashlib
import importlib
import inspect
import json
import logging
import math
import pickletools
import re
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.errors import ModelError

log = logging.getLogger(__name__)

FORMAT = "bulletnav-policy/1"
"""The ``format`` field of a safe model's JSON."""


class UnsafeModelError(ModelError):
    """A model file that can only be opened by running code it contains."""


# ----------------------------------------------------------------------------- allow-lists
_SB3 = "stable_baselines3"
POLICY_CLASSES = frozenset({
    f"{_SB3}.common.policies.ActorCriticPolicy", f"{_SB3}.common.policies.MultiInputActorCriticPolicy",
    f"{_SB3}.sac.policies.SACPolicy", f"{_SB3}.sac.policies.MultiInputPolicy",
    f"{_SB3}.td3.policies.TD3Policy", f"{_SB3}.td3.policies.MultiInputPolicy",
    "bulletnav.rl.policies.ClearanceActorCriticPolicy", "bulletnav.rl.policies.ClearanceSACPolicy",
    "bulletnav.rl.policies.ClearanceTD3Policy",
})
"""Policy classes a model may name (``policy_class``)."""
BUFFER_CLASSES = frozenset({
    f"{_SB3}.common.buffers.RolloutBuffer", f"{_SB3}.common.buffers.DictRolloutBuffer",
    f"{_SB3}.common.buffers.ReplayBuffer", f"{_SB3}.common.buffers.DictReplayBuffer",
})
"""Buffer classes (``rollout_buffer_class`` / ``replay_buffer_class``)."""
KWARG_CLASSES = frozenset({
    f"{_SB3}.common.torch_layers.FlattenExtractor", f"{_SB3}.common.torch_layers.CombinedExtractor",
    f"{_SB3}.common.torch_layers.NatureCNN", "bulletnav.rl.features.ClearanceFeatures",
    *(f"torch.nn.modules.activation.{n}" for n in ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid")),
    "torch.optim.adam.Adam", "torch.optim.adamw.AdamW", "torch.optim.rmsprop.RMSprop", "torch.optim.sgd.SGD",
    f"{_SB3}.common.sb2_compat.rmsprop_tf_like.RMSpropTFLike",
})
"""Classes a policy's keyword arguments may name (feature extractors, activations, optimizers)."""

_STATE_KEYS = frozenset({"num_timesteps", "_total_timesteps", "_num_timesteps_at_start", "_n_updates", "_episode_num",
                         "_current_progress_remaining", "n_envs", "start_time"})
_NOT_RESTORED = frozenset({"_last_obs", "_last_episode_starts", "_last_original_obs", "ep_info_buffer",
                           "ep_success_buffer"})
"""Pickled run state a loaded model does without (a resumed run starts its rollouts afresh)."""


def resolve(name: str, allowed: frozenset[str], what: str) -> type:
    """The class of dotted ``name`` if it is in ``allowed``; else :class:`UnsafeModelError`."""
    if not isinstance(name, str) or name not in allowed:
        raise UnsafeModelError(f"{what} names {name!r}, which is not a class bulletnav rebuilds without running "
                               f"the file's code (allowed: {', '.join(sorted(n.rsplit('.', 1)[1] for n in allowed))})")
    module, _, attr = name.rpartition(".")
    return getattr(importlib.import_module(module), attr)


def dotted(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


# ----------------------------------------------------------------------------- pickles, read not run
def pickle_globals(b64: str) -> tuple[list[str], list[Any]]:
    """The global names a base64 pickle references and the plain constants it holds, read from
    its opcodes (``pickletools.genops``): nothing is imported or executed."""
    raw = base64.b64decode(b64.encode(), validate=True)
    names: list[str] = []
    consts: list[Any] = []
    strings: list[str] = []
    for op, arg, _ in pickletools.genops(raw):
        if op.name in ("SHORT_BINUNICODE", "BINUNICODE", "UNICODE", "BINUNICODE8", "SHORT_BINSTRING", "BINSTRING"):
            strings.append(arg)
            consts.append(arg)
        elif op.name == "STACK_GLOBAL":
            if len(strings) < 2:
                raise ValueError("STACK_GLOBAL without its two names")
            names.append(f"{strings[-2]}.{strings[-1]}")
            del consts[-2:]
        elif op.name == "GLOBAL":
            module, name = str(arg).split(" ", 1)
            names.append(f"{module}.{name}")
        elif op.name in ("BININT", "BININT1", "BININT2", "LONG1", "BINFLOAT", "INT", "FLOAT", "LONG"):
            consts.append(arg)
    return names, consts


def _bare_class(entry: dict[str, Any], allowed: frozenset[str], what: str) -> type:
    """A pickled entry that is nothing but a reference to a class."""
    try:
        names, consts = pickle_globals(entry[":serialized:"])
    except (ValueError, TypeError, KeyError) as exc:
        raise UnsafeModelError(f"{what}: unreadable serialized entry ({exc})") from None
    if len(names) != 1 or consts:
        raise UnsafeModelError(f"{what} is a pickled object, not a bare class reference ({len(names)} global(s))")
    return resolve(names[0], allowed, what)


# ----------------------------------------------------------------------------- spaces
def space_to_json(space: Any) -> dict[str, Any]:
    """A Box or Discrete space as JSON fields (non-finite bounds as the strings "inf"/"-inf")."""
    from gymnasium import spaces

    if isinstance(space, spaces.Box):
        return {"type": "Box", "shape": list(space.shape), "dtype": str(space.dtype),
                "low": _floats_out(space.low), "high": _floats_out(space.high)}
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    raise ModelError(f"the safe format stores Box and Discrete spaces, not {type(space).__name__}")


def space_from_json(d: Any, what: str) -> Any:
    from gymnasium import spaces

    if not isinstance(d, dict) or d.get("type") not in ("Box", "Discrete"):
        raise ModelError(f"{what}: expected a Box or Discrete space, got {str(d)[:80]!r}")
    try:
        if d["type"] == "Discrete":
            return spaces.Discrete(int(d["n"]), start=int(d.get("start", 0)))
        shape = tuple(int(x) for x in d["shape"])
        if d["dtype"] not in ("float32", "float64", "float16", "int64", "int32", "uint8"):
            raise ValueError(f"dtype {d['dtype']!r}")
        if len(shape) > 4 or math.prod(shape) > 10_000_000:
            raise ValueError(f"shape {shape}")
        low = np.asarray(_floats_in(d["low"]), dtype=np.float64).reshape(shape)
        high = np.asarray(_floats_in(d["high"]), dtype=np.float64).reshape(shape)
        return spaces.Box(low=low.astype(d["dtype"]), high=high.astype(d["dtype"]), shape=shape, dtype=d["dtype"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{what}: malformed space ({exc})") from None


def _floats_out(a: np.ndarray) -> list[Any]:
    return [x if math.isfinite(x) else ("inf" if x > 0 else "-inf") for x in np.asarray(a, dtype=np.float64).ravel().tolist()]


def _floats_in(values: Any) -> list[float]:
    if not isinstance(values, list):
        raise TypeError("bounds must be a list")
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float, str)) or (isinstance(v, str) and v not in ("inf", "-inf")):
            raise ValueError(f"bound {v!r}")
        out.append(float(v))
    return out


_ARRAY = re.compile(r"^\[[\s0-9eE.+\-infa]*\]$")


def _printed_array(text: Any, what: str) -> list[float]:
    """An array as SB3's JSON prints it (``str(ndarray)``), parsed without evaluating it."""
    if not isinstance(text, str) or "..." in text or not _ARRAY.match(text.strip()):
        raise UnsafeModelError(f"{what}: bounds not readable from the file's text ({str(text)[:60]!r})")
    try:
        return [float(x) for x in text.strip()[1:-1].split()]
    except ValueError as exc:
        raise UnsafeModelError(f"{what}: bounds not readable ({exc})") from None


def _space_from_zip(entry: dict[str, Any], what: str) -> Any:
    kind = entry.get(":type:", "")
    if kind == "<class 'gymnasium.spaces.box.Box'>":
        shape = [int(x) for x in re.findall(r"\d+", str(entry.get("_shape", "")))]
        dtype = str(entry.get("dtype", ""))
        return space_from_json({"type": "Box", "shape": shape, "dtype": dtype,
                                "low": _printed_array(entry.get("low"), what), "high": _printed_array(entry.get("high"), what)}, what)
    if kind == "<class 'gymnasium.spaces.discrete.Discrete'>":
        return space_from_json({"type": "Discrete", "n": entry.get("n"), "start": entry.get("start", 0)}, what)
    raise UnsafeModelError(f"{what} is a {kind or 'pickled object'}; bulletnav rebuilds Box and Discrete spaces only")


# ----------------------------------------------------------------------------- policy kwargs
_CLASS_TEXT = re.compile(r"^<class '([A-Za-z0-9_.]+)'>$")


def kwargs_to_json(kwargs: dict[str, Any]) -> dict[str, Any]:
    """A policy's keyword arguments with classes as dotted names (every class allow-listed)."""
    out: dict[str, Any] = {}
    for k, v in kwargs.items():
        if isinstance(v, type):
            resolve(dotted(v), KWARG_CLASSES, f"policy_kwargs[{k!r}]")
            out[k] = {"class": dotted(v)}
        else:
            json.dumps(v)  # raises TypeError on anything not plain
            out[k] = v
    return out


def kwargs_from_json(d: Any, what: str) -> dict[str, Any]:
    if not isinstance(d, dict):
        raise ModelError(f"{what}: policy kwargs must be a mapping")
    return {str(k): (resolve(v["class"], KWARG_CLASSES, f"{what}[{k!r}]") if isinstance(v, dict) and set(v) == {"class"} else v)
            for k, v in d.items()}


SIZED_HYPERPARAMETERS = ("n_steps", "batch_size", "buffer_size", "n_envs")
"""Hyperparameters of a saved model that size what building it allocates, each bounded by the
limit of the same name in :mod:`bulletnav.limits` (the network by ``net_width`` and ``net_layers``)."""


def check_sizes(kwargs: Any, hyper: Any, what: str) -> None:
    """Refuse a saved model whose network (``kwargs["net_arch"]``, ``features_dim``) or
    hyperparameters (:data:`SIZED_HYPERPARAMETERS`) pass their limits, before anything is built.

    Raises:
        ModelError: a size that is not a whole number >= 1.
        LimitError: a size past its limit (the message names the file, the entry, the value and
            the ``BULLETNAV_MAX_*`` variable that raises it).
    """
    from bulletnav import limits

    def whole(value: Any, name: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ModelError(f"{what}: {name} must be a whole number >= 1, got {str(value)[:60]!r}")
        return value

    arch = kwargs.get("net_arch") if isinstance(kwargs, dict) else None
    nets = arch.items() if isinstance(arch, dict) else [("", arch)] if arch is not None else []
    for key, net in nets:
        name = f"net_arch[{key!r}]" if key else "net_arch"
        if not isinstance(net, (list, tuple)):
            raise ModelError(f"{what}: {name} must be a list of layer widths, got {str(net)[:60]!r}")
        limits.check("net_layers", len(net), f"{what}: {name} layers")
        for width in net:
            limits.check("net_width", whole(width, f"{name} width"), f"{what}: {name} width")
    extractor = kwargs.get("features_extractor_kwargs") if isinstance(kwargs, dict) else None
    if isinstance(extractor, dict) and "features_dim" in extractor:
        limits.check("net_width", whole(extractor["features_dim"], "features_dim"), f"{what}: features_dim")
    for key in SIZED_HYPERPARAMETERS:
        if isinstance(hyper, dict) and hyper.get(key) is not None:
            limits.check(key, whole(hyper[key], key), f"{what}: {key}")


def _kwargs_from_zip(entry: dict[str, Any], what: str) -> dict[str, Any]:
    try:
        names, _ = pickle_globals(entry[":serialized:"])
    except (ValueError, TypeError, KeyError) as exc:
        raise UnsafeModelError(f"{what}: unreadable serialized entry ({exc})") from None
    if entry.get(":type:") != "<class 'dict'>" or not set(names) <= KWARG_CLASSES:
        odd = sorted(set(names) - KWARG_CLASSES) or [entry.get(":type:")]
        raise UnsafeModelError(f"{what} is a pickle referencing {', '.join(map(str, odd))}, not a mapping of allowed classes")
    out: dict[str, Any] = {}
    for k, v in entry.items():
        if k in (":type:", ":serialized:"):
            continue
        if isinstance(v, str):
            m = _CLASS_TEXT.match(v)
            if m:
                out[k] = resolve(m.group(1), KWARG_CLASSES, f"{what}[{k!r}]")
                continue
            try:
                v = ast.literal_eval(v)  # literals only (numbers, strings, lists, dicts): never code
            except (ValueError, SyntaxError, MemoryError, RecursionError):
                raise UnsafeModelError(f"{what}[{k!r}] = {v[:60]!r} is not a literal or an allowed class") from None
        out[k] = v
    return out


# ----------------------------------------------------------------------------- schedules and the rest
class _Unavailable:
    """A schedule that was a pickled function: not rebuilt, and refusing to be used."""

    def __init__(self, what: str) -> None:
        self.what = what

    def __call__(self, _progress: float) -> float:
        raise ModelError(f"{self.what} was stored as a pickled function, which bulletnav does not run; "
                         "set it in a hyperparameter file to train this model on")


def _schedule(entry: dict[str, Any], what: str) -> Any:
    from stable_baselines3.common.utils import LinearSchedule

    text = str(entry.get("value_schedule", ""))
    m = re.fullmatch(r"ConstantSchedule\(val=([-+0-9.eE]+)\)", text)
    if m:
        return float(m.group(1))
    m = re.fullmatch(r"LinearSchedule\(start=([-+0-9.eE]+), end=([-+0-9.eE]+), end_fraction=([-+0-9.eE]+)\)", text)
    if m:
        return LinearSchedule(*(float(x) for x in m.groups()))
    return _Unavailable(what)


def _train_freq(entry: dict[str, Any], what: str) -> Any:
    names, consts = pickle_globals(entry[":serialized:"])
    allowed = {f"{_SB3}.common.type_aliases.TrainFreq", f"{_SB3}.common.type_aliases.TrainFrequencyUnit"}
    ints = [c for c in consts if isinstance(c, int) and not isinstance(c, bool)]
    units = [c for c in consts if c in ("step", "episode")]
    if not set(names) <= allowed or len(ints) != 1 or len(units) != 1:
        raise UnsafeModelError(f"{what} is not a plain TrainFreq")
    return (ints[0], units[0])


def _action_noise(entry: dict[str, Any], what: str) -> Any:
    from stable_baselines3.common.noise import NormalActionNoise

    if entry.get(":type:") == f"<class '{_SB3}.common.noise.NormalActionNoise'>":
        return NormalActionNoise(np.array(_printed_array(entry.get("_mu"), what)), np.array(_printed_array(entry.get("_sigma"), what)))
    log.warning("%s: a %s, not rebuilt (the model acts without it; training on would explore without noise)",
                what, entry.get(":type:"))
    return None


def zip_custom_objects(data: dict[str, Any], path: Path) -> dict[str, Any]:
    """SB3 ``custom_objects`` replacing every pickled entry of a zip's ``data``, so that loading
    it unpickles nothing.

    Raises:
        UnsafeModelError: an entry that cannot be rebuilt without running the file's code.
    """
    objects: dict[str, Any] = {}
    check_sizes({}, data, str(path))  # n_steps, buffer_size, ... size what loading allocates
    for key, entry in data.items():
        if not (isinstance(entry, dict) and ":serialized:" in entry):
            continue
        what = f"{path}: entry {key!r}"
        if key == "policy_class":
            objects[key] = _bare_class(entry, POLICY_CLASSES, what)
        elif key in ("rollout_buffer_class", "replay_buffer_class"):
            objects[key] = _bare_class(entry, BUFFER_CLASSES, what)
        elif key == "policy_kwargs":
            objects[key] = _kwargs_from_zip(entry, what)
            check_sizes(objects[key], {}, what)
        elif key in ("observation_space", "action_space"):
            objects[key] = _space_from_zip(entry, what)
        elif key in ("lr_schedule", "learning_rate"):
            # the policy's optimizer is built with the rate at progress 1 while loading: a pickled
            # function (RL Zoo's linear schedule) becomes rate 0, which acting never uses
            rate = _schedule(entry, what)
            if isinstance(rate, _Unavailable):
                log.warning("%s: a pickled learning-rate function, not run: the model acts with it unset (rate 0); "
                            "set learning_rate in a hyperparameter file to train it on", what)
                rate = 0.0
            objects[key] = rate
        elif key in ("clip_range", "clip_range_vf", "ent_coef"):
            objects[key] = _schedule(entry, what)
        elif key == "train_freq":
            objects[key] = _train_freq(entry, what)
        elif key == "action_noise":
            objects[key] = _action_noise(entry, what)
        elif key in _NOT_RESTORED:
            objects[key] = None
        else:
            raise UnsafeModelError(f"{what} is a pickled {entry.get(':type:', 'object')} that bulletnav does not rebuild "
                                   "without running the file's code")
    return objects


def read_zip_data(path: Path) -> dict[str, Any]:
    """The ``data`` JSON of an SB3 zip, as text (nothing deserialized)."""
    try:
        with zipfile.ZipFile(path) as zf:
            data = json.loads(zf.read("data"))
    except (zipfile.BadZipFile, OSError, KeyError, json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ModelError(f"{path}: corrupt model archive ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict):
        raise ModelError(f"{path}: corrupt model archive (its data is not a mapping)")
    return data


def load_zip(path: Path, cls: type, env: Any = None, trust_pickle: bool = False) -> Any:
    """Load an SB3 zip as ``cls`` with no entry unpickled (unless ``trust_pickle``)."""
    objects = None if trust_pickle else zip_custom_objects(read_zip_data(path), path)
    return cls.load(path, env=env, device="cpu", custom_objects=objects)


def zip_spaces(path: Path) -> tuple[Any, Any]:
    """A zip's observation and action spaces, rebuilt from its text."""
    objects = zip_custom_objects({k: v for k, v in read_zip_data(path).items() if k in ("observation_space", "action_space")}, path)
    return objects.get("observation_space"), objects.get("action_space")


# ----------------------------------------------------------------------------- normalization statistics
class ObsNormalizer:
    """``VecNormalize``'s observation normalization from its statistics, with its arithmetic
    (``clip((obs - mean) / sqrt(var + epsilon), -clip_obs, clip_obs)``, as float32)."""

    def __init__(self, stats: dict[str, Any]) -> None:
        self.stats = stats
        self.norm_obs = bool(stats["norm_obs"])
        obs = stats["obs"] or {"mean": [], "var": []}
        self.mean = np.asarray(obs["mean"], dtype=np.float64)
        self.var = np.asarray(obs["var"], dtype=np.float64)
        self.clip_obs = float(stats["clip_obs"])
        self.epsilon = float(stats["epsilon"])

    def normalize_obs(self, obs: np.ndarray) -> np.ndarray:
        return np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs, self.clip_obs).astype(np.float32)


def stats_to_json(vecnorm: Any) -> dict[str, Any]:
    """A ``VecNormalize``'s statistics and settings as JSON fields (floats exact); ``obs`` is
    None when it does not normalize observations (it then keeps no observation statistics)."""
    state = vars(vecnorm)  # an unpickled VecNormalize has no venv, and its __getattr__ recurses on a missing name
    if state.get("norm_obs_keys") is not None or isinstance(state.get("obs_rms"), dict):
        raise ModelError("the safe format stores statistics of Box observations only")

    def rms(r: Any) -> dict[str, Any] | None:
        if r is None:
            return None
        return {"mean": np.asarray(r.mean, dtype=np.float64).ravel().tolist(),
                "var": np.asarray(r.var, dtype=np.float64).ravel().tolist(), "count": float(r.count)}

    return {"obs": rms(state.get("obs_rms")) if state["norm_obs"] else None, "ret": rms(state.get("ret_rms")),
            **{k: float(state[k]) for k in ("clip_obs", "clip_reward", "epsilon", "gamma")},
            "norm_obs": bool(state["norm_obs"]), "norm_reward": bool(state["norm_reward"])}


def check_stats(stats: Any, where: str) -> dict[str, Any]:
    """Validate a statistics block (types, shapes, finite, non-negative variances)."""
    try:
        for key in ("norm_obs", "norm_reward"):
            if not isinstance(stats[key], bool):
                raise ValueError(f"{key} must be true or false")
        for name in ("obs", "ret"):
            if stats[name] is None:
                if name == "obs" and stats["norm_obs"]:
                    raise ValueError("norm_obs is true but obs holds no statistics")
                continue
            mean = np.asarray(stats[name]["mean"], dtype=np.float64)
            var = np.asarray(stats[name]["var"], dtype=np.float64)
            if mean.shape != var.shape or mean.ndim != 1 or not (np.isfinite(mean).all() and np.isfinite(var).all()) \
                    or (var < 0).any():
                raise ValueError(f"{name}: mean/var of shapes {mean.shape}/{var.shape}, finite non-negative variances needed")
            float(stats[name]["count"])
        for key in ("clip_obs", "clip_reward", "epsilon", "gamma"):
            if isinstance(stats[key], bool) or not math.isfinite(float(stats[key])):
                raise ValueError(f"{key} is not a finite number")
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ModelError(f"{where}: malformed normalization statistics ({exc})") from None
    return stats


def apply_stats(vecnorm: Any, stats: dict[str, Any]) -> Any:
    """Load JSON statistics into a live ``VecNormalize`` (resume, fine-tuning)."""
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    for name in ("obs", "ret"):
        if stats[name] is None:
            continue
        rms = RunningMeanStd(shape=np.asarray(stats[name]["mean"]).shape)
        rms.mean = np.asarray(stats[name]["mean"], dtype=np.float64)
        rms.var = np.asarray(stats[name]["var"], dtype=np.float64)
        rms.count = float(stats[name]["count"])
        setattr(vecnorm, f"{name}_rms", rms)
    vecnorm.clip_obs, vecnorm.clip_reward = float(stats["clip_obs"]), float(stats["clip_reward"])
    vecnorm.epsilon, vecnorm.gamma = float(stats["epsilon"]), float(stats["gamma"])
    vecnorm.norm_obs, vecnorm.norm_reward = bool(stats["norm_obs"]), bool(stats["norm_reward"])
    return vecnorm


def stats_path(model_path: Path, suffix: str = ".json") -> Path:
    """``model.zip`` -> ``model_vecnormalize.json`` (or ``.npz`` / ``.pkl``)."""
    return model_path.with_name(model_path.stem + "_vecnormalize" + suffix)


def load_stats(model_path: Path, meta: dict[str, Any], trust_pickle: bool = False) -> dict[str, Any] | Any | None:
    """The normalization statistics of a model: the sidecar's ``normalization`` block, else
    ``NAME_vecnormalize.json`` / ``.npz``; a ``.pkl`` only when ``trust_pickle`` (returned as the
    unpickled ``VecNormalize``). None when the model has none.

    Raises:
        UnsafeModelError: only a pickle holds them and pickles are not trusted.
    """
    if meta.get("normalization") is not None:
        return check_stats(meta["normalization"], f"{model_path.with_suffix('.json')}: normalization")
    js, npz, pkl = stats_path(model_path), stats_path(model_path, ".npz"), stats_path(model_path, ".pkl")
    if js.is_file():
        try:
            return check_stats(json.loads(js.read_text()), str(js))
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
            raise ModelError(f"{js}: not valid JSON ({exc})") from None
    if npz.is_file():
        return check_stats(_stats_from_npz(npz), str(npz))
    if pkl.is_file():
        if not trust_pickle:
            raise UnsafeModelError(f"{pkl}: normalization statistics stored as a pickle, which runs code when opened; "
                                   "bulletnav does not open it (pass --trust-pickle only for a file you trust, or "
                                   f"convert it once with `bulletnav convert-model {model_path} --trust-pickle`)")
        import pickle

        with open(pkl, "rb") as f:
            return pickle.load(f)  # the user said they trust this file
    return None


def _stats_from_npz(path: Path) -> dict[str, Any]:
    try:
        with np.load(path, allow_pickle=False) as z:
            out: dict[str, Any] = {k: z[k].item() for k in ("clip_obs", "clip_reward", "epsilon", "gamma")}
            out.update({k: bool(z[k].item()) for k in ("norm_obs", "norm_reward")})
            for n in ("obs", "ret"):
                out[n] = ({"mean": z[f"{n}_mean"].tolist(), "var": z[f"{n}_var"].tolist(), "count": z[f"{n}_count"].item()}
                          if f"{n}_mean" in z.files else None)
            return out
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise ModelError(f"{path}: unreadable statistics ({type(exc).__name__}: {exc})") from None


def normalizer(stats: Any) -> Any:
    """What :class:`~bulletnav.rl.policy.SB3Policy` normalizes observations with."""
    if stats is None or not isinstance(stats, dict):
        return stats  # None, or a trusted, unpickled VecNormalize
    return ObsNormalizer(stats)


# ----------------------------------------------------------------------------- the safe format
def weights_path(model_path: Path) -> Path:
    """``model.zip`` -> ``model.safetensors``."""
    return model_path.with_suffix(".safetensors")


def save_safe(model: Any, model_path: Path, vecnorm: Any, meta: dict[str, Any]) -> dict[str, Any]:
    """Write ``model.safetensors`` and return ``meta`` with the ``format``, ``policy`` and
    ``normalization`` blocks added (the caller writes it as the sidecar, atomically)."""
    from safetensors.torch import save

    from bulletnav.files import write_bytes
    from bulletnav.rl.algos import ALGOS

    algo = type(model).__name__.lower()
    if algo not in ALGOS:
        raise ModelError(f"the safe format stores {', '.join(ALGOS)} models, not {type(model).__name__}")
    state = {k: v.detach().cpu().clone().contiguous() for k, v in model.policy.state_dict().items()}
    blob = save(state)
    write_bytes(weights_path(model_path), blob)
    hyper = {}
    for name in inspect.signature(type(model).__init__).parameters:
        if name in ("self", "policy", "env", "policy_kwargs", "device", "_init_setup_model", "tensorboard_log", "verbose",
                    "seed", "action_noise", "replay_buffer_class", "rollout_buffer_class", "stats_window_size"):
            continue
        value = getattr(model, name, None)
        if name == "train_freq" and value is not None:
            value = [int(value.frequency), value.unit.value]
        constant = getattr(getattr(value, "value_schedule", None), "val", None)  # FloatSchedule(ConstantSchedule)
        if constant is not None:
            value = float(constant)
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError):
            continue  # schedules and objects: rebuilt by _setup_model from the plain values
        hyper[name] = value
    policy = {
        "algo": algo, "class": dotted(type(model.policy)),
        "observation_space": space_to_json(model.observation_space), "action_space": space_to_json(model.action_space),
        "kwargs": kwargs_to_json(model.policy_kwargs), "hyperparameters": hyper,
        "num_timesteps": int(model.num_timesteps), "weights_sha256": hashlib.sha256(blob).hexdigest(),
    }
    return {**meta, "format": FORMAT, "policy": policy, "normalization": stats_to_json(vecnorm) if vecnorm is not None else None}


class _SpacesEnv(gym.Env):
    """An env that is only its spaces: what SB3's constructor needs to build the networks.
    Acting uses ``predict``; nothing ever steps it."""

    def __init__(self, observation_space: Any, action_space: Any) -> None:
        self.observation_space, self.action_space = observation_space, action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        raise ModelError("a model rebuilt from its files has no env: give it one to act in (set_env)")

    def step(self, action: Any):
        raise ModelError("a model rebuilt from its files has no env: give it one to act in (set_env)")

    def close(self) -> None:
        pass


def has_safe(model_path: Path, meta: dict[str, Any]) -> bool:
    return meta.get("format") == FORMAT and weights_path(model_path).is_file()


def load_safe(model_path: Path, meta: dict[str, Any]) -> Any:
    """Rebuild an SB3 model from ``model.safetensors`` and the sidecar's ``policy`` block with
    the project's own classes; nothing executable is read."""
    from safetensors import SafetensorError
    from safetensors.torch import load

    from bulletnav.rl.algos import ALGOS, algo_class

    side = model_path.with_suffix(".json")
    p = meta.get("policy")
    if not isinstance(p, dict) or p.get("algo") not in ALGOS:
        raise ModelError(f"{side}: no usable 'policy' block (algorithm one of {', '.join(ALGOS)})")
    blob = weights_path(model_path).read_bytes()
    if p.get("weights_sha256") not in (None, hashlib.sha256(blob).hexdigest()):
        raise ModelError(f"{weights_path(model_path)}: its SHA-256 differs from the one {side.name} records "
                         "(the weights were replaced or damaged)")
    cls = algo_class(p["algo"])
    policy_cls = resolve(p.get("class"), POLICY_CLASSES, f"{side}: policy class")
    obs_space = space_from_json(p.get("observation_space"), f"{side}: observation_space")
    act_space = space_from_json(p.get("action_space"), f"{side}: action_space")
    kwargs = kwargs_from_json(p.get("kwargs", {}), f"{side}: policy kwargs")
    hyper = p.get("hyperparameters", {})
    check_sizes(kwargs, hyper, str(side))  # before the networks and buffers are built from them
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "policy", "env", "policy_kwargs", "device",
                                                                 "_init_setup_model", "tensorboard_log", "verbose"}
    if not isinstance(hyper, dict) or not set(hyper) <= allowed:
        raise ModelError(f"{side}: hyperparameters {sorted(set(hyper) - allowed) if isinstance(hyper, dict) else hyper!r} "
                         f"are not {cls.__name__} parameters")
    try:
        hyper = dict(hyper)
        if "train_freq" in hyper:
            hyper["train_freq"] = tuple(hyper["train_freq"])
        if "buffer_size" in hyper:
            hyper["buffer_size"] = 1  # acting needs no replay memory; training on starts a fresh one of its own size
        model = cls(policy_cls, _SpacesEnv(obs_space, act_space), device="cpu", policy_kwargs=kwargs, **hyper)
        model.num_timesteps = int(p.get("num_timesteps", 0))
        state = load(blob)
        model.policy.load_state_dict(state, strict=True)
    except ModelError:
        raise
    except (SafetensorError, RuntimeError, ValueError, TypeError, KeyError, AssertionError) as exc:
        raise ModelError(f"{weights_path(model_path)}: cannot rebuild the {p['algo'].upper()} policy "
                         f"({type(exc).__name__}: {str(exc)[:300]})") from None
    return model


def convert_model(path: Path, trust_pickle: bool = False) -> dict[str, Any]:
    """Write the safe format beside an SB3 zip: ``NAME.safetensors``, the sidecar ``NAME.json``
    with its ``policy`` and ``normalization`` blocks, and ``NAME_vecnormalize.json``.

    The zip itself is the source (not safe files already beside it), read without unpickling
    unless ``trust_pickle``; statistics come from ``NAME_vecnormalize.json`` / ``.npz``, else
    from ``NAME_vecnormalize.pkl`` when ``trust_pickle`` is on (:func:`load_stats`). Returns the
    new sidecar.

    Raises:
        UnsafeModelError: the zip or the statistics can only be read by unpickling, untrusted.
    """
    from bulletnav.files import write_json
    from bulletnav.rl.sidecar import guess_algo, read_sidecar, sidecar_path

    path = Path(path)
    if not zipfile.is_zipfile(path):
        raise ModelError(f"{path}: not a model archive (not a zip file)")
    side = sidecar_path(path)
    meta = {k: v for k, v in read_sidecar(path).items() if k not in ("format", "policy", "normalization")}
    from bulletnav.rl.algos import ALGOS, algo_class

    algo = meta.get("algo") or guess_algo(read_zip_data(path))
    if algo not in ALGOS:
        raise ModelError(f"{path}: cannot tell the algorithm; write {side.name} with \"algo\" first")
    try:
        model = load_zip(path, algo_class(algo), trust_pickle=trust_pickle)
    except ModelError:
        raise
    except Exception as exc:  # SB3 and torch raise many kinds on a broken archive
        raise ModelError(f"{path}: cannot load as {algo.upper()} ({type(exc).__name__}: {str(exc)[:300]})") from None
    stats = load_stats(path, {}, trust_pickle=trust_pickle)  # the files beside the zip, not an earlier sidecar's
    if stats is not None and not isinstance(stats, dict):
        stats = stats_to_json(stats)  # the trusted pickle, now numbers
    new = save_safe(model, path, None, meta)
    new["normalization"] = stats
    if stats is not None:
        write_json(stats_path(path), stats)
    write_json(sidecar_path(path), new)
    return new
