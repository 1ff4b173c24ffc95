"""Property-based fuzzing of every input a user feeds bulletnav (Hypothesis).

Each property: any input gives a result or the project's own error with a non-empty message,
never another exception from deep inside, never a hang (Hypothesis ``deadline`` under
``make fuzz``; none in ``make test``, which asserts no timing), never a physics-server crash. The expected errors, per parser:

| input | function | result or |
|---|---|---|
| layout / world YAML | ``sim.layout.load_layout`` | ``LayoutError`` naming the file |
| sweep file | ``sweep.spec.SweepSpec.from_file`` | ``ConfigError`` naming the file |
| hyperparameter file | ``rl.hyperparams.load_hyperparams`` | ``ConfigError`` naming the file |
| benchmark suite | ``benchmark.suite.load_suite`` | ``SuiteError`` naming the file |
| env kwargs | ``gym.make("bulletnav/Warehouse-v0", **kwargs)`` | ``TypeError`` / ``ValueError`` naming the keyword |
| reset options, actions | ``env.reset(options=...)``, ``env.step`` | ``ValueError`` naming the option / the action |
| CLI argv | ``bulletnav.cli.main`` | an exit status, or argparse's ``SystemExit`` |

Examples per property are in each docstring (the ``ci`` profile, derandomized);
``HYPOTHESIS_PROFILE=fuzz`` (``make fuzz``) runs 20 times as many on random seeds.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import itertools
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
import yaml
from hypothesis import event, example, given, settings
from hypothesis import strategies as st
from hypothesis.control import currently_in_test_context

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.benchmark.suite import SuiteError, load_suite
from bulletnav.errors import BulletnavError, ConfigError, LayoutError
from bulletnav.rl.hyperparams import load_hyperparams
from bulletnav.sim.layout import load_layout
from bulletnav.sweep.spec import SweepSpec
from fuzz_strategies import (
    BILLION_LAUGHS,
    ENV_ID,
    deadline,
    examples,
    hyperparams,
    junk,
    keys,
    layouts,
    mutated,
    numbers,
    raw_files,
    scalars,
    suites,
    sweeps,
)

TMP = Path(tempfile.mkdtemp(prefix="bulletnav-fuzz-"))
"""One directory for the files the properties write (Hypothesis runs many examples per test,
so pytest's function-scoped ``tmp_path`` would be shared anyway)."""


def _write(data: bytes, name: str = "doc.yaml") -> Path:
    path = TMP / name
    path.write_bytes(data)
    return path


def _expect(exc: BaseException, kinds: tuple[type[BaseException], ...], path: Path | None = None) -> None:
    """``exc`` is one of ``kinds`` with a message of at most a few kB (never a whole alias
    bomb printed), naming ``path`` when given."""
    if not isinstance(exc, kinds):
        raise exc
    if currently_in_test_context():
        event(f"refused: {type(exc).__name__}")
    message = str(exc)
    assert message.strip(), f"{type(exc).__name__} with an empty message"
    assert len(message) < 20_000, f"a {len(message)}-character message"
    if path is not None:
        assert str(path) in message, f"the message does not name the file: {message}"


# --------------------------------------------------------------------------- files


@settings(max_examples=examples(300))
@given(raw_files(mutated(layouts)))
# inputs that once failed (kept as regressions): UnicodeDecodeError, RecursionError after 2 s,
# ValueError from PyYAML's int constructor, TypeError from a list as a mover type
@pytest.mark.slow
@example(b"size: [10, 10]\nname: \xff\xfe\xfa\n")
@example(b"[" * 3000 + b"]" * 3000)
@example(b"!<tag:yaml.org,2002:int> x\n")
@example(b"size: [10.0, 8.0]\ndynamic:\n- {type: [], waypoints: [[0, 0], [0, 1]]}\n")
def test_layout_files(data):
    """examples: 300. A layout file (with ``dynamic:``, ``events:``, ``goals:``) loads or
    fails with a LayoutError naming the file."""
    path = _write(data, "layout.yaml")
    try:
        layout = load_layout(path)
    except Exception as exc:  # noqa: BLE001  (the property is about the type)
        _expect(exc, (LayoutError,), path)
        return
    event("loaded")
    assert len(layout.size) == 2 and all(np.isfinite(layout.size))
    for obs in layout.obstacles:
        assert np.isfinite(obs.center).all()


@settings(max_examples=examples(200))
@given(raw_files(mutated(sweeps)))
@example(b"(:\nnull:")  # keys of two types: sorted() raised TypeError
@example(("algo: ppo\nseeds: [0, 1]\ngrid: {" + ", ".join(f"k{i}: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]" for i in range(20))
          + "}\n").encode())  # 10^20 configurations: refused before they are expanded
def test_sweep_files(data):
    """examples: 200. A sweep file parses or fails with a ConfigError naming the file; a
    parsed one has a finite number of trials within the limit."""
    path = _write(data, "sweep.yaml")
    try:
        spec = SweepSpec.from_file(path)
    except Exception as exc:  # noqa: BLE001
        _expect(exc, (ConfigError,), path)
        return
    event("loaded")
    assert len(spec.configurations()) * len(spec.seeds) <= 10_000
    assert SweepSpec.from_record(spec.to_dict()) == spec


@settings(max_examples=examples(150))
@given(raw_files(mutated(hyperparams)))
@example(BILLION_LAUGHS.encode())  # a repr in parse_randomize's message ran out of memory
@example(b"bulletnav/Warehouse-v0:\n  collision_terminal: false\n  env_kwargs: '0'\n")  # dict('0'): ValueError
@example(b"bulletnav/Warehouse-v0:\n  n_envs: 1\n  0: 1\n")  # PPO(..., **{0: 1}): TypeError in training
@example(b"bulletnav/Warehouse-v0:\n  n_envs: null\n")  # int(None): TypeError in training
def test_hyperparameter_files(data):
    """examples: 150. A hyperparameter file loads (a mapping) or fails with a ConfigError
    naming the file."""
    path = _write(data, "hyper.yml")
    try:
        hp = load_hyperparams("ppo", ENV_ID, path)
    except Exception as exc:  # noqa: BLE001
        _expect(exc, (ConfigError,), path)
        return
    event("loaded")
    assert isinstance(hp, dict)


@settings(max_examples=examples(150))
@given(raw_files(mutated(suites)))
@example(b"controllers:\n- {class: 'mypkg.mod:MyPolicy', kwargs: [[{}]], type: policy}\nworlds:\n- env: bulletnav/Warehouse-v0\n")
def test_benchmark_suite_files(data):
    """examples: 150. A suite file parses or fails with a SuiteError naming the file."""
    path = _write(data, "suite.yaml")
    try:
        suite = load_suite(str(path))
    except Exception as exc:  # noqa: BLE001
        _expect(exc, (SuiteError,), path)
        return
    event("loaded")
    assert suite.total >= 1 and suite.worlds and suite.controllers


# --------------------------------------------------------------------------- env kwargs

KNOWN_KWARGS = ["num_obstacles", "world_size", "min_goal_distance", "max_goal_distance", "lidar_rays", "lidar_range",
                "lidar_noise", "lidar_caster", "imu_accel_noise", "imu_gyro_noise", "odometry_noise", "physics_hz", "control_hz",
                "solver_iterations", "goal_radius", "pose_source", "collision_terminates", "layout_style",
                "lidar_rate_hz", "camera_enabled", "task_name", "layouts_every", "camera_obs", "normalize_actions",
                "min_detour", "blocked_by", "detour_share", "aisles", "lidar_history", "guidance", "goals", "goal_order",
                "steps_per_goal", "forklifts", "workers", "forklift_speed", "worker_speed", "pallet_events_per_min",
                "yield_to_robot", "world", "config", "render_mode", "perturb", "randomize", "physics",
                "reward_collision", "reward_goal", "shift_mass_scale", "shift_action_latency", "shift_imu_accel_bias"]

env_kwargs = st.dictionaries(
    st.one_of(st.sampled_from(KNOWN_KWARGS), st.text(min_size=1, max_size=8).filter(str.isidentifier)),
    st.one_of(junk, st.tuples(numbers, numbers), st.sampled_from([("rack",), (3, 5), "mission", "aisles", "fast",
                                                                   "slippery", "floorplan", "odometry"])),
    max_size=3)


plausible_kwargs = st.fixed_dictionaries({}, optional={
    "num_obstacles": st.integers(0, 25), "lidar_rays": st.integers(1, 72), "world_size": st.tuples(st.floats(6, 20),
                                                                                                     st.floats(6, 20)),
    "lidar_noise": st.floats(0, 0.2), "lidar_caster": st.sampled_from(["bullet", "exact"]),
    "task_name": st.sampled_from(["navigation", "mission"]), "goals": st.integers(1, 3),
    "forklifts": st.integers(0, 2), "workers": st.integers(0, 2), "pallet_events_per_min": st.floats(0, 5),
    "layout_style": st.sampled_from(["scattered", "aisles"]), "camera_enabled": st.booleans(),
    "normalize_actions": st.booleans(), "perturb": st.sampled_from([None, "slippery", "laggy"]),
    "physics": st.sampled_from(["default", "fast"]), "lidar_history": st.integers(1, 3),
    "guidance": st.sampled_from(["none", "floorplan"]), "reward_collision": st.floats(-50, 0)})
"""Keywords with plausible values: most of these build a working env."""


def _check_kwargs_error(exc: BaseException, kwargs: dict) -> None:
    _expect(exc, (TypeError, ValueError))
    message = str(exc)
    assert any(k in message or k.replace("_", " ") in message for k in kwargs) or "bulletnav/Warehouse-v0" in message \
        or any(part in message for k in kwargs for part in k.split("_") if len(part) > 3), \
        f"{type(exc).__name__} names none of {sorted(kwargs)}: {message}"


@settings(max_examples=examples(300))
@given(env_kwargs)
@example({"lidar_rays": "abc"})  # TypeError "'<' not supported between 'str' and 'int'"
@example({"world_size": None})  # TypeError "'NoneType' object is not iterable"
@example({"config": (0, 0), "task_name": "mission"})  # TypeError "replace() should be called on dataclass instances"
@example({"shift_imu_accel_bias": (0, 10**400)})  # OverflowError
def test_env_kwargs_config(kwargs):
    """examples: 300. ``make_config(**kwargs)`` (what the env's constructor runs first, no
    world built) returns a config or raises TypeError / ValueError naming the keyword."""
    from bulletnav.envs.warehouse import make_config

    try:
        make_config(**{k: v for k, v in kwargs.items() if k != "render_mode"})
    except Exception as exc:  # noqa: BLE001
        _check_kwargs_error(exc, kwargs)


@settings(max_examples=examples(15), deadline=deadline(10_000))
@given(st.one_of(plausible_kwargs, plausible_kwargs, env_kwargs).filter(
    # gym.make itself reads render_mode (and calls str methods on it) before the env sees it
    lambda kw: kw.get("render_mode") is None or isinstance(kw["render_mode"], str) and kw["render_mode"] != "human"))
def test_env_kwargs_make_reset_step(kwargs):
    """examples: 15 (two thirds with plausible values; each may build a PyBullet world). ``gym.make`` with random keywords
    builds an env that resets and steps, or raises TypeError / ValueError naming the
    keyword; the physics server stays connected."""
    try:
        env = gym.make(ENV_ID, disable_env_checker=True, **kwargs)
    except Exception as exc:  # noqa: BLE001
        _check_kwargs_error(exc, kwargs)
        event(f"refused: {type(exc).__name__}")
        return
    event("built")
    try:
        obs, _ = env.reset(seed=0)
        env.step(env.action_space.sample())
        event("reset and stepped")
        assert p.isConnected(physicsClientId=env.unwrapped._scene.cid)
    except BulletnavError:  # e.g. no start/goal pair fits a tiny floor: the project's own error
        pass
    finally:
        env.close()


# --------------------------------------------------------------------------- actions and reset options

actions = st.one_of(
    st.lists(numbers, min_size=2, max_size=2).map(lambda a: np.asarray(a)),
    st.lists(numbers, min_size=2, max_size=2).map(lambda a: np.asarray(a, dtype=object)),
    st.lists(numbers, max_size=4),
    st.tuples(numbers, numbers),
    st.lists(st.floats(width=32, allow_nan=True), min_size=2, max_size=2).map(lambda a: np.asarray(a, np.float32)),
    st.sampled_from([np.zeros((2, 1)), np.zeros((1, 2)), np.zeros(3), np.zeros(0), np.array([1, 2], np.int8),
                     np.array([True, False]), np.array([1 + 2j, 0]), np.array(["a", "b"]), np.array([2**62, -2**62]),
                     np.array([1e308, -1e308]), {"v": 0.1}, "0.1 0.2", b"\x00\x01", None, 0.3, [[0.1, 0.2]],
                     [0.1, "x"], [0.1, None], np.ma.masked_array([0.1, 0.2], [True, False])]),
    junk,
)


@pytest.fixture(scope="module")
def env():
    env = gym.make(ENV_ID, num_obstacles=10, camera_enabled=False, disable_env_checker=True)
    env.reset(seed=0)
    yield env
    env.close()


def _stepped(env, action) -> None:
    try:
        obs, reward, terminated, truncated, info = env.step(action)
    except Exception as exc:  # noqa: BLE001
        _expect(exc, (ValueError,))
        assert "action" in str(exc), str(exc)
        event("refused")
        return
    event("stepped")
    assert np.isfinite(obs).all() and np.isfinite(reward)
    if terminated or truncated:
        env.reset()


@settings(max_examples=examples(200))
@given(actions=st.lists(actions, min_size=1, max_size=4))
@example(actions=[[2**70, 0]])  # OverflowError from np.asarray
def test_actions(env, actions):
    """examples: 200 (sequences of up to 4 steps). ``env.step`` with NaN / infinite / huge
    values, wrong shapes and dtypes takes a valid step or raises a ValueError naming the
    action; the physics server never dies."""
    for action in actions:
        _stepped(env, action)
    assert p.isConnected(physicsClientId=env.unwrapped._scene.cid)


reset_options = st.one_of(
    st.dictionaries(st.sampled_from(["start", "goal", "goals"]), st.one_of(junk, st.lists(numbers, max_size=4)),
                    max_size=2),
    st.dictionaries(keys, junk, max_size=2),
    junk,
)


@settings(max_examples=examples(60), deadline=deadline(5000))
@given(options=reset_options)
@example(options=True)  # TypeError "argument of type 'bool' is not iterable"
@example(options={"goal": [10**400, 0]})  # OverflowError
def test_reset_options(env, options):
    """examples: 60. ``env.reset(options=...)`` with random start / goal values resets or
    raises a ValueError (or the project's SamplingError) naming the option."""
    try:
        env.reset(options=options)
    except Exception as exc:  # noqa: BLE001
        _expect(exc, (ValueError, TypeError, BulletnavError))
        assert "option" in str(exc) or isinstance(exc, BulletnavError), str(exc)
        env.reset(seed=0)
    assert p.isConnected(physicsClientId=env.unwrapped._scene.cid)


# --------------------------------------------------------------------------- CLI


class _Reached(Exception):
    """Raised where a command would start real work (an env reset, a sweep, a benchmark): the
    arguments got that far without an unexpected error."""


_RUNS = itertools.count()
COMMANDS = ["navigate", "train", "sweep", "evaluate", "compare", "demo", "view", "benchmark", "bench"]
FLAGS = ["--episodes", "--seed", "--obstacles", "--planner", "--pose", "--json", "--algo", "--timesteps", "--n-envs",
         "--out", "--resume", "--eval-freq", "--vec-env", "--hyperparams", "--model", "--world", "--goals", "--order",
         "--perturb", "--physics", "--shield", "--optimize", "--num-cpus", "--workers", "--report-only",
         "--group-by", "--steps", "--rates", "--seconds", "-v", "-h", "--bogus", "--"]
token = st.one_of(st.sampled_from(FLAGS), st.sampled_from(COMMANDS), scalars.map(str),
                  st.sampled_from(["astar", "ppo", "-1", "0", "1", "1e9", "99999999999999999999", "nan", "fast",
                                   "slippery", "free", "fixed", "env", "physics", "240,0", "a,b", "quick"]))


@st.composite
def argvs(draw):
    """An argv whose run stops early: every command that would drive envs gets an env id that
    is not registered, a layout that is invalid, or a missing model, or its real work is
    patched to raise :class:`_Reached` (sweeps, benchmarks, env resets)."""
    files = {"layout": _write(draw(raw_files(mutated(layouts))), "cli-layout.yaml"),
             "sweep": _write(draw(raw_files(mutated(sweeps))), "cli-sweep.yaml"),
             "suite": _write(draw(raw_files(mutated(suites))), "cli-suite.yaml"),
             "hyper": _write(draw(raw_files(mutated(hyperparams))), "cli-hyper.yml")}
    command = draw(st.sampled_from([*COMMANDS, "nope", ""]))
    rest = draw(st.lists(token, max_size=6))
    poison = {
        "navigate": [["--world", str(files["layout"])], ["--env", "bulletnav/Nope-v0"]],
        "evaluate": [["--model", str(TMP / "missing.zip")], ["--world", str(files["layout"])]],
        "demo": [["--model", str(TMP / "missing.zip")], ["--env", "bulletnav/Nope-v0"]],
        # training envs in this process (--vec-env dummy), where resets are patched, in a new directory
        "train": [["--out", str(TMP / f"run{next(_RUNS)}"), "--vec-env", "dummy", "--hyperparams", str(files["hyper"])],
                  ["--env", "CartPole-v1"]],
        "sweep": [[str(files["sweep"]), "--out", str(TMP / "sweeps")]],
        "benchmark": [[str(files["suite"]), "--out", str(TMP / "bench")], ["quick", "--report-only", "--out", str(TMP)]],
        "compare": [[str(TMP / "no-run")]],
        "view": [["--env", "bulletnav/Nope-v0"]],
        "bench": [["env", "--env", "bulletnav/Nope-v0"], ["planners", "--env", "Nope-v0"]],
    }.get(command, [[]])
    rest = [t for t in rest if t not in ("--gui", "--resume", "--screenshots", "--vec-env", "--init-from")]
    return [t for t in [command] if t] + draw(st.sampled_from(poison)) + rest


@settings(max_examples=examples(80), deadline=deadline(10_000))
@given(argv=argvs())
def test_cli_arguments(argv, monkeypatch_session):
    """examples: 80. ``bulletnav.cli.main(argv)`` returns an exit status (an error as one
    ``bulletnav <command>: error: ...`` message) or exits through argparse; nothing else."""
    from bulletnav import cli

    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = cli.main(argv)
    except SystemExit as exc:
        assert exc.code in (0, 2), exc.code  # argparse: --help, or a usage error
        event(f"argparse exit {exc.code}")
        return
    except _Reached:
        event("reached real work")
        return
    assert isinstance(status, int)
    event(f"status {status}")
    if status == 2:
        assert err.getvalue().startswith(f"bulletnav {argv[0]}: error: "), err.getvalue()


@pytest.fixture(scope="module")
def monkeypatch_session():
    """Real work (env resets, training, sweeps, benchmarks) replaced by :class:`_Reached` for the CLI property (module-scoped, as
    Hypothesis reuses one fixture value for all examples)."""
    import bulletnav.evaluation  # noqa: F401  (torch and SB3 imported once here, not inside a timed example)
    from bulletnav.benchmark import runner
    train = importlib.import_module("bulletnav.rl.train")
    from bulletnav.envs.warehouse import WarehouseEnv
    from bulletnav.sweep import run

    def reached(*args, **kwargs):
        raise _Reached

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(WarehouseEnv, "reset", reached)
        mp.setattr(run, "run_sweep", reached)
        mp.setattr(runner, "run_suite", reached)
        mp.setattr(train, "train", reached)  # the hyperparameter file is test_hyperparameter_files' subject
        yield mp


def test_hostile_documents_are_refused_by_every_loader():
    """The hand-written hostile documents (alias bomb, Python tags, deep nesting, non-UTF-8)
    through each loader: each refuses them with its own error type, quickly."""
    from fuzz_strategies import HOSTILE, NON_UTF8

    for i, doc in enumerate([d.encode() for d in HOSTILE] + NON_UTF8):
        path = _write(doc, f"hostile{i}.yaml")
        for load, kind in ((load_layout, LayoutError), (SweepSpec.from_file, ConfigError),
                           (lambda q: load_hyperparams("ppo", ENV_ID, q), ConfigError),
                           (lambda q: load_suite(str(q)), SuiteError)):
            try:
                load(path)
            except Exception as exc:  # noqa: BLE001
                _expect(exc, (kind,), path)
    tag = _write(b"!!python/object/apply:os.system ['touch pwned']\n", "tag.yaml")
    with pytest.raises(LayoutError, match="not valid YAML"):
        load_layout(tag)
    assert yaml.safe_load("a: 1") == {"a": 1}
