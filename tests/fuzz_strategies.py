"""Hypothesis strategies and settings profiles for tests/test_fuzz.py.

Profiles (``HYPOTHESIS_PROFILE`` selects one; ``ci`` when unset):

- ``ci``: derandomized (the same examples every run), each property's own bounded
  ``max_examples`` (:func:`examples`), so the fuzz file runs in well under a minute.
- ``fuzz``: random seeds, 20 times the examples (``make fuzz``).
"""

from __future__ import annotations

import os
from typing import Any

import yaml
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.register_profile("fuzz", derandomize=False, deadline=2000, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
settings.load_profile(PROFILE)
SCALE = 20 if PROFILE == "fuzz" else 1
"""Examples per property relative to the ``ci`` profile."""


def deadline(ms: int) -> int | None:
    """A property's hang guard: none in the ``ci`` profile (no timing assertion in ``make test``:
    a fresh clone compiles its numba kernels on first use), ``ms`` under ``fuzz``."""
    return ms if PROFILE == "fuzz" else None


def examples(n: int) -> int:
    """``max_examples`` of a property: ``n`` in the ``ci`` profile, ``20 n`` under ``fuzz``."""
    return n * SCALE


# --------------------------------------------------------------------------- values

HUGE = (10**30, -(10**30), 10**400, 2**63, -(2**63) - 1, 1e308, -1e308)

numbers = st.one_of(
    st.integers(min_value=-5, max_value=50),
    st.floats(min_value=-20.0, max_value=20.0, allow_nan=False),
    st.sampled_from([0, -1, 0.0, -0.0, float("nan"), float("inf"), float("-inf"), 1e-300, *HUGE]),
)
"""Mostly plausible numbers, with zeros, negatives, NaN, infinities and huge integers."""

scalars = st.one_of(
    st.none(), st.booleans(), numbers,
    st.text(max_size=12),
    st.sampled_from(["", "box", "forklift", "ppo", "nan", "1e999", "~", "yes", "null", "\x00", "é", "../..",
                     "lin_0.5", "lin_x", "bulletnav.nope.Class", "os:system"]),
)

keys = st.one_of(st.text(min_size=1, max_size=10), st.integers(-3, 3), st.booleans(), st.none(),
                 st.floats(allow_nan=False, max_value=9, min_value=-9))
"""Mapping keys as YAML can produce them: strings, but also ints, booleans, None and floats
(and mixed in one mapping, which ``sorted`` cannot order)."""

junk = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=4)),
    max_leaves=12,
)
"""Any YAML-representable value."""


def deep(depth: int, leaf: Any = 1) -> Any:
    """A list nested ``depth`` levels deep."""
    out = leaf
    for _ in range(depth):
        out = [out]
    return out


# --------------------------------------------------------------------------- mutations


def _containers(doc: Any, path: tuple = ()) -> list[tuple]:
    """Paths of every mapping and list inside ``doc`` (the root included)."""
    out = []
    if isinstance(doc, (dict, list)):
        out.append(path)
        items = doc.items() if isinstance(doc, dict) else enumerate(doc)
        for k, v in items:
            out.extend(_containers(v, (*path, k)))
    return out


def _at(doc: Any, path: tuple) -> Any:
    for k in path:
        doc = doc[k]
    return doc


@st.composite
def mutated(draw, base: st.SearchStrategy, max_mutations: int = 3) -> Any:
    """A well-formed document from ``base``, then 0 to ``max_mutations`` edits: a field dropped,
    replaced by junk (wrong type, NaN, huge, deep nesting), an unknown key added, a list
    entry duplicated."""
    import copy

    doc = copy.deepcopy(draw(base))
    for _ in range(draw(st.integers(0, max_mutations))):
        places = _containers(doc)
        if not places:
            break
        node = _at(doc, draw(st.sampled_from(places)))
        action = draw(st.sampled_from(["drop", "replace", "replace", "add", "dup", "deep"]))
        if isinstance(node, dict):
            if not node or action == "add":
                node[draw(keys)] = draw(junk)
                continue
            key = draw(st.sampled_from(sorted(node, key=repr)))
            if action == "drop":
                del node[key]
            elif action == "deep":
                node[key] = deep(draw(st.integers(2, 60)), node[key])
            else:
                node[key] = draw(junk)
        else:
            if not node or action == "add":
                node.append(draw(junk))
                continue
            i = draw(st.integers(0, len(node) - 1))
            if action == "drop":
                del node[i]
            elif action == "dup":
                node.extend([node[i]] * draw(st.integers(1, 3)))
            elif action == "deep":
                node[i] = deep(draw(st.integers(2, 60)), node[i])
            else:
                node[i] = draw(junk)
    return doc


# --------------------------------------------------------------------------- raw files

