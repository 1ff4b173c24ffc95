"""The sweep file: what to train, what to vary, how to score it.

A sweep file is YAML (every field below; only ``algo`` is required)::

    name: ppo_seeds                  # results under OUT/<name> (default: the file's stem)
    algo: ppo                        # ppo | sac | td3 | a2c
    env_id: bulletnav/Warehouse-v0
    hyperparams: null                # base file (default: the packaged rl/hyperparams/<algo>.yml)
    env_kwargs: {}                   # env options on top of the base file's
    timesteps: 500000                # step budget of every trial
    seeds: [0, 1, 2, 3, 4]           # every configuration is trained once per seed
    grid:                            # hyperparameters crossed with each other (and the seeds);
      learning_rate: [3.0e-4, 1.0e-4]  # a dotted name reaches into a mapping:
      env_kwargs.reward_collision: [-20.0, -40.0]
    search:                          # --optimize N: distributions Optuna's TPE samples from
      learning_rate: {loguniform: [1.0e-5, 1.0e-3]}
      n_steps: {choice: [256, 512, 1024]}
    early_stopping: {scheduler: asha, grace_period: 50000, reduction_factor: 2}  # --optimize only
    resources: {cpu: 1}              # Ray resources of one trial
    n_envs: null                     # training envs per trial (default: the base file's)
    vec_env: dummy                   # dummy: a trial's envs in its own process (fits resources.cpu 1)
    eval_freq: 25000                 # in-training evaluations (what early stopping sees)
    eval_episodes: 20
    checkpoint_freq: 25000           # a resumed sweep continues trials from here
    evaluation: {episodes: 200, seed: 1000}  # the held-out score of each finished trial
    metric: success_rate             # an entry of that evaluation's summary
    mode: max

Every error names the file and the field.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from bulletnav import ENV_ID, limits
from bulletnav.errors import ConfigError, LimitError
from bulletnav.rl.algos import ALGOS
from bulletnav.yamlfile import read_yaml, show

DISTRIBUTIONS = ("uniform", "loguniform", "randint", "choice")
"""Forms of a ``search:`` entry: ``{uniform: [lo, hi]}``, ``{loguniform: [lo, hi]}``,
``{randint: [lo, hi]}`` (integers, ``hi`` excluded) and ``{choice: [v, ...]}``."""
SCHEDULERS = ("asha", "median", "none")
METRICS = ("success_rate", "collision_rate", "spl", "mean_reward", "mean_length")
"""Metrics a sweep can rank by: entries of both the in-training evaluations (what early
stopping compares) and the held-out one (what the table ranks)."""

FIELDS = ("name", "algo", "env_id", "hyperparams", "env_kwargs", "timesteps", "seeds", "grid", "search",
          "early_stopping", "resources", "n_envs", "vec_env", "eval_freq", "eval_episodes", "checkpoint_freq",
          "evaluation", "metric", "mode")


@dataclass(frozen=True)
class EarlyStopping:
    """Stopping of bad trials during ``--optimize``, on the in-training evaluations."""

    scheduler: str = "asha"
    """``asha`` (asynchronous successive halving), ``median`` (median stopping rule) or ``none``."""
    grace_period: int = 50_000
    """Timesteps every trial runs before it may be stopped."""
    reduction_factor: int = 2
    """ASHA: the fraction 1/reduction_factor of trials that goes on at each rung."""


@dataclass(frozen=True)
class SweepSpec:
    """A parsed, validated sweep file (see the module docstring for the fields)."""

    algo: str
    name: str = "sweep"
    env_id: str = ENV_ID
    hyperparams: str | None = None
    """Absolute path of the base hyperparameter file, or None for the packaged one."""
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    timesteps: int = 500_000
    seeds: tuple[int, ...] = (0,)
    grid: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    search: dict[str, dict[str, Any]] = field(default_factory=dict)
    early_stopping: EarlyStopping = field(default_factory=EarlyStopping)
    resources: dict[str, float] = field(default_factory=lambda: {"cpu": 1.0})
    n_envs: int | None = None
    vec_env: str = "dummy"
    eval_freq: int = 25_000
    eval_episodes: int = 20
    checkpoint_freq: int = 25_000
    evaluation_episodes: int = 200
    evaluation_seed: int = 1000
    metric: str = "success_rate"
    mode: str = "max"

    @classmethod
    def from_file(cls, path: str | Path) -> SweepSpec:
        """Read and validate a sweep file.

        Raises:
            ConfigError: unreadable, not YAML, or a field is unknown, missing or invalid
                (the message names the file and the field).
        """
        path = Path(path)
        data = read_yaml(path, "sweep file", ConfigError)
        return cls.from_dict(data, where=str(path), default_name=path.stem)

    @classmethod
    def from_dict(cls, data: Any, where: str = "sweep", default_name: str = "sweep") -> SweepSpec:
        """Validate a sweep given as a mapping (what :meth:`from_file` reads)."""
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: a sweep file is a mapping of fields ({', '.join(FIELDS)})")
        unknown = sorted(set(data) - set(FIELDS), key=str)
        if unknown:
            raise ConfigError(f"{where}: unknown field(s) {', '.join(map(repr, unknown))}; valid: {', '.join(FIELDS)}")

        def bad(name: str, why: str) -> ConfigError:
            return ConfigError(f"{where}: field {show(name)}: {why} (got {show(data.get(name))})")

        if "algo" not in data:
            raise ConfigError(f"{where}: field 'algo' is required (one of {', '.join(ALGOS)})")
        if data["algo"] not in ALGOS:
            raise bad("algo", f"must be one of {', '.join(ALGOS)}")
        kw: dict[str, Any] = {"algo": data["algo"], "name": str(data.get("name") or default_name)}
        if not limits.is_slug(kw["name"]):
            given = "" if data.get("name") else f" (default: the file's name, {show(default_name)})"
            raise bad("name", f"names the results folder{given}: it must be {limits.SLUG_RULE}")
        _environment(data, kw, bad)  # env id, hyperparameter file, env kwargs, resources
        _training(data, kw, bad)  # step counts, n_envs, vec_env
        _trials(data, kw, where, bad)  # seeds, grid and their product's limit
        _scoring(data, kw, where, bad)  # search, early stopping, evaluation, metric, mode
        return cls(**kw)

    def configurations(self) -> list[dict[str, Any]]:
        """Every combination of the grid's values (one empty configuration without a grid)."""
        keys = list(self.grid)
        return [dict(zip(keys, values)) for values in itertools.product(*(self.grid[k] for k in keys))]

    def results_dir(self, out: str | Path, storage: str | Path | None = None) -> Path:
        """``out/<name>``, where the sweep's tables and plot go (and the trials, unless a local
        ``storage`` folder is given: ``storage/<name>`` is checked too).

        Raises:
            ConfigError: either resolves outside its folder (a link inside it leading out).
        """
        try:
            if storage is not None:
                limits.inside(storage, self.name)
            return limits.inside(out, self.name)
        except ValueError as exc:
            raise ConfigError(f"sweep {self.name!r}: the results folder {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain data (what trials receive and the results record)."""
        d = asdict(self)
        d["grid"] = {k: list(v) for k, v in self.grid.items()}
        d["seeds"] = list(self.seeds)
        return d

    @classmethod
    def from_record(cls, d: dict[str, Any]) -> SweepSpec:
        """The inverse of :meth:`to_dict`."""
        d = dict(d)
        d["early_stopping"] = EarlyStopping(**d["early_stopping"])
        d["grid"] = {k: tuple(v) for k, v in d["grid"].items()}
        d["seeds"] = tuple(d["seeds"])
        return cls(**d)


def _environment(data: dict[str, Any], kw: dict[str, Any], bad) -> None:
    """:meth:`SweepSpec.from_dict`'s ``env_id``, ``hyperparams``, ``env_kwargs`` and ``resources`` into ``kw``."""
    env_id = data.get("env_id", ENV_ID)
    if not isinstance(env_id, str) or not env_id:
        raise bad("env_id", "must be a registered env id")
    kw["env_id"] = env_id
    if data.get("hyperparams") is not None:
        hp = Path(str(data["hyperparams"])).expanduser()
        if not hp.is_absolute():  # relative to where the sweep is started (as train --hyperparams)
            hp = Path.cwd() / hp
        if not hp.is_file():
            raise bad("hyperparams", f"no such file {hp}")
        kw["hyperparams"] = str(hp.resolve())
    for name in ("env_kwargs", "resources"):
        if data.get(name) is not None and not isinstance(data[name], dict):
            raise bad(name, "must be a mapping")
    kw["env_kwargs"] = dict(data.get("env_kwargs") or {})
    if data.get("resources") is not None:
        res = {}
        for key, value in data["resources"].items():
            if not isinstance(value, (int, float)) or isinstance(value, bool) or value < 0:
                raise bad("resources", f"{show(key)} must be a number >= 0")
            res[str(key)] = float(value)
        kw["resources"] = res


def _training(data: dict[str, Any], kw: dict[str, Any], bad) -> None:
    """:meth:`SweepSpec.from_dict`'s step counts, ``n_envs`` and ``vec_env`` into ``kw``."""
    for name, low in (("timesteps", 1), ("eval_freq", 1), ("eval_episodes", 1), ("checkpoint_freq", 1)):
        if name in data:
            kw[name] = _int(data[name], low, bad, name)
    if data.get("n_envs") is not None:
        kw["n_envs"] = _int(data["n_envs"], 1, bad, "n_envs")
    if "vec_env" in data:
        if data["vec_env"] not in ("dummy", "subproc"):
            raise bad("vec_env", "must be 'dummy' or 'subproc'")
        kw["vec_env"] = data["vec_env"]


def _trials(data: dict[str, Any], kw: dict[str, Any], where: str, bad) -> None:
    """:meth:`SweepSpec.from_dict`'s ``seeds`` and ``grid`` into ``kw``, and their product
    (the trials) checked against the limit before the grid is ever expanded."""
    if "seeds" in data:
        seeds = data["seeds"]
        if isinstance(seeds, int) and not isinstance(seeds, bool):
            seeds = [seeds]
        if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds):
            raise bad("seeds", "must be a non-empty list of integers")
        if len(set(seeds)) != len(seeds):
            raise bad("seeds", "lists a seed twice")
        kw["seeds"] = tuple(seeds)
    if data.get("grid") is not None:
        if not isinstance(data["grid"], dict):
            raise bad("grid", "must map hyperparameter names to lists of values")
        grid = {}
        for key, values in data["grid"].items():
            if not isinstance(values, list) or not values:
                raise ConfigError(f"{where}: field 'grid': {show(key)} must be a non-empty list of values (got {show(values)})")
            grid[str(key)] = tuple(values)
        kw["grid"] = grid
    trials = math.prod(len(v) for v in kw.get("grid", {}).values()) * len(kw.get("seeds", (0,)))
    try:  # before the grid is ever expanded: 20 keys of 10 values are 10^20 configurations
        limits.check("sweep_trials", trials, "sweep trials (grid configurations x seeds)")
    except LimitError as exc:
        raise ConfigError(f"{where}: field 'grid': {exc}") from None


