"""Resource limits (bulletnav.limits): each refused just above, accepted at the limit, raised by
its environment variable; and wired into the places values enter (env kwargs, layout files,
sweep files, benchmark suites, mission goals)."""

from __future__ import annotations

import re
from dataclasses import fields

import pytest
import yaml

from bulletnav import limits
from bulletnav.config import CameraConfig, DynamicConfig, LidarConfig, TaskConfig, WorldConfig
from bulletnav.errors import BulletnavError, ConfigError, LayoutError, LimitError
from bulletnav.limits import Limits, env_var

D = Limits()

# The defaults and variables as docs/limits.md publishes them, written out by hand: the
# boundary tests below are held to these numbers, not to the values the module reads itself.
SPEC = {
    "world_size": (200.0, "BULLETNAV_MAX_WORLD_SIZE"), "obstacles": (1000, "BULLETNAV_MAX_OBSTACLES"),
    "movers": (64, "BULLETNAV_MAX_MOVERS"), "events": (1000, "BULLETNAV_MAX_EVENTS"),
    "event_rate": (600.0, "BULLETNAV_MAX_EVENT_RATE"), "lidar_rays": (4096, "BULLETNAV_MAX_LIDAR_RAYS"),
    "camera_width": (4096, "BULLETNAV_MAX_CAMERA_WIDTH"), "camera_height": (4096, "BULLETNAV_MAX_CAMERA_HEIGHT"),
    "camera_pixels": (8_388_608, "BULLETNAV_MAX_CAMERA_PIXELS"), "episode_steps": (100_000, "BULLETNAV_MAX_EPISODE_STEPS"),
    "goals": (8, "BULLETNAV_MAX_GOALS"), "sweep_trials": (10_000, "BULLETNAV_MAX_SWEEP_TRIALS"),
    "suite_episodes": (100_000, "BULLETNAV_MAX_SUITE_EPISODES"), "suite_worlds": (64, "BULLETNAV_MAX_SUITE_WORLDS"),
    "suite_controllers": (64, "BULLETNAV_MAX_SUITE_CONTROLLERS"), "suite_total": (1_000_000, "BULLETNAV_MAX_SUITE_TOTAL"),
    "map_extent": (1000.0, "BULLETNAV_MAX_MAP_EXTENT"), "map_cells": (16_777_216, "BULLETNAV_MAX_MAP_CELLS"),
    "net_width": (4096, "BULLETNAV_MAX_NET_WIDTH"), "net_layers": (16, "BULLETNAV_MAX_NET_LAYERS"),
    "n_steps": (1_048_576, "BULLETNAV_MAX_N_STEPS"), "batch_size": (1_048_576, "BULLETNAV_MAX_BATCH_SIZE"),
    "buffer_size": (5_000_000, "BULLETNAV_MAX_BUFFER_SIZE"), "n_envs": (256, "BULLETNAV_MAX_N_ENVS"),
    "fleet_robots": (16, "BULLETNAV_MAX_FLEET_ROBOTS"), "fleet_duration": (3600.0, "BULLETNAV_MAX_FLEET_DURATION"),
}