BILLION_LAUGHS = "\n".join(
    ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    + [f"{chr(98 + i)}: &{chr(98 + i)} [" + ",".join([f"*{chr(97 + i)}"] * 9) + "]" for i in range(8)]
    + ["size: *i", "obstacles: *i", "algo: *i", "grid: {x: *i}", "worlds: *i", "controllers: *i",
       "bulletnav/Warehouse-v0: {env_kwargs: {lidar_rays: *i}, randomize: *i, curriculum: *i}", ""])
"""Nine levels of nine aliases: 9^9 (387 M) strings if expanded; ``safe_load`` shares them,
but anything that walks or prints the structure (a ``repr`` in a message) would not end."""

HOSTILE = [
    BILLION_LAUGHS,
    "!!python/object/apply:os.system ['echo pwned']\n",
    "size: !!python/object/apply:builtins.eval ['10**10']\nobstacles: []\n",
    "algo: !!python/name:os.system\n",
    "!!python/object:bulletnav.config.EnvConfig {}\n",
    "[" * 3000 + "]" * 3000 + "\n",
    "{a: " * 2000 + "1" + "}" * 2000 + "\n",
    "- " * 2000 + "x\n",
    "&a [*a]\n",
    "a: *nope\n",
    "size: [10, 10]\nsize: [20, 20]\nobstacles: []\n",
    "? [1, 2]\n: x\n",
    "? {a: 1}\n: x\n",
    "--- 1\n--- 2\n",
    "\t\tsize: [1, 2]\n",
    "size: [1e999, 10]\nobstacles: []\n",
    "size: [.nan, 10]\n",
    "size: [10, 10]\nobstacles: [{type: box, center: [0, 0], size: [1, 1, 1e400]}]\n",
    "size: [10, 10]\nobstacles: {type: box}\n",
    "\ufeffsize: [10, 10]\n",
    "",
    "~\n",
    "%YAML 9.9\n---\na: 1\n",
    "!<tag:yaml.org,2002:int> x\n",
    "!!binary AAAA\n",
    "!!timestamp 2001-12-14\n",
    "x: !!set {a, b}\n",
    "<<: [*a]\n",
]
"""Hand-written hostile documents: an alias bomb, Python object tags (which ``safe_load``
refuses), 3000-deep nesting, recursive and undefined aliases, complex keys, duplicate keys,
overflowing floats, a BOM, odd directives and tags."""

NON_UTF8 = [b"size: [10, 10]\nname: \xff\xfe\xfa\n", b"\xff\xff\xff", b"\x80abc: 1\n",
            "size: [10, 10]\nname: caf\u00e9\n".encode("latin-1"), "a: b\n".encode("utf-16")]


def raw_files(documents: st.SearchStrategy) -> st.SearchStrategy[bytes]:
    """File contents: YAML dumps of ``documents``, hostile texts, non-UTF-8 bytes, random
    bytes, and dumps with a random byte flipped."""
    dumped = documents.map(lambda d: yaml.safe_dump(d, allow_unicode=True).encode())

    @st.composite
    def flipped(draw) -> bytes:
        data = bytearray(draw(dumped))
        if data:
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
        return bytes(data)

    return st.one_of(
        dumped, dumped, dumped, flipped(),
        st.sampled_from(HOSTILE).map(str.encode),
        st.sampled_from(NON_UTF8),
        st.binary(max_size=64),
        st.text(max_size=64).map(str.encode),
    )


# --------------------------------------------------------------------------- well-formed documents

point = st.tuples(st.floats(-4.5, 4.5), st.floats(-3.5, 3.5)).map(list)
box = st.fixed_dictionaries(
    {"type": st.just("box"), "center": point, "size": st.tuples(st.floats(0.1, 1.5), st.floats(0.1, 1.5),
                                                              st.floats(0.1, 2.0)).map(list)},
    optional={"yaw": st.floats(-3.2, 3.2), "label": st.sampled_from(["rack", "pallet", "box"])})
cylinder = st.fixed_dictionaries(
    {"type": st.just("cylinder"), "center": point, "radius": st.floats(0.05, 0.5), "height": st.floats(0.1, 3.0)},
    optional={"label": st.just("column")})
forklift = st.fixed_dictionaries(
    {"type": st.just("forklift"), "route": st.lists(point, min_size=2, max_size=4)},
    optional={"speed": st.floats(0.1, 2.0), "size": st.just([1.1, 0.8, 2.0]), "accel": st.floats(0.1, 3.0),
              "yield_to_robot": st.booleans()})
worker = st.fixed_dictionaries(
    {"type": st.just("worker"), "waypoints": st.lists(point, min_size=2, max_size=4)},
    optional={"speed": st.floats(0.1, 2.0), "radius": st.floats(0.1, 0.4), "pause": st.floats(0.0, 3.0),
              "height": st.floats(1.0, 2.0), "yield_to_robot": st.booleans()})
event = st.one_of(
    st.fixed_dictionaries({"at": st.floats(0.0, 60.0), "add": box}),
    st.fixed_dictionaries({"at": st.floats(0.0, 60.0), "remove": st.sampled_from(["rack", "pallet", "box", "nope"])}))