def _scoring(data: dict[str, Any], kw: dict[str, Any], where: str, bad) -> None:
    """:meth:`SweepSpec.from_dict`'s ``search``, ``early_stopping``, ``evaluation``, ``metric``
    and ``mode`` into ``kw``."""
    if data.get("search") is not None:
        if not isinstance(data["search"], dict):
            raise bad("search", f"must map hyperparameter names to distributions ({', '.join(DISTRIBUTIONS)})")
        kw["search"] = {str(k): _distribution(v, f"{where}: field 'search': {show(k)}") for k, v in data["search"].items()}
        clash = sorted(set(kw["search"]) & set(kw.get("grid", {})))
        if clash:
            raise bad("search", f"{', '.join(clash)} also in 'grid'")
    if data.get("early_stopping") is not None:
        es = data["early_stopping"]
        if not isinstance(es, dict) or set(es) - {"scheduler", "grace_period", "reduction_factor"}:
            raise bad("early_stopping", "must be a mapping of scheduler, grace_period, reduction_factor")
        if es.get("scheduler", "asha") not in SCHEDULERS:
            raise bad("early_stopping", f"scheduler must be one of {', '.join(SCHEDULERS)}")
        kw["early_stopping"] = EarlyStopping(
            scheduler=es.get("scheduler", "asha"),
            grace_period=_int(es.get("grace_period", 50_000), 1, bad, "early_stopping"),
            reduction_factor=_int(es.get("reduction_factor", 2), 2, bad, "early_stopping"))
    if data.get("evaluation") is not None:
        ev = data["evaluation"]
        if not isinstance(ev, dict) or set(ev) - {"episodes", "seed"}:
            raise bad("evaluation", "must be a mapping of episodes and seed")
        kw["evaluation_episodes"] = _int(ev.get("episodes", 200), 1, bad, "evaluation")
        kw["evaluation_seed"] = _int(ev.get("seed", 1000), 0, bad, "evaluation")
    if "metric" in data:
        if data["metric"] not in METRICS:
            raise bad("metric", f"must be one of {', '.join(METRICS)}")
        kw["metric"] = data["metric"]
    if "mode" in data:
        if data["mode"] not in ("max", "min"):
            raise bad("mode", "must be 'max' or 'min'")
        kw["mode"] = data["mode"]


def _int(value: Any, low: int, bad, name: str) -> int:
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise bad(name, f"must be an integer >= {low}")
    return value


def _distribution(spec: Any, where: str) -> dict[str, Any]:
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in DISTRIBUTIONS:
        raise ConfigError(f"{where}: must be one of {{uniform|loguniform|randint: [lo, hi]}} or {{choice: [values]}} "
                          f"(got {show(spec)})")
    kind, args = next(iter(spec.items()))
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise ConfigError(f"{where}: choice needs a non-empty list (got {show(args)})")
        return {kind: list(args)}
    if (not isinstance(args, list) or len(args) != 2
            or not all(isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) for a in args)
            or not args[0] < args[1]):
        raise ConfigError(f"{where}: {kind} needs [lo, hi] with lo < hi (got {show(args)})")
    if kind == "loguniform" and args[0] <= 0:
        raise ConfigError(f"{where}: loguniform needs lo > 0 (got {show(args)})")
    if kind == "randint" and not all(isinstance(a, int) for a in args):
        raise ConfigError(f"{where}: randint needs integers (got {show(args)})")
    return {kind: list(args)}
