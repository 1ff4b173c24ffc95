"""Input holes of issue 52, each closed and each test failing at 052a810: suite policy classes
only from an allow-list (or ``--trust-code``); suite and sweep names that are folder names and
output folders that stay inside the output folder; bag maps bounded by limits, with NaN/inf
poses dropped and counted, and ``map --resolution`` read as metres; saved models' network and
buffer sizes bounded; fleet robots and duration through limits.py; the suite's limits raisable
by their variables; dataset ids checked by Minari's own rule before any episode; replay commands
in full, shell-quoted, and replaying their episode when run.

Functions new since 052a810 are imported inside the tests, so that each test fails there on its
own hole rather than the module failing to import."""

from __future__ import annotations

import json
import math
import os
import shlex
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import hang
from bulletnav.cli import main
from bulletnav.errors import BulletnavError, ConfigError, LimitError

ROOT = Path(__file__).resolve().parents[1]
NAV = {"type": "navigator", "planner": "none"}
WAREHOUSE = {"env": "bulletnav/Warehouse-v0"}


def _suite(where: str = "s.yaml", trust_code: bool = False, **over):
    from bulletnav.benchmark.suite import parse_suite

    raw = {"name": "s", "episodes": 1, "worlds": [WAREHOUSE], "controllers": [NAV], **over}
    return parse_suite(raw, where, trust_code=trust_code) if trust_code else parse_suite(raw, where)


# ------------------------------------------------------------------ suite policy classes
@pytest.mark.parametrize("target", ["os:getcwd", "subprocess:Popen", "builtins:eval", "bulletnavx.evil:Policy",
                                    "torch.nn:Linear"])
def test_a_suite_policy_outside_the_allow_list_is_refused_naming_file_entry_and_value(target, tmp_path):
    controllers = [NAV, {"name": "mine", "type": "policy", "class": target}]
    with pytest.raises(BulletnavError) as err:
        _suite("suites/mine.yaml", controllers=controllers)
    message = str(err.value)
    assert message.startswith("suites/mine.yaml: ") and "controllers[1].class" in message and repr(target) in message
    assert "--trust-code" in message and "\n" not in message
    # the allow-list is the hyperparameter files' one, less torch (no policies there)
    assert _suite(controllers=[{"type": "policy", "class": "bulletnav.control.navigator:Navigator"}]).controllers
    # --trust-code takes it as written
    assert _suite(trust_code=True, controllers=controllers).controllers[1].cls == target


def test_the_runner_imports_no_class_outside_the_allow_list_even_from_a_hand_made_suite(monkeypatch):
    """A Suite built in Python (not parsed) still cannot make a cell import os."""
    from bulletnav.benchmark import runner
    from bulletnav.benchmark.suite import ControllerSpec

    imported = []
    real = runner.import_module
    monkeypatch.setattr(runner, "import_module", lambda name: imported.append(name) or real(name))
    spec = ControllerSpec(name="evil", type="policy", cls="os:getcwd")
    with pytest.raises(BulletnavError, match=r"'os:getcwd'.*--trust-code"):
        runner.make_cell(runner.WorldSpec("w", "bulletnav/Warehouse-v0"), spec)
    assert imported == []  # refused before anything was imported