layouts = st.fixed_dictionaries(
    {"size": st.just([10.0, 8.0]), "obstacles": st.lists(st.one_of(box, cylinder), max_size=4)},
    optional={"name": st.text(max_size=8), "wall_height": st.floats(0.5, 3.0), "start": st.just([-4.0, -3.0, 0.0]),
              "goal": point, "goals": st.lists(point, min_size=1, max_size=3),
              "dynamic": st.lists(st.one_of(forklift, worker), max_size=3), "events": st.lists(event, max_size=3)})
"""Layout documents (``bulletnav.sim.layout``), many of them valid."""

sweeps = st.fixed_dictionaries(
    {"algo": st.sampled_from(["ppo", "sac", "td3", "a2c"])},
    optional={"name": st.sampled_from(["s", "my_sweep"]), "env_id": st.just("bulletnav/Warehouse-v0"),
              "env_kwargs": st.just({"num_obstacles": 10}), "timesteps": st.integers(1, 10**6),
              "seeds": st.lists(st.integers(0, 100), min_size=1, max_size=5, unique=True),
              "grid": st.dictionaries(st.sampled_from(["learning_rate", "n_steps", "env_kwargs.reward_collision"]),
                                      st.lists(numbers, min_size=1, max_size=3), max_size=2),
              "search": st.dictionaries(st.sampled_from(["gamma", "batch_size"]), st.one_of(
                  st.just({"uniform": [0.9, 0.99]}), st.just({"loguniform": [1e-5, 1e-3]}),
                  st.just({"randint": [1, 8]}), st.just({"choice": [64, 128]})), max_size=2),
              "early_stopping": st.just({"scheduler": "asha", "grace_period": 1000, "reduction_factor": 2}),
              "resources": st.just({"cpu": 1}), "n_envs": st.integers(1, 8),
              "vec_env": st.sampled_from(["dummy", "subproc"]), "eval_freq": st.integers(1, 10**5),
              "eval_episodes": st.integers(1, 50), "checkpoint_freq": st.integers(1, 10**5),
              "evaluation": st.just({"episodes": 20, "seed": 1000}),
              "metric": st.sampled_from(["success_rate", "spl"]), "mode": st.sampled_from(["max", "min"])})
"""Sweep documents (``bulletnav.sweep.spec``)."""

ENV_ID = "bulletnav/Warehouse-v0"
hyperparams = st.fixed_dictionaries({ENV_ID: st.fixed_dictionaries(
    {"n_envs": st.integers(1, 8)},
    optional={"policy": st.sampled_from(["MlpPolicy", "bulletnav.rl.policies.ClearanceActorCriticPolicy"]),
              "n_timesteps": st.integers(1, 10**6), "learning_rate": st.sampled_from([3e-4, "lin_3e-4"]),
              "env_kwargs": st.just({"normalize_actions": True, "reward_collision": -20.0}),
              "normalize": st.just({"norm_obs": False, "norm_reward": True}),
              "collision_terminal": st.booleans(),
              "randomize": st.just({"shift_mass_scale": {"uniform": [0.8, 1.2]}}),
              "curriculum": st.just({"stages": [{"num_obstacles": 10}, {"num_obstacles": 20}]}),
              "policy_kwargs": st.just({"net_arch": [64, 64]})})})
"""Hyperparameter documents (``bulletnav.rl.hyperparams``; RL Zoo's format keyed by env id)."""

suites = st.fixed_dictionaries(
    {"worlds": st.lists(st.fixed_dictionaries(
        {"env": st.sampled_from(["bulletnav/Warehouse-v0", "bulletnav/WarehouseMission-v0", "CartPole-v1"])},
        optional={"name": st.text(min_size=1, max_size=6), "episodes": st.integers(0, 30),
                  "kwargs": st.fixed_dictionaries({}, optional={"num_obstacles": st.integers(0, 60),
                                                                "goals": st.integers(1, 4),
                                                                "perturb": st.just("slippery"),
                                                                "world": st.just("nope.yaml")})}),
        min_size=1, max_size=3),
     "controllers": st.lists(st.one_of(
         st.fixed_dictionaries({"type": st.just("navigator")}, optional={"planner": st.sampled_from(["none", "astar", "rrt"]),
                                                                         "shield": st.booleans()}),
         st.fixed_dictionaries({"type": st.just("model"), "model": st.just("shipped")}, optional={"name": st.just("m")}),
         st.fixed_dictionaries({"type": st.just("policy"), "class": st.just("mypkg.mod:MyPolicy")},
                               optional={"kwargs": st.just({"gain": 2.0})})), min_size=1, max_size=3)},
    optional={"name": st.text(min_size=1, max_size=6), "episodes": st.integers(1, 50), "seed": st.integers(0, 10**6),
              "description": st.text(max_size=10)})
"""Benchmark suite documents (``bulletnav.benchmark.suite``)."""