CASES = {
    # limit -> (build with value v, the field as the message names it, a value just above the limit)
    "world_size": (lambda v: WorldConfig(size=(v, 10.0)), "world size (x)", D.world_size + 0.5),
    "obstacles": (lambda v: WorldConfig(num_obstacles=v), "world num_obstacles", D.obstacles + 1),
    "movers": (lambda v: DynamicConfig(forklifts=(0, v // 2), workers=(0, v - v // 2)), "dynamic forklifts + workers",
               D.movers + 1),
    "events": (lambda v: DynamicConfig(event_pallets=v), "dynamic event_pallets", D.events + 1),
    "event_rate": (lambda v: DynamicConfig(pallet_events_per_min=v), "dynamic pallet_events_per_min",
                   D.event_rate + 0.5),
    "lidar_rays": (lambda v: LidarConfig(num_rays=v), "lidar num_rays", D.lidar_rays + 1),
    "camera_width": (lambda v: CameraConfig(width=v, height=16), "camera width", D.camera_width + 1),
    "camera_height": (lambda v: CameraConfig(width=16, height=v), "camera height", D.camera_height + 1),
    "camera_pixels": (lambda v: CameraConfig(width=4096, height=v // 4096), "camera pixels (4096 x",
                      D.camera_pixels + 4096),
    "episode_steps": (lambda v: TaskConfig(steps_per_goal=v), "task steps_per_goal x goals", D.episode_steps + 1),
    "goals": (lambda v: TaskConfig(goals=v, steps_per_goal=100), "task goals", D.goals + 1),
    "sweep_trials": (lambda v: _sweep(v), "sweep trials (grid configurations x seeds)", D.sweep_trials + 1),
    "suite_episodes": (lambda v: _suite(episodes=v), "field 'episodes'", D.suite_episodes + 1),
    "suite_worlds": (lambda v: _suite(worlds=v), "field 'worlds' (entries)", D.suite_worlds + 1),
    "suite_controllers": (lambda v: _suite(controllers=v), "field 'controllers' (entries)", D.suite_controllers + 1),
    "suite_total": (lambda v: _suite(total=v), "episodes in all", D.suite_total + 1),
    "map_extent": (lambda v: _mapper((0.0, 0.0, v, 1.0), 1.0), "map extent (x)", D.map_extent + 0.5),
    # 2^-15 m cells (exact in binary): v cells in a row, 512 m at the limit
    "map_cells": (lambda v: _mapper((0.0, 0.0, v * 2.0**-15, 2.0**-15), 2.0**-15), "map cells (", D.map_cells + 1),
    "net_width": (lambda v: _sizes({"net_arch": {"pi": [64, v]}}, {}), "m.json: net_arch['pi'] width", D.net_width + 1),
    "net_layers": (lambda v: _sizes({"net_arch": [64] * v}, {}), "m.json: net_arch layers", D.net_layers + 1),
    "n_steps": (lambda v: _sizes({}, {"n_steps": v}), "m.json: n_steps", D.n_steps + 1),
    "batch_size": (lambda v: _sizes({}, {"batch_size": v}), "m.json: batch_size", D.batch_size + 1),
    "buffer_size": (lambda v: _sizes({}, {"buffer_size": v}), "m.json: buffer_size", D.buffer_size + 1),
    "n_envs": (lambda v: _sizes({}, {"n_envs": v}), "m.json: n_envs", D.n_envs + 1),
    "fleet_robots": (lambda v: _fleet(num_robots=v), "fleet num_robots", D.fleet_robots + 1),
    "fleet_duration": (lambda v: _fleet(duration_s=v), "fleet duration_s", D.fleet_duration + 0.5),
}


def _suite(episodes=1, worlds=1, controllers=1, total=None):
    from bulletnav.benchmark.suite import parse_suite

    if total is not None:  # worlds of at most suite_episodes each, summing to `total`
        sizes = [D.suite_episodes] * (total // D.suite_episodes) + ([total % D.suite_episodes] if total % D.suite_episodes else [])
        world_list = [{"name": f"w{i}", "env": "bulletnav/Warehouse-v0", "episodes": n} for i, n in enumerate(sizes)]
    else:
        world_list = [{"name": f"w{i}", "env": "bulletnav/Warehouse-v0"} for i in range(worlds)]
    return parse_suite({"episodes": episodes, "worlds": world_list,
                        "controllers": [{"name": f"c{i}", "type": "navigator"} for i in range(controllers)]}, "s.yaml")


def _mapper(bounds, resolution):
    from bulletnav.planning.mapping import LidarMapper

    return LidarMapper(bounds, resolution)


def _sizes(kwargs, hyper):
    from bulletnav.rl.safe import check_sizes

    check_sizes(kwargs, hyper, "m.json")


def _fleet(**kwargs):
    from bulletnav.fleet.config import FleetConfig

    return FleetConfig(**kwargs)


def _sweep(trials: int):
    from bulletnav.sweep.spec import SweepSpec

    # trials = 10 configurations x seeds; the grid is never expanded by the check
    return SweepSpec.from_dict({"algo": "ppo", "grid": {"learning_rate": list(range(10))},
                                "seeds": list(range(trials // 10 + (trials % 10 > 0)))})


def test_every_limit_has_a_case_and_a_documented_row():
    names = [f.name for f in fields(Limits)]
    assert sorted(CASES) == sorted(names) == sorted(SPEC)
    page = open("docs/limits.md").read()
    for name in names:
        assert f"`{env_var(name)}`" in page, name
        assert f"`{name}`" in page, name
    # Each documented row states the hand-written default and variable; the module agrees.
    rows = {m[1]: (m[2], m[3]) for m in re.finditer(r"^\| `(\w+)` \| ([\d,]+) \| [^|]+ \| `(\w+)` \|", page, re.M)}
    for name, (default, var) in SPEC.items():
        assert rows[name] == (f"{default:,.0f}", var), name
        assert getattr(D, name) == default and type(getattr(D, name)) is type(default) and env_var(name) == var, name


@pytest.mark.parametrize("name", sorted(CASES))
def test_accepted_at_the_limit(name):
    build, _, _ = CASES[name]
    build(SPEC[name][0])  # the documented default itself passes


@pytest.mark.parametrize("name", sorted(CASES))
def test_refused_just_above_with_field_value_limit_and_variable(name):
    build, what, above = CASES[name]
    with pytest.raises((LimitError, ConfigError)) as err:
        build(above)
    message = str(err.value)
    assert isinstance(err.value, BulletnavError) and isinstance(err.value, ValueError)
    assert what in message
    assert f"exceeds the limit {getattr(D, name)} (raise it with {env_var(name)})" in message
    limit, var = SPEC[name]
    reported = 10_010 if name == "sweep_trials" else above  # the sweep case rounds up to whole seeds of 10 configurations
    assert message.endswith(f" = {reported} exceeds the limit {limit} (raise it with {var})")


@pytest.mark.parametrize("name", sorted(CASES))
def test_raised_by_its_environment_variable(name, monkeypatch):
    build, _, above = CASES[name]
    assert env_var(name) == SPEC[name][1]
    monkeypatch.setenv(SPEC[name][1], str(above * 2 if name != "camera_pixels" else above))
    assert getattr(limits.current(), name) == type(getattr(D, name))(above * 2 if name != "camera_pixels" else above)
    build(above)
    monkeypatch.delenv(SPEC[name][1])
    with pytest.raises((LimitError, ConfigError)):
        build(above)


def test_lowered_by_its_environment_variable(monkeypatch):
    monkeypatch.setenv("BULLETNAV_MAX_LIDAR_RAYS", "36")
    LidarConfig(num_rays=36)
    with pytest.raises(LimitError, match=r"^lidar num_rays = 37 exceeds the limit 36 \(raise it with BULLETNAV_MAX_LIDAR_RAYS\)$"):
        LidarConfig(num_rays=37)


@pytest.mark.parametrize("raw", ["many", "-5", "0", "1.5", "nan", "inf"])
def test_a_bad_variable_is_named(raw, monkeypatch):
    monkeypatch.setenv("BULLETNAV_MAX_LIDAR_RAYS", raw)
    with pytest.raises(LimitError, match=f"BULLETNAV_MAX_LIDAR_RAYS={raw!r} must be a positive integer"):
        LidarConfig(num_rays=36)


def test_env_kwargs_are_checked_before_a_world_is_built(monkeypatch):
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.envs import scene

    def no_scene(*args, **kwargs):
        raise AssertionError("a scene was built")

    monkeypatch.setattr(scene.Scene, "__init__", no_scene)
    for kwargs, what in [({"lidar_rays": 10_000_000}, "lidar num_rays = 10000000 exceeds the limit 4096"),
                         ({"world_size": (10_000.0, 10_000.0)}, "world size (x) = 10000.0 exceeds the limit 200.0"),
                         ({"num_obstacles": 100_000}, "world num_obstacles = 100000 exceeds the limit 1000"),
                         ({"forklifts": 50, "workers": 50}, "dynamic forklifts + workers (50 + 50) = 100"),
                         ({"task_name": "mission", "goals": 20}, "task goals = 20 exceeds the limit 8")]:
        with pytest.raises(LimitError, match=re.escape(what)):
            gym.make("bulletnav/Warehouse-v0", **kwargs)


def test_max_episode_steps_through_make_env():
    from bulletnav.rl.envs import make_env

    with pytest.raises(LimitError, match=r"max_episode_steps = 1000000 exceeds the limit 100000 "
                                         r"\(raise it with BULLETNAV_MAX_EPISODE_STEPS\)"):
        make_env("bulletnav/Warehouse-v0", {"max_episode_steps": 1_000_000})
    # The boundary by hand: 100,001 is refused with the exact line, 100,000 builds the env.
    with pytest.raises(LimitError) as err:
        make_env("bulletnav/Warehouse-v0", {}, max_episode_steps=100_001)
    assert str(err.value) == ("max_episode_steps = 100001 exceeds the limit 100000 "
                              "(raise it with BULLETNAV_MAX_EPISODE_STEPS)")
    env = make_env("bulletnav/Warehouse-v0", {"max_episode_steps": 100_000})
    assert env.spec.max_episode_steps == 100_000
    env.close()


BOX = {"type": "box", "center": [0.0, 0.0], "size": [0.2, 0.2, 0.5]}


@pytest.mark.parametrize("data, what", [
    ({"size": [10_000.0, 10.0], "obstacles": []},
     "field 'size[0]' = 10000.0 exceeds the limit 200.0 (raise it with BULLETNAV_MAX_WORLD_SIZE)"),
    ({"size": [10.0, 10.0], "obstacles": [BOX] * (D.obstacles + 1)},
     "field 'obstacles (entries)' = 1001 exceeds the limit 1000 (raise it with BULLETNAV_MAX_OBSTACLES)"),
    ({"size": [10.0, 10.0], "dynamic": [{"type": "worker", "waypoints": [[1, 1], [2, 2]]}] * (D.movers + 1)},
     "field 'dynamic (entries)' = 65 exceeds the limit 64 (raise it with BULLETNAV_MAX_MOVERS)"),
    ({"size": [10.0, 10.0], "events": [{"at": 1.0, "add": BOX}] * (D.events + 1)},
     "field 'events (entries)' = 1001 exceeds the limit 1000 (raise it with BULLETNAV_MAX_EVENTS)"),
    ({"size": [10.0, 10.0], "goals": [[1.0, 1.0]] * (D.goals + 1)},
     "field 'goals (entries)' = 9 exceeds the limit 8 (raise it with BULLETNAV_MAX_GOALS)"),
])
def test_layout_files_name_file_field_and_limit(tmp_path, data, what):
    from bulletnav.sim.layout import load_layout

    path = tmp_path / "big.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(LayoutError) as err:
        load_layout(path)
    assert str(err.value).startswith(f"{path}: ")
    assert what in str(err.value)
    assert str(err.value) == f"{path}: {what}"  # the whole line: one above the documented limit, by hand


def test_layout_at_the_limits_loads(tmp_path):
    from bulletnav.sim.layout import load_layout

    # the documented limits, by hand (one more of each is refused above)
    data = {"size": [200.0, 10.0], "obstacles": [BOX] * 1000,
            "dynamic": [{"type": "worker", "waypoints": [[1, 1], [2, 2]]}] * 64,
            "events": [{"at": 1.0, "add": {**BOX, "center": [3.0, 3.0]}}] * 1000, "goals": [[1.0, 1.0]] * 8}
    path = tmp_path / "big.yaml"
    path.write_text(yaml.safe_dump(data))
    layout = load_layout(path)
    assert (len(layout.obstacles), len(layout.dynamic), len(layout.events), len(layout.goals)) == (1000, 64, 1000, 8)
    assert layout.size == (200.0, 10.0)


def test_benchmark_suite_world_kwargs(tmp_path):
    from bulletnav.benchmark.suite import SuiteError, parse_suite

    def suite(**kwargs):
        return {"worlds": [{"env": "bulletnav/Warehouse-v0", "kwargs": kwargs}], "controllers": [{"type": "navigator"}]}

    assert parse_suite(suite(num_obstacles=1000, goals=8), "s.yaml").name == "s"  # the documented limits
    with pytest.raises(SuiteError, match=r"s.yaml: field 'worlds\[0\].kwargs.num_obstacles' = 1001 exceeds the limit"):
        parse_suite(suite(num_obstacles=D.obstacles + 1), "s.yaml")
    with pytest.raises(SuiteError, match=r"field 'worlds\[0\].kwargs.goals' = 9 exceeds the limit 8"):
        parse_suite(suite(goals=9), "s.yaml")
    with pytest.raises(SuiteError, match=r"field 'worlds\[0\].kwargs.num_obstacles' must be an integer"):
        parse_suite(suite(num_obstacles="many"), "s.yaml")


def test_sweep_grid_is_refused_before_it_is_expanded():
    from bulletnav.sweep.spec import SweepSpec

    grid = {f"k{i}": list(range(10)) for i in range(20)}  # 10^20 configurations
    with pytest.raises(ConfigError, match=r"sweep: field 'grid': sweep trials .* = 100000000000000000000 exceeds"):
        SweepSpec.from_dict({"algo": "ppo", "grid": grid})
    # The boundary by hand: 100 x 100 configurations pass, 10,001 (73 x 137) are refused.
    SweepSpec.from_dict({"algo": "ppo", "grid": {"a": list(range(100)), "b": list(range(100))}})
    with pytest.raises(ConfigError, match=r"sweep trials \(grid configurations x seeds\) = 10001 exceeds the limit 10000 "
                                          r"\(raise it with BULLETNAV_MAX_SWEEP_TRIALS\)$"):
        SweepSpec.from_dict({"algo": "ppo", "grid": {"a": list(range(73)), "b": list(range(137))}})


def test_mission_goals_option(monkeypatch):
    from bulletnav.tasks.mission import MissionTask

    task = MissionTask.__new__(MissionTask)
    with pytest.raises(LimitError, match=r"options\['goals'\] \(entries\) = 9 exceeds the limit 8"):
        task._goal_option([[0.0, 0.0]] * 9, None)


def test_tour_follows_the_goals_limit(monkeypatch):
    from bulletnav.planning.tour import tour

    dist = [[abs(i - j) for j in range(11)] for i in range(11)]  # 10 goals
    with pytest.raises(ValueError, match="at most 8 goals, got 10 .raise it with BULLETNAV_MAX_GOALS"):
        tour(dist)
    monkeypatch.setenv("BULLETNAV_MAX_GOALS", "10")
    assert tour(dist)[1] == tuple(range(1, 11))
