"""Benchmark suites: which worlds, which controllers, how many seeded episodes.

A suite is a YAML file (shipped: ``quick`` and ``standard`` in ``bulletnav/benchmark/suites/``)::

    name: quick
    episodes: 20                  # per world and controller
    seed: 3000000                 # episode k of every world is env.reset(seed=seed + k)
    worlds:
      - name: scattered           # optional; default: the id's short name
        env: bulletnav/Warehouse-v0
        kwargs: {num_obstacles: 40}    # optional: num_obstacles, world, perturb, goals, goal_order, physics
        episodes: 10              # optional: this world's own count
      - env: bulletnav/WarehouseAisles-v0
      - name: barn                # BARN's worlds: one world per index, each with `episodes` runs
        env: bulletnav/BARN-v0
        barn_worlds: test         # test (0, 6, ..., 294), train (the other 250), all, or a list [0, 6, 93]
        episodes: 10              # runs per BARN world (run k: env.reset(seed=seed + k), its sensor noise)
    controllers:
      - {name: PID + A*, type: navigator, planner: astar}    # planner: none, astar or rrt
      - {name: PPO, type: model, model: shipped}             # shipped: the world's shipped model; else a path
      - {name: PPO + shield, type: model, model: shipped, shield: true}
      - {name: mine, type: policy, class: "mypackage.module:MyPolicy", kwargs: {gain: 2.0}}
      - {name: DWA, type: dwa}                               # ROS move_base + navfn + DWA, BARN's parameters
      - {name: DWA 2 m/s, type: dwa, params: barn-2ms, env: {min_speed: -0.5, lidar_rays: 720}}

Every controller runs on the same seeded episodes of a world. A ``policy`` class implements
:class:`bulletnav.policy.Policy` (``reset(info)``, ``act(obs, info)``) and is built as
``Class(scene, **kwargs)`` with the env's read-only scene view, from the modules of
bulletnav, stable_baselines3 or sb3_contrib only (:data:`IMPORTABLE`; any other module needs
``--trust-code``, for it runs that module's code); any controller takes ``shield: true``. A
``dwa`` controller is :class:`bulletnav.control.dwa.MoveBaseDWA` with BARN's move_base
parameters, or ``params:`` a shipped set (``barn``, ``barn-2ms``, ``barn-per-cell``) or an override YAML (relative
to the suite file); its env opens with ``min_speed`` = the parameters' ``escape_vel`` (so it can
back up), as ``bulletnav navigate --planner dwa`` does, unless its ``env:`` sets ``min_speed``.
A ``navigator``, ``dwa`` or ``policy`` controller may add env keywords of its own, ``env:``
(:data:`CONTROLLER_ENV_KWARGS`: ``min_speed``, ``lidar_rays``), laid over the world's. The
suite's ``name`` names its output folder (``runs/benchmark/<name>``): a slug
(:data:`bulletnav.limits.SLUG`). Its sizes are limits of :mod:`bulletnav.limits`
(``suite_*``). World kwargs are limited to those the CLI can express, so that every episode
of a report can be replayed by one ``bulletnav navigate`` / ``evaluate`` command, quoted
for the shell (:func:`replay_command`).

A ``barn_worlds`` entry (``bulletnav/BARN-v0`` only) stands for one world per BARN index,
named ``<name>-<index>`` (``barn-006``) with ``kwargs: {world_idx: index}``; their rows are also
summarised together as BARN's ``report_test.py`` does (:mod:`bulletnav.benchmark.barn`). In
BARN-v0 the world, start and goal are fixed by the index, so the runs of a world differ only by
their seed's sensor noise.
"""

from __future__ import annotations

import hashlib
import shlex
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from bulletnav import AISLES_ENV_ID, BARN_ENV_ID, DYNAMIC_ENV_ID, ENV_ID, MISSION_ENV_ID, limits
from bulletnav.config import PHYSICS_PROFILES
from bulletnav.errors import ConfigError, LayoutError, LimitError
from bulletnav.filekinds import wrong_kind
from bulletnav.rl.hyperparams import IMPORTABLE as HYPERPARAM_IMPORTABLE
from bulletnav.yamlfile import read_yaml, show

