"""``--env ID`` on the CLI subcommands, and the safety metrics of the evaluation (static and
dynamic collisions, timeouts, separation from movers, near misses, episode time)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict

import pytest

from bulletnav.cli import DEFAULT_ENV_ID, build_parser, main
from bulletnav.cli.envs import make_env
from bulletnav.evaluation import NEAR_MISS_M, SAFETY_KEYS, EpisodeResult, SafetyTracker, summarize

AISLES = "bulletnav/WarehouseAisles-v0"

# ------------------------------------------------------------------------------------------
# --env on the command line


@pytest.mark.parametrize("argv", [
    ["navigate"], ["evaluate", "--model", "m.zip"], ["demo"], ["train", "--out", "r"], ["view"],
])
def test_every_env_subcommand_defaults_to_warehouse_v0_and_takes_env(argv):
    parser = build_parser()
    args = parser.parse_args(argv)
    assert args.env_id == DEFAULT_ENV_ID == "bulletnav/Warehouse-v0"
    assert parser.parse_args([*argv, "--env", AISLES]).env_id == AISLES
    if argv[0] != "train":
        assert args.obstacles is None  # only passed to the env when given


def test_env_option_reaches_the_env():
    args = build_parser().parse_args(["navigate", "--env", AISLES])
    env = make_env(args)
    try:
        env.reset(seed=3)
        scene = env.unwrapped.scene
        layout = scene.layout
        assert tuple(layout.size) == (20.0, 16.0)
        assert any(o.label == "rack" for o in layout.obstacles)
        assert env.spec.id == AISLES
        # the episode's start and goal lie on free floor: by Shapely, each is farther than the
        # robot's radius from every rack footprint and inside the 20 x 16 m floor
        from shapely import affinity
        from shapely.geometry import Point, box

        racks = [affinity.rotate(box(o.center[0] - o.size[0] / 2, o.center[1] - o.size[1] / 2,
                                     o.center[0] + o.size[0] / 2, o.center[1] + o.size[1] / 2),
                                 o.yaw, origin=tuple(o.center), use_radians=True)
                 for o in layout.obstacles if o.kind == "box"]
        floor = box(-10.0, -8.0, 10.0, 8.0)
        for xy in (scene.start[:2], scene.goal):
            pt = Point(float(xy[0]), float(xy[1]))
            assert floor.contains(pt.buffer(scene.geometry.radius))
            assert min(pt.distance(r) for r in racks) > scene.geometry.radius, xy
    finally:
        env.close()


def test_navigate_json_on_the_aisles_env(capsys):
    assert main(["navigate", "--env", AISLES, "--planner", "none", "--episodes", "1", "--seed", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["env_id"] == AISLES
    assert out["world_size"] == [20.0, 16.0]
    assert out["world"] == "procedural"
    for key in SAFETY_KEYS:
        assert key in out
    assert out["min_separation_m"] is None  # no movers: NaN, written as null
    assert out["near_miss_rate"] == 0.0
    ep = out["per_episode"][0]
    assert ep["collision_dynamic"] is False and ep["near_miss_steps"] == 0
    # by hand and formula from the row: 24 control steps a second; SPL = S * l / max(p, l)
    assert ep["sim_time"] == pytest.approx(ep["steps"] / 24) and out["episode_time_s"] == pytest.approx(ep["steps"] / 24)
    assert ep["spl"] == pytest.approx(ep["shortest_path"] / max(ep["path_length"], ep["shortest_path"])
                                      if ep["success"] else 0.0)
    assert ep["shortest_path"] >= ep["initial_distance"] - 0.1  # never shorter than the straight line (0.1 m grid)
    assert ep["collision_static"] == ep["collision"] and ep["timeout"] == (not ep["success"] and not ep["collision"])


def test_navigate_default_env_report_is_unchanged_but_for_the_safety_line(capsys):
    assert main(["navigate", "--planner", "none", "--episodes", "1", "--world", "bulletnav/assets/worlds/empty.yaml"]) == 0
    text = capsys.readouterr().out
    assert "| bulletnav/assets/worlds/empty.yaml |" in text and "Warehouse-v0" not in text
    assert "safety         collisions static 0.0 %  dynamic 0.0 %" in text and "min separation n/a (no movers)" in text


def test_world_file_with_the_aisles_env(capsys):
    world = "bulletnav/assets/worlds/hall.yaml"
    assert main(["navigate", "--env", AISLES, "--world", world, "--planner", "none", "--episodes", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["world"] == world and out["env_id"] == AISLES and out["world_size"] == [14.0, 12.0]
    # the world file as PyYAML reads it gives that size; the episode's start and goal lie on its
    # floor, so their distance is at most the floor's diagonal less the robot's clearance
    import yaml

    with open(world) as f:
        assert [float(v) for v in yaml.safe_load(f)["size"]] == out["world_size"]
    ep = out["per_episode"][0]
    assert 0.0 < ep["initial_distance"] < math.hypot(14.0, 12.0)
    assert ep["shortest_path"] >= ep["initial_distance"] - 0.1


@pytest.mark.parametrize("argv", [
    ["navigate", "--episodes", "1"], ["evaluate", "--model", "models/ppo_warehouse.zip", "--episodes", "1"],
    ["view", "--seconds", "0.1"], ["train", "--out", "unused", "--timesteps", "1"], ["demo", "--episodes", "1"],
])
def test_unknown_env_id_is_a_clear_error(argv, capsys):
    assert main([*argv, "--env", "bulletnav/Nope-v0"]) == 2
    err = capsys.readouterr().err
    assert "unknown env id 'bulletnav/Nope-v0'" in err
    assert "bulletnav/Warehouse-v0" in err and AISLES in err


# ------------------------------------------------------------------------------------------
# safety metrics from hand-made episodes


def _episode(k: int, steps: int, success: bool = False, collision: bool = False, **extra) -> EpisodeResult:
    return EpisodeResult(episode=k, seed=k, initial_distance=3.0, shortest_path=3.0, steps=steps, reward=0.0,
                         final_distance=1.0, path_length=2.0, success=success, collision=collision, spl=0.0,
                         sim_time=steps / 24, wall_time=0.0, **extra)


def _track(step_infos: list[dict], final: dict) -> dict:
    tracker = SafetyTracker()
    for info in step_infos:
        tracker.step(info)
    return tracker.result(final)


def test_tracker_in_a_static_world():
    # no mover keys at all: a collision is a static one, no separation, no near misses
    r = _track([{}, {}], {"collision": True, "is_success": False})
    assert math.isnan(r.pop("min_separation"))
    assert r == {"collision_static": True, "collision_dynamic": False, "timeout": False, "near_miss_steps": 0}
    r = _track([{}], {"collision": False, "is_success": False})
    assert not r["collision_static"] and not r["collision_dynamic"] and r["timeout"] and math.isnan(r["min_separation"])
    r = _track([{}], {"collision": False, "is_success": True})
    assert not r["collision_static"] and not r["collision_dynamic"] and not r["timeout"]


def test_tracker_with_movers():
    infos = [{"nearest_mover_m": d, "collision_with": None} for d in (math.inf, 1.5, 0.19, 0.05, NEAR_MISS_M, 0.3)]
    r = _track(infos, {"collision": True, "is_success": False, "collision_with": "dynamic"})
    assert r == {"collision_static": False, "collision_dynamic": True, "timeout": False, "near_miss_steps": 2,
                 "min_separation": 0.05}
    # movers reported but none present (inf throughout): no separation
    r = _track([{"nearest_mover_m": math.inf}] * 3, {"collision": True, "is_success": False, "collision_with": "static"})
    assert r["collision_static"] and not r["collision_dynamic"] and math.isnan(r["min_separation"])
    assert r["near_miss_steps"] == 0
    # the tracker's figures build an EpisodeResult, whose per-episode row stays plain numbers
    result = _episode(1, 6, collision=True, **_track(infos, {"collision": True, "is_success": False,
                                                              "collision_with": "dynamic"}))
    assert result.min_separation_m == 0.05 and "min_separation" not in asdict(result)


def test_summarize_safety_metrics_known_answers():
    results = [
        _episode(1, 48, success=True, min_separation=0.5, near_miss_steps=0),
        _episode(2, 24, collision=True, collision_dynamic=True, min_separation=0.0, near_miss_steps=6),
        _episode(3, 120, collision=True, collision_static=True, min_separation=0.3, near_miss_steps=0),
        _episode(4, 48, timeout=True),  # an episode without movers: NaN separation, left out of the mean
    ]
    s = summarize(results)
    assert s["collision_static_rate"] == 0.25
    assert s["collision_dynamic_rate"] == 0.25
    assert s["collision_rate"] == 0.5
    assert s["timeout_rate"] == 0.25
    assert s["min_separation_m"] == pytest.approx((0.5 + 0.0 + 0.3) / 3)
    assert s["near_miss_rate"] == pytest.approx(6 / (48 + 24 + 120 + 48))
    assert s["episode_time_s"] == pytest.approx((48 + 24 + 120 + 48) / 24 / 4)
    assert s["per_episode"][1]["collision_dynamic"] is True and s["per_episode"][1]["near_miss_steps"] == 6


def test_summarize_safety_metrics_without_movers_or_episodes():
    s = summarize([_episode(1, 10, collision=True, collision_static=True), _episode(2, 30, success=True)])
    assert s["collision_static_rate"] == 0.5 and s["collision_dynamic_rate"] == 0.0 and s["timeout_rate"] == 0.0
    assert math.isnan(s["min_separation_m"]) and s["near_miss_rate"] == 0.0
    assert s["episode_time_s"] == pytest.approx(20 / 24)
    empty = summarize([])
    assert empty["timeout_rate"] == 0.0 and math.isnan(empty["min_separation_m"]) and empty["near_miss_rate"] == 0.0


def test_train_reads_the_env_ids_own_hyperparameters_and_records_it(monkeypatch, tmp_path):
    import yaml

    from bulletnav.rl import train as train_module
    from bulletnav.rl.hyperparams import load_hyperparams

    for algo in ("ppo", "sac", "td3", "a2c"):  # every packaged file has the ids, as Warehouse-v0 plus guidance at most
        base = load_hyperparams(algo)
        # what RL Zoo would read: the packaged file through PyYAML, entry by env id
        with open(f"bulletnav/rl/hyperparams/{algo}.yml") as f:
            zoo = yaml.safe_load(f)
        assert base == zoo["bulletnav/Warehouse-v0"]
        for env_id in ("bulletnav/WarehouseAisles-v0", "bulletnav/WarehouseDynamic-v0", "bulletnav/WarehouseMission-v0"):
            assert load_hyperparams(algo, env_id=env_id) == zoo[env_id], (algo, env_id)
        for env_id in ("bulletnav/WarehouseAisles-v0", "bulletnav/WarehouseDynamic-v0", "bulletnav/WarehouseMission-v0"):
            hp = load_hyperparams(algo, env_id=env_id)
            kwargs = dict(hp["env_kwargs"])
            assert kwargs.pop("guidance", "floorplan") == "floorplan"
            assert {**hp, "env_kwargs": kwargs} == base
    for env_id in ("bulletnav/WarehouseDynamic-v0", "bulletnav/WarehouseMission-v0"):  # PPO's are trained with it
        assert load_hyperparams("ppo", env_id=env_id)["env_kwargs"]["guidance"] == "floorplan"
    seen = {}

    def fake_train(cfg, plot_curve=None):  # the CLI passes the learning-curve plotter
        seen["env_id"] = cfg.env_id
        raise SystemExit(0)

    monkeypatch.setattr(train_module, "train", fake_train)
    with pytest.raises(SystemExit):
        main(["train", "--env", "bulletnav/WarehouseDynamic-v0", "--out", str(tmp_path / "r"), "--timesteps", "1"])
    assert seen["env_id"] == "bulletnav/WarehouseDynamic-v0"