def test_the_cli_refuses_the_suite_in_one_line_with_status_2(tmp_path, capsys):
    suite = tmp_path / "evil.yaml"
    suite.write_text(yaml.safe_dump({"name": "evil", "episodes": 1, "worlds": [WAREHOUSE],
                                     "controllers": [{"type": "policy", "class": "os:getcwd"}]}))
    assert main(["benchmark", str(suite), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(suite) in err and "'os:getcwd'" in err
    assert not (tmp_path / "out").exists()


def test_trust_code_lets_the_cli_import_the_named_module(tmp_path, capsys, monkeypatch):
    """With --trust-code the class outside the allow-list is imported and runs the suite."""
    (tmp_path / "ram_policy.py").write_text(RAM)
    monkeypatch.syspath_prepend(str(tmp_path))
    suite = tmp_path / "mine.yaml"
    suite.write_text(yaml.safe_dump({"name": "mine", "episodes": 1, "seed": 7000,
                                     "worlds": [{"name": "wall", "env": "bulletnav/WarehouseAisles-v0",
                                                 "kwargs": {"world": "wall.yaml"}}],
                                     "controllers": [{"name": "ram", "type": "policy", "class": "ram_policy:Ram"}]}))
    (tmp_path / "wall.yaml").write_text(yaml.safe_dump(WALL))
    assert main(["benchmark", str(suite), "--out", str(tmp_path / "out")]) == 2
    assert "--trust-code" in capsys.readouterr().err
    assert main(["benchmark", str(suite), "--out", str(tmp_path / "out"), "--trust-code", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["episodes"]
    assert row["controller"] == "ram" and row["collision"] and not row["success"]


# ------------------------------------------------------------------ names that become folders
BAD_NAMES = ["..", "../escape", "a/../../b", "a..b", "...", "/etc", "x" * 65, " x", "-x", "a b", "a\\b", ".hidden"]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_suite_names_are_slugs(name):
    with pytest.raises(BulletnavError, match=r"s\.yaml: field 'name'"):
        _suite(name=name)


@pytest.mark.parametrize("name", BAD_NAMES)
def test_sweep_names_are_slugs(name):
    from bulletnav.sweep.spec import SweepSpec

    with pytest.raises(ConfigError, match=r"sweep\.yaml: field 'name'"):
        SweepSpec.from_dict({"algo": "ppo", "name": name}, where="sweep.yaml")


def test_default_names_from_the_file_are_slugs_too(tmp_path):
    from bulletnav.sweep.spec import SweepSpec

    with pytest.raises(BulletnavError, match="default: the file's name"):
        _suite_without_name("my suite.yaml")
    path = tmp_path / "my sweep.yaml"
    path.write_text("algo: ppo\n")
    with pytest.raises(ConfigError, match="default: the file's name"):
        SweepSpec.from_file(path)
    assert _suite_without_name("fine-name_1.0.yaml").name == "fine-name_1.0"


def _suite_without_name(where: str):
    from bulletnav.benchmark.suite import parse_suite

    return parse_suite({"episodes": 1, "worlds": [WAREHOUSE], "controllers": [NAV]}, where)


def test_output_folders_resolve_inside_their_base(tmp_path):
    """A slug can still lead out through a link inside the output folder: refused by resolving."""
    from bulletnav.sweep.spec import SweepSpec

    base, outside = tmp_path / "runs", tmp_path / "elsewhere"
    base.mkdir()
    outside.mkdir()
    (base / "s").symlink_to(outside)
    with pytest.raises(BulletnavError, match="outside"):
        _suite().out_dir(base)
    assert _suite(name="t").out_dir(base) == base / "t"
    spec = SweepSpec.from_dict({"algo": "ppo", "name": "s"})
    with pytest.raises(ConfigError, match="outside"):
        spec.results_dir(base)
    with pytest.raises(ConfigError, match="outside"):  # the trials' storage folder likewise
        spec.results_dir(tmp_path / "tables", storage=base)
    assert SweepSpec.from_dict({"algo": "ppo", "name": "t"}).results_dir(base) == base / "t"


def test_a_run_never_writes_through_a_link_out_of_its_folder(tmp_path):
    from bulletnav.benchmark.runner import run_suite

    out, outside = tmp_path / "out", tmp_path / "outside.jsonl"
    out.mkdir()
    (out / "episodes.jsonl").symlink_to(outside)  # dangling: exists() is False
    with pytest.raises(BulletnavError, match="outside"):
        run_suite(_suite(), out)
    assert not outside.exists()


# ------------------------------------------------------------------ bag maps
def _bag(poses, n_scans=None, rays=8):
    """Scans at the poses' stamps (+1 ms), 8 rays reaching 2 m."""
    from bulletnav.ros.bagmap import BagData, Scan

    angles = np.linspace(-math.pi, math.pi, rays, endpoint=False)
    stamps = [t for t, _ in poses][: n_scans or len(poses)]
    scans = [Scan(t + 1_000_000, "laser", angles, np.full(rays, 1.5), 0.1, 2.0) for t in stamps]
    return BagData(scans, list(poses))


def test_a_bag_spanning_kilometres_is_refused_before_the_grid_is_allocated():
    from bulletnav.ros.bagmap import build_map

    # 2 km along x; the scans 1 ms after the poses span 2.5-2000 m, grown by 2 m each way
    poses = [(k * 100_000_000, (k * 250.0, 0.0, 0.0)) for k in range(9)]
    with pytest.raises(LimitError, match=r"map extent \(x\) = 2001\.5 exceeds the limit 1000\.0 "
                                         r"\(raise it with BULLETNAV_MAX_MAP_EXTENT\)"):
        build_map(_bag(poses), resolution=1.0)


def test_map_cells_are_bounded_and_raisable(monkeypatch):
    from bulletnav.ros.bagmap import build_map

    poses = [(k * 100_000_000, (k * 0.5, 0.0, 0.0)) for k in range(5)]  # 2 m + 2 x 2 m reach: 6 x 4 m
    monkeypatch.setenv("BULLETNAV_MAX_MAP_CELLS", "2000")
    with pytest.raises(LimitError, match=r"map cells \(60 x 40 of 0\.1 m\) = 2400 exceeds the limit 2000 .*"
                                         r"BULLETNAV_MAX_MAP_CELLS"):
        build_map(_bag(poses), resolution=0.1, margin=2.0)
    monkeypatch.setenv("BULLETNAV_MAX_MAP_CELLS", "2400")
    assert build_map(_bag(poses), resolution=0.1, margin=2.0).mapper.log_odds.shape == (60, 40)


def test_nan_and_infinite_poses_are_dropped_and_counted():
    from bulletnav.ros.bagmap import build_map

    good = [(k * 100_000_000, (k * 0.2, 0.1 * k, 0.05 * k)) for k in range(10)]
    bad = [(good[2][0] + 50_000_000, (math.nan, 0.0, 0.0)), (good[5][0] + 50_000_000, (0.0, math.inf, 0.0)),
           (good[7][0] + 50_000_000, (1.0, 1.0, -math.inf))]
    mixed = sorted(good + bad)
    bag = _bag(mixed)  # a scan 1 ms after every pose, the bad ones included
    result = build_map(bag, resolution=0.1)
    assert result.poses_skipped == 3 and result.scans_used == len(mixed) and result.scans_skipped == 0
    assert np.isfinite(result.mapper.log_odds).all()
    # every scan is placed on the good poses alone: numpy's linear interpolation is the reference
    t = np.array([g[0] for g in good], dtype=float)
    stamps = np.array([s.stamp_ns for s in bag.scans], dtype=float)
    expected = np.column_stack([np.interp(stamps, t, [g[1][0] for g in good]), np.interp(stamps, t, [g[1][1] for g in good])])
    np.testing.assert_allclose(np.array(result.trajectory), expected, atol=1e-9)
    only_bad = [(0, (math.nan, 0.0, 0.0)), (100_000_000, (math.inf, 0.0, 0.0))]
    with pytest.raises(BulletnavError, match=r"no scan has a pose: .*\(2 of 2 not finite, dropped\)"):
        build_map(_bag(only_bad), resolution=0.1)


def test_a_lidar_mapper_refuses_bounds_that_are_not_numbers():
    from bulletnav.planning.mapping import LidarMapper

    for bounds in [(0.0, 0.0, math.nan, 1.0), (0.0, -math.inf, 1.0, 1.0), (2.0, 0.0, 1.0, 1.0)]:
        with pytest.raises(ValueError, match="map bounds must be finite"):
            LidarMapper(bounds, 0.1)
    with pytest.raises(ValueError, match="resolution must be a finite number"):
        LidarMapper((0.0, 0.0, 1.0, 1.0), math.inf)


@pytest.mark.parametrize("value", ["0", "-0.1", "nan", "inf", "1e9", "0.0001", "ten"])
def test_map_resolution_is_read_as_metres(value, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["map", str(tmp_path / "bag.mcap"), "--resolution", value])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "--resolution" in err and "cell size in metres" in err and "seconds" not in err


# ------------------------------------------------------------------ saved models
def _sidecar_model(tmp_path: Path, edit) -> Path:
    """A copy of the shipped PPO in the safe format, its sidecar edited by ``edit(policy)``."""
    for suffix in (".zip", ".json", ".safetensors"):
        (tmp_path / f"m{suffix}").write_bytes((ROOT / "models" / f"ppo_warehouse{suffix}").read_bytes())
    meta = json.loads((tmp_path / "m.json").read_text())
    edit(meta["policy"])
    (tmp_path / "m.json").write_text(json.dumps(meta))
    return tmp_path / "m.zip"


@pytest.mark.parametrize("edit, variable", [
    (lambda p: p["kwargs"].update(net_arch={"pi": [128, 5000], "vf": [128, 128]}), "BULLETNAV_MAX_NET_WIDTH"),
    (lambda p: p["kwargs"].update(net_arch={"pi": [8] * 17, "vf": [128, 128]}), "BULLETNAV_MAX_NET_LAYERS"),
    (lambda p: p["hyperparameters"].update(n_steps=10**12), "BULLETNAV_MAX_N_STEPS"),
    (lambda p: p["hyperparameters"].update(batch_size=10**12), "BULLETNAV_MAX_BATCH_SIZE"),
])
def test_a_sidecar_asking_for_huge_networks_or_buffers_is_refused_before_building(tmp_path, monkeypatch, edit, variable):
    from bulletnav.rl import safe
    from bulletnav.rl.io import load_model

    built = []
    monkeypatch.setattr(safe, "_SpacesEnv", lambda *a: built.append(a) or pytest.fail("built"))
    path = _sidecar_model(tmp_path, edit)
    with pytest.raises(LimitError, match=f"m.json: .* exceeds the limit .*{variable}"):
        load_model(path)
    assert built == []


def test_a_sidecar_of_the_shipped_sizes_still_loads(tmp_path):
    from bulletnav.rl.io import load_model

    model, _, _ = load_model(_sidecar_model(tmp_path, lambda p: None))
    assert model.n_steps == 512


def test_buffer_size_and_n_envs_are_bounded():
    from bulletnav.rl.safe import check_sizes

    for key, variable in (("buffer_size", "BULLETNAV_MAX_BUFFER_SIZE"), ("n_envs", "BULLETNAV_MAX_N_ENVS")):
        with pytest.raises(LimitError, match=f"m.json: {key} = 1000000000000 exceeds .*{variable}"):
            check_sizes({}, {key: 10**12}, "m.json")


# ------------------------------------------------------------------ fleet
def test_fleet_duration_and_robots_are_limits(monkeypatch):
    from bulletnav.fleet.config import FleetConfig

    with pytest.raises(BulletnavError, match=r"fleet duration_s = 1000000\.0 exceeds the limit 3600\.0 "
                                            r"\(raise it with BULLETNAV_MAX_FLEET_DURATION\)"):
        FleetConfig(duration_s=1e6)
    monkeypatch.setenv("BULLETNAV_MAX_FLEET_DURATION", "2e6")
    assert FleetConfig(duration_s=1e6).duration_s == 1e6
    monkeypatch.setenv("BULLETNAV_MAX_FLEET_ROBOTS", "3")
    with pytest.raises(BulletnavError, match=r"fleet num_robots = 4 exceeds the limit 3 .*BULLETNAV_MAX_FLEET_ROBOTS"):
        FleetConfig(num_robots=4)


# ------------------------------------------------------------------ one limits table
def test_the_suite_limits_are_in_the_one_table_and_raisable(monkeypatch):
    from bulletnav import limits
    from bulletnav.benchmark import suite

    assert not hasattr(suite, "LIMITS")
    for name in ("suite_episodes", "suite_worlds", "suite_controllers", "suite_total"):
        assert hasattr(limits.current(), name)
    with pytest.raises(BulletnavError, match="BULLETNAV_MAX_SUITE_EPISODES"):
        _suite(episodes=150_000)
    monkeypatch.setenv("BULLETNAV_MAX_SUITE_EPISODES", "200000")
    assert _suite(episodes=150_000).episodes == 150_000
    monkeypatch.setenv("BULLETNAV_MAX_SUITE_WORLDS", "1")
    with pytest.raises(BulletnavError, match=r"field 'worlds' \(entries\) = 2 exceeds the limit 1"):
        _suite(worlds=[{"name": "a", **WAREHOUSE}, {"name": "b", **WAREHOUSE}])


# ------------------------------------------------------------------ dataset ids
@pytest.mark.parametrize("name", ["bulletnav/a.b-v0", "x/name-v0", "bulletnav/name", "name.v0-v0"])
def test_dataset_ids_follow_minaris_rule(name):
    """Each of these passed bulletnav's old rule and failed in Minari's, after every episode ran."""
    from minari.dataset.minari_dataset import parse_dataset_id

    from bulletnav.datasets import check_name

    with pytest.raises((ValueError, TypeError)):  # the reference: Minari's own parser
        parse_dataset_id(name)
    with pytest.raises(BulletnavError, match="name-vN"):
        check_name(name)


def test_a_bad_dataset_id_stops_navigate_before_any_episode(capsys, monkeypatch):
    from bulletnav import evaluation

    ran = []
    monkeypatch.setattr(evaluation, "run_episodes", lambda *a, **k: ran.append(1) or pytest.fail("an episode ran"))
    assert main(["navigate", "--episodes", "1", "--planner", "none", "--dataset", "bulletnav/a.b-v0"]) == 2
    captured = capsys.readouterr()
    assert ran == [] and "bulletnav/a.b-v0" in captured.err and len(captured.err.strip().splitlines()) == 1


# ------------------------------------------------------------------ replay commands
RAM = '''
import numpy as np


class Ram:
    """Full speed ahead, never turning: into the wall, and the episode ends."""

    def __init__(self, scene):
        self.scene = scene

    def reset(self, info):
        pass

    def act(self, obs, info):
        return self.scene.action_for(self.scene.command_limits[0][1], 0.0)
'''

WALL = {"name": "wall", "size": [6.0, 4.0], "start": [-2.0, 0.0, 0.0], "goal": [2.0, 0.0],
        "obstacles": [{"type": "box", "center": [0.0, 0.0], "size": [0.4, 3.2, 1.0], "yaw": 0.0}]}


@pytest.mark.slow
def test_a_replay_command_from_a_report_replays_its_episode(tmp_path, monkeypatch):
    """A suite in a folder with a space and a quote in its name, its path far over 60
    characters: the report's replay commands hold the paths in full, quoted for the shell, and
    the policy's command, run by /bin/sh in a fresh process, gives the row of the report."""
    from bulletnav.benchmark.runner import run_suite
    from bulletnav.benchmark.suite import load_suite
    from bulletnav.cli import build_parser

    base = tmp_path / "a folder named with spaces and it's quote" / "one more level to pass sixty characters"
    base.mkdir(parents=True)
    (tmp_path / "ram_policy.py").write_text(RAM)
    monkeypatch.syspath_prepend(str(tmp_path))
    (base / "wall world.yaml").write_text(yaml.safe_dump(WALL))
    suite_file = base / "replay suite.yaml"
    suite_file.write_text(yaml.safe_dump({
        "name": "replay", "episodes": 1, "seed": 7000,
        "worlds": [{"name": "wall", "env": "bulletnav/WarehouseAisles-v0", "kwargs": {"world": "wall world.yaml"}}],
        "controllers": [{"name": "ram", "type": "policy", "class": "ram_policy:Ram"}]}))
    assert len(str(suite_file)) > 100
    results = run_suite(load_suite(str(suite_file), trust_code=True), tmp_path / "out")
    (row,) = results["episodes"]
    assert not row["success"] and row["collision"] and row["steps"] < 200  # it drove into the wall
    command = row["replay"]
    assert "..." not in command and "trust_code=True" in command
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
           "PYTHONPATH": str(tmp_path)}
    done = hang.run(["/bin/sh", "-c", command], "the gallery's replay command", env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    replayed = json.loads(done.stdout.strip().splitlines()[-1])
    for key in ("success", "collision", "steps", "seed", "timeout", "path_length_m"):
        assert replayed[key] == row[key], key
    # a navigator's command: argparse gets the world file's path back whole
    from bulletnav.benchmark.suite import ControllerSpec, replay_command

    suite = load_suite(str(suite_file), trust_code=True)
    nav = replay_command(suite, suite.worlds[0], ControllerSpec("PID", "navigator", planner="none"), 7000, ROOT)
    argv = shlex.split(nav)
    assert argv[:2] == ["bulletnav", "navigate"]
    args = build_parser().parse_args(argv[1:])
    assert args.world == str(base / "wall world.yaml") and args.seed == 7000 and args.env_id == "bulletnav/WarehouseAisles-v0"