SUITES_DIR = Path(str(resources.files("bulletnav").joinpath("benchmark", "suites")))
"""The shipped suites (``quick``, ``standard``)."""

SHIPPED_MODELS = {
    ENV_ID: "models/ppo_warehouse.zip",
    AISLES_ENV_ID: "models/ppo_dynamic.zip",
    DYNAMIC_ENV_ID: "models/ppo_dynamic.zip",
    MISSION_ENV_ID: "models/ppo_mission.zip",
    BARN_ENV_ID: "models/ppo_barn.zip",
}
"""``model: shipped`` for each registered id: the policy trained for that world (the aisle
world's is the dynamic policy, trained on the same aisle warehouses with movers), relative
to the project root."""

WORLD_KWARGS = {"num_obstacles": "--obstacles", "world": "--world", "perturb": "--perturb", "goals": "--goals",
                "goal_order": "--order", "world_idx": "--world-idx", "physics": "--physics"}
"""World kwargs a suite may set, with the CLI flag that replays them."""

CONTROLLER_ENV_KWARGS = {"min_speed": "--min-speed", "lidar_rays": "--lidar-rays"}
"""Env keywords a controller's ``env:`` may set (over its world's), with the CLI flag that replays them."""

PLANNERS = ("none", "astar", "rrt")

CONTROLLER_TYPES = ("navigator", "dwa", "model", "policy")
"""The kinds of controller a suite may run."""

BARN_SETS = {"test": "BARN's 50 test worlds 0, 6, ..., 294 (report_test.py's)",
             "train": "the 250 other worlds (those a BARN policy may train on)",
             "all": "all 300 static worlds 0-299"}
"""The named sets a ``barn_worlds`` field may give (or a list of indices)."""

IMPORTABLE = tuple(p for p in HYPERPARAM_IMPORTABLE if not p.startswith("torch."))
"""Packages whose classes a suite's ``policy`` entries may name without ``--trust-code``: the
allow-list of hyperparameter files (:data:`bulletnav.rl.hyperparams.IMPORTABLE`) less torch's
layers and optimizers, which are no policies. The sizes a suite may ask for are limits of
:mod:`bulletnav.limits` (``suite_*``)."""


class SuiteError(ConfigError):
    """A suite file that cannot be used; the message names the file and the field."""


@dataclass(frozen=True)
class WorldSpec:
    """One world of a suite."""

    name: str
    env: str
    """Registered env id."""
    kwargs: dict[str, Any] = field(default_factory=dict)
    """Env kwargs on top of the id's (see :data:`WORLD_KWARGS`)."""
    episodes: int = 0
    """Episodes of this world (the suite's count when 0)."""
    barn_world: int | None = None
    """The BARN world index when this world came from a ``barn_worlds`` entry."""
    group: str = ""
    """The name of the ``barn_worlds`` entry it came from (its rows are summarised together)."""


@dataclass(frozen=True)
class ControllerSpec:
    """One controller of a suite."""

    name: str
    type: str
    """``navigator``, ``dwa``, ``model`` or ``policy``."""
    planner: str = "astar"
    """Navigators: ``none`` (PID alone), ``astar`` or ``rrt``."""
    model: str = ""
    """Models: a path, or ``shipped``."""
    cls: str = ""
    """Policies: ``module:Class``."""
    kwargs: dict[str, Any] = field(default_factory=dict)
    """Policies: keyword arguments of the class."""
    shield: bool = False
    """Behind the safety shield."""
    params: str = ""
    """DWA: move_base's parameters: ``""`` (BARN's), a shipped set (``barn``, ``barn-2ms``,
    ``barn-per-cell``) or an override file (a path)."""
    env: dict[str, Any] = field(default_factory=dict)
    """Env keywords of this controller's own, laid over the world's (:data:`CONTROLLER_ENV_KWARGS`)."""

    def model_path(self, env_id: str, root: Path) -> Path:
        """The model file this controller runs on ``env_id`` (``shipped`` resolved, relative
        paths against ``root``)."""
        path = Path(SHIPPED_MODELS.get(env_id, SHIPPED_MODELS[ENV_ID]) if self.model == "shipped"
                    else self.model)
        return path if path.is_absolute() else root / path


@dataclass(frozen=True)
class Suite:
    """A parsed suite file."""

    name: str
    episodes: int
    seed: int
    worlds: tuple[WorldSpec, ...]
    controllers: tuple[ControllerSpec, ...]
    source: str = ""
    """Where it came from (file path)."""
    sha256: str = ""
    """SHA-256 of the file's bytes (the results record it)."""
    trust_code: bool = False
    """Policy classes outside :data:`IMPORTABLE` were accepted (``--trust-code``)."""

    def episodes_of(self, world: WorldSpec) -> int:
        return world.episodes or self.episodes

    @property
    def total(self) -> int:
        """Episodes in the whole suite."""
        return sum(self.episodes_of(w) for w in self.worlds) * len(self.controllers)

    def out_dir(self, base: str | Path = "runs/benchmark") -> Path:
        """``base/<name>``, the default output folder.

        Raises:
            SuiteError: it resolves outside ``base`` (a link inside ``base`` leading out).
        """
        try:
            return limits.inside(base, self.name)
        except ValueError as exc:
            raise SuiteError(f"{self.source}: field 'name' = {show(self.name)}: the output folder {exc}") from None


def resolve_suite(name_or_path: str) -> Path:
    """A shipped suite by name (``quick``), else a file path.

    Raises:
        SuiteError: neither exists (the message lists the shipped suites).
    """
    shipped = SUITES_DIR / f"{name_or_path}.yaml"
    if "/" not in name_or_path and not name_or_path.endswith((".yaml", ".yml")) and shipped.is_file():
        return shipped
    path = Path(name_or_path)
    if not path.is_file():
        names = sorted(p.stem for p in SUITES_DIR.glob("*.yaml"))
        raise SuiteError(f"no suite {show(name_or_path)}: neither a shipped suite ({', '.join(names)}) nor a file")
    return path


def load_suite(name_or_path: str, trust_code: bool = False) -> Suite:
    """Read and check a suite (:func:`resolve_suite`, :func:`parse_suite`; ``trust_code`` is
    ``--trust-code``).

    Raises:
        SuiteError: the file is missing, not YAML, or a field is wrong (named in the message).
    """
    path = resolve_suite(name_or_path)
    other = wrong_kind(path, "suite")  # a world, a map or hyperparameters given as a suite
    if other:
        raise SuiteError(other)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SuiteError(f"{path}: cannot read suite file ({exc.strerror or exc})") from exc
    raw = read_yaml(path, "suite file", SuiteError, data)
    return parse_suite(raw, str(path), hashlib.sha256(data).hexdigest(), trust_code)


def _int(value: Any, where: str, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SuiteError(f"{where}: field '{name}' must be an integer from {lo} to {hi}, got {show(value)}")
    return value


def _str(value: Any, where: str, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise SuiteError(f"{where}: field '{name}' must be a non-empty string, got {show(value)}")
    return value


def _mapping(value: Any, where: str, name: str, allowed: set[str]) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SuiteError(f"{where}: {name} must be a mapping, got {show(value)}")
    unknown = sorted(str(k) for k in set(value) - allowed)
    if unknown:
        raise SuiteError(f"{where}: {name} has unknown field(s) {unknown}; allowed: {sorted(allowed)}")
    return value


def parse_suite(raw: Any, where: str = "<suite>", sha256: str = "", trust_code: bool = False) -> Suite:
    """Check a decoded suite document and build a :class:`Suite`.

    Args:
        trust_code: accept ``policy`` classes outside :data:`IMPORTABLE` (``--trust-code``:
            running the suite imports and runs the module each names).

    Raises:
        SuiteError: naming ``where``, the field and what is wrong.
    """
    import bulletnav  # noqa: F401  (registers the ids)

    top = _mapping(raw, where, "the suite", {"name", "description", "episodes", "seed", "worlds", "controllers"})
    for required in ("worlds", "controllers"):
        if required not in top:
            raise SuiteError(f"{where}: field '{required}' is missing")
    name = _str(top.get("name", Path(where).stem), where, "name")
    if not limits.is_slug(name):
        given = "field 'name'" if "name" in top else "field 'name' (default: the file's name)"
        raise SuiteError(f"{where}: {given} names the output folder: it must be {limits.SLUG_RULE}, got {show(name)}")
    episodes = _int(top.get("episodes", 20), where, "episodes", 1, 2**31 - 1)
    _limit(where, "suite_episodes", episodes, "field 'episodes'")
    seed = _int(top.get("seed", 0), where, "seed", 0, 2**31 - 1)
    worlds_raw, controllers_raw = top["worlds"], top["controllers"]
    for key, items in (("worlds", worlds_raw), ("controllers", controllers_raw)):
        if not isinstance(items, list) or not items:
            raise SuiteError(f"{where}: field '{key}' must be a non-empty list, got {show(items)}")
        _limit(where, f"suite_{key}", len(items), f"field '{key}' (entries)")
    worlds = [spec for i, w in enumerate(worlds_raw) for spec in _parse_world(w, where, f"worlds[{i}]")]
    controllers = [_parse_controller(c, where, f"controllers[{i}]", trust_code) for i, c in enumerate(controllers_raw)]
    for label, names in (("worlds", [w.name for w in worlds]), ("controllers", [c.name for c in controllers])):
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise SuiteError(f"{where}: {label} need distinct names; repeated: {dup}")
    suite = Suite(name, episodes, seed, tuple(worlds), tuple(controllers), where, sha256, trust_code)
    last = seed + max(suite.episodes_of(w) for w in worlds) - 1
    if last > 2**31 - 1:
        raise SuiteError(f"{where}: field 'seed' = {seed}: its last episode's seed {last} passes 2^31 - 1")
    _limit(where, "suite_total", suite.total, "episodes in all (worlds' episodes x controllers)")
    return suite


def _limit(where: str, name: str, value: int, what: str) -> None:
    """:func:`bulletnav.limits.check` as a :class:`SuiteError` naming the file."""
    try:
        limits.check(name, value, what)
    except LimitError as exc:
        raise SuiteError(f"{where}: {exc}") from None


def _parse_world(w: Any, where: str, tag: str) -> list[WorldSpec]:
    """One ``worlds:`` entry: one world, or one per BARN index of a ``barn_worlds`` entry."""
    import gymnasium as gym

    w = _mapping(w, where, tag, {"name", "env", "kwargs", "episodes", "barn_worlds"})
    env = _str(w.get("env"), where, f"{tag}.env")
    if env not in gym.registry or not env.startswith("bulletnav/"):
        known = sorted(e for e in gym.registry if e.startswith("bulletnav/"))
        raise SuiteError(f"{where}: field '{tag}.env' must be a bulletnav env id ({', '.join(known)}), got {show(env)}")
    kwargs = _mapping(w.get("kwargs") or {}, where, f"{tag}.kwargs", set(WORLD_KWARGS))
    for key, limit in (("num_obstacles", "obstacles"), ("goals", "goals")):
        if key in kwargs:
            count = _int(kwargs[key], where, f"{tag}.kwargs.{key}", 0 if key == "num_obstacles" else 1, 2**31)
            _limit(where, limit, count, f"field '{tag}.kwargs.{key}'")
    if "physics" in kwargs and kwargs["physics"] not in PHYSICS_PROFILES:
        raise SuiteError(f"{where}: field '{tag}.kwargs.physics' must be one of {', '.join(PHYSICS_PROFILES)}, "
                         f"got {show(kwargs['physics'])}")
    if "world" in kwargs:
        world_file = Path(_str(kwargs["world"], where, f"{tag}.kwargs.world"))
        if not world_file.is_absolute():  # relative to the suite file, as written in it
            world_file = Path(where).parent / world_file
        kwargs = {**kwargs, "world": str(world_file)}
    default_name = env.split("/")[-1].removeprefix("Warehouse").removesuffix("-v0").lower() or "scattered"
    count = _int(w.get("episodes", 0), where, f"{tag}.episodes", 0, 2**31 - 1)
    _limit(where, "suite_episodes", count, f"field '{tag}.episodes'")
    name = _str(w.get("name", default_name), where, f"{tag}.name")
    if "world_idx" in kwargs:
        if env != BARN_ENV_ID:
            raise SuiteError(f"{where}: field '{tag}.kwargs.world_idx' is for {BARN_ENV_ID} only, not {show(env)}")
        _barn_index(kwargs["world_idx"], where, f"{tag}.kwargs.world_idx")
    if "barn_worlds" not in w:
        return [WorldSpec(name, env, dict(kwargs), count)]
    if env != BARN_ENV_ID:
        raise SuiteError(f"{where}: field '{tag}.barn_worlds' is for env {BARN_ENV_ID} only, not {show(env)}")
    if "world_idx" in kwargs:
        raise SuiteError(f"{where}: field '{tag}.kwargs.world_idx' and field '{tag}.barn_worlds' both choose the "
                         "BARN world: give one")
    indices = barn_indices(w["barn_worlds"], where, f"{tag}.barn_worlds")
    return [WorldSpec(f"{name}-{i:03d}", env, {**kwargs, "world_idx": i}, count, barn_world=i, group=name)
            for i in indices]


def barn_indices(value: Any, where: str, field_: str) -> list[int]:
    """The BARN world indices a ``barn_worlds`` field names: a set of :data:`BARN_SETS` or a
    non-empty list of distinct indices 0-299 (in the list's order), as
    :func:`bulletnav.barn.data.world_pool` reads a pool.

    Raises:
        SuiteError: naming ``where``, the field (an index by its place in the list) and the value.
    """
    from bulletnav.barn.data import N_WORLDS, POOLS, world_pool

    if not (value in BARN_SETS if isinstance(value, str) else isinstance(value, list) and value):
        raise SuiteError(f"{where}: field '{field_}' must be one of {sorted(BARN_SETS)} or a non-empty list of BARN "
                         f"world indices 0-299, got {show(value)}")
    if isinstance(value, list):
        for k, v in enumerate(value):
            _barn_index(v, where, f"{field_}[{k}]")
    try:
        return list(world_pool(value, {**POOLS, "all": tuple(range(N_WORLDS))}, f"{where}: field '{field_}'"))
    except LayoutError as exc:
        raise SuiteError(str(exc)) from None


def _barn_index(value: Any, where: str, field_: str) -> int:
    return _int(value, where, field_, 0, 299)


def _parse_controller(c: Any, where: str, tag: str, trust_code: bool) -> ControllerSpec:
    """One ``controllers:`` entry."""
    c = _mapping(c, where, tag, {"name", "type", "planner", "model", "class", "kwargs", "shield", "params", "env"})
    kind = c.get("type")
    if kind not in CONTROLLER_TYPES:
        raise SuiteError(f"{where}: field '{tag}.type' must be one of {list(CONTROLLER_TYPES)}, got {show(kind)}")
    shield = c.get("shield", False)
    if not isinstance(shield, bool):
        raise SuiteError(f"{where}: field '{tag}.shield' must be true or false, got {show(shield)}")
    spec: dict[str, Any] = {"type": kind, "shield": shield}
    if "params" in c and kind != "dwa":
        raise SuiteError(f"{where}: field '{tag}.params' is for dwa controllers only, not {show(kind)}")
    if "env" in c:
        spec["env"] = _controller_env(c["env"], where, tag, kind)
    if kind == "dwa":
        spec["params"] = _dwa_params(c.get("params", ""), where, f"{tag}.params")
        default = "DWA" if spec["params"] in ("", "barn") else f"DWA ({Path(spec['params']).stem})"
    elif kind == "navigator":
        planner = c.get("planner", "astar")
        if planner not in PLANNERS:
            raise SuiteError(f"{where}: field '{tag}.planner' must be one of {list(PLANNERS)}, got {show(planner)}")
        spec["planner"] = planner
        default = {"none": "PID", "astar": "PID + A*", "rrt": "PID + RRT"}[planner]
    elif kind == "model":
        spec["model"] = _str(c.get("model"), where, f"{tag}.model")
        default = "PPO" if spec["model"] == "shipped" else Path(spec["model"]).stem
    else:
        target = _str(c.get("class"), where, f"{tag}.class")
        if target.count(":") != 1 or not all(target.split(":")):
            raise SuiteError(f"{where}: field '{tag}.class' must be 'module:Class', got {show(target)}")
        problem = None if trust_code else untrusted(target)
        if problem:
            raise SuiteError(f"{where}: field '{tag}.class' = {show(target)}: {problem}")
        spec["cls"] = target
        kwargs_ = c.get("kwargs") or {}
        spec["kwargs"] = dict(_mapping(kwargs_, where, f"{tag}.kwargs", set(kwargs_) if isinstance(kwargs_, dict) else set()))
        default = target.split(":")[1]
    name_ = _str(c.get("name", default + (" + shield" if shield else "")), where, f"{tag}.name")
    return ControllerSpec(name=name_, **spec)


def _controller_env(value: Any, where: str, tag: str, kind: str) -> dict[str, Any]:
    """A controller's ``env:``: keywords of :data:`CONTROLLER_ENV_KWARGS` whose values the env takes."""
    from bulletnav.envs.warehouse import make_config

    if kind == "model":
        raise SuiteError(f"{where}: field '{tag}.env' is for navigator, dwa and policy controllers: a model runs on "
                         "the env it was trained for")
    env = dict(_mapping(value, where, f"{tag}.env", set(CONTROLLER_ENV_KWARGS)))
    for key, v in env.items():
        try:
            make_config(**{key: v})
        except (TypeError, ValueError) as exc:
            raise SuiteError(f"{where}: field '{tag}.env.{key}' = {show(v)}: {exc}") from None
    return env


def _dwa_params(value: Any, where: str, field_: str) -> str:
    """A ``dwa`` controller's ``params``: a shipped set, or a file relative to the suite, read and
    checked now (a typo fails before any episode runs)."""
    from bulletnav.control.dwa_params import SHIPPED, load_dwa_params

    if value == "":
        return ""
    name = _str(value, where, field_)
    if name not in SHIPPED:
        path = Path(name)
        name = str(path if path.is_absolute() else Path(where).parent / path)
    try:
        load_dwa_params(name)
    except ConfigError as exc:
        raise SuiteError(f"{where}: field '{field_}' = {show(value)}: {exc}") from None
    return name


def untrusted(target: str) -> str | None:
    """Why the policy class ``module:Class`` may not be imported without ``--trust-code``
    (its module lies outside :data:`IMPORTABLE`), or None when it may."""
    module = target.partition(":")[0]
    if (module + ".").startswith(IMPORTABLE):
        return None
    allowed = ", ".join(m.rstrip(".") for m in IMPORTABLE)
    return (f"a suite may name policy classes of {allowed} only; pass --trust-code to import and run "
            f"the module {show(module)} (it runs that module's code)")


def replay_command(suite: Suite, world: WorldSpec, controller: ControllerSpec, seed: int, root: Path) -> str:
    """The shell command that replays episode ``seed`` of ``world`` with ``controller`` (the
    same env kwargs, the same seeded reset, the same shield): every argument in full and
    quoted for a POSIX shell (``shlex.split`` gives the arguments back)."""
    flags = ["--env", world.env]
    for key, value in world.kwargs.items():
        flags += [WORLD_KWARGS[key], str(value)]
    for key, value in controller.env.items():
        flags += [CONTROLLER_ENV_KWARGS[key], str(value)]
    flags += ["--seed", str(seed), "--episodes", "1"]
    if controller.shield:
        flags.append("--shield")
    if controller.type == "navigator":
        return shlex.join(["bulletnav", "navigate", "--planner", controller.planner, *flags, "--video", "episode.mp4"])
    if controller.type == "dwa":
        params = ["--dwa-params", controller.params] if controller.params else []
        return shlex.join(["bulletnav", "navigate", "--planner", "dwa", *params, *flags, "--video", "episode.mp4"])
    if controller.type == "model":
        path = controller.model_path(world.env, root)
        try:
            shown = path.relative_to(root)
        except ValueError:
            shown = path
        return shlex.join(["bulletnav", "evaluate", "--model", str(shown), *flags, "--video", "episode.mp4"])
    args = [repr(suite.source), repr(world.name), repr(controller.name), str(seed)]
    if suite.trust_code:
        args.append("trust_code=True")
    code = f"import json; from bulletnav.benchmark.runner import replay; print(json.dumps(replay({', '.join(args)})))"
    return shlex.join(["python", "-c", code])
