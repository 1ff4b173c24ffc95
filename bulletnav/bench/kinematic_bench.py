"""How far the kinematic profile (``physics="kinematic"``) stands from full physics, measured side
by side (``bulletnav bench kinematic``; docs/performance/kinematic.md).

Full physics (``physics="default"``, PyBullet at 240 Hz) is the reference throughout; ``fast``
(96 Hz) is measured beside the kinematic profile where it applies, so a reader sees how far
each cheaper profile moves. Four tables:

- **scans**: the same seeded reset puts the robot at rest at the same pose in the same world
  (checked: the poses are compared too); both profiles' scans, noise off, ray by ray, in every
  world source (procedural, aisles, a YAML layout, a map_server map, an SDF world, BARN);
- **manoeuvres**: the same command sequences from rest on an empty floor (straight, turn in
  place, arcs, a full-speed stop), for the article robot and the Jackal: end pose error against
  full physics;
- **contacts**: full speed into a wall, a rack and a BARN cylinder: the step of the first
  contact, and where the robot's nose was then against the obstacle's face;
- **outcomes**: PID + A* and the shipped PPO on the quick suite's worlds and episodes in both
  profiles (the ``kinematic-pair`` suite, :func:`bulletnav.benchmark.runner.run_suite`): per
  world, success and collisions, and the episodes whose outcome differs, listed.
"""

from __future__ import annotations

import logging
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

SOURCES = ("procedural", "aisles", "yaml", "map_server", "sdf", "barn")
"""The world sources the scans are compared in."""

SDF_WORLD = """<?xml version="1.0" ?>
<sdf version="1.9">
  <world name="site">
    <model name="walls">
      <static>true</static>
      <pose>10 20 0 0 0 0</pose>
      <link name="outer">
        <collision name="south"><pose>0 -3.5 1 0 0 0</pose><geometry><box><size>10 0.2 2</size></box></geometry></collision>
        <collision name="north"><pose>0 3.5 1 0 0 0</pose><geometry><box><size>10 0.2 2</size></box></geometry></collision>
        <collision name="west"><pose>-5 0 1 0 0 1.5707963</pose><geometry><box><size>7 0.2 2</size></box></geometry></collision>
        <collision name="east"><pose>5 0 1 0 0 1.5707963</pose><geometry><box><size>7 0.2 2</size></box></geometry></collision>
      </link>
      <link name="divider"><pose>1 -1 0 0 0 0.3</pose>
        <collision name="c"><pose>0 0 0.75 0 0 0</pose><geometry><box><size>0.3 3 1.5</size></box></geometry></collision>
      </link>
    </model>
    <model name="pillar">
      <static>true</static>
      <pose>7.5 22 0 0 0 0</pose>
      <link name="l"><collision name="c"><pose>0 0 1.5 0 0 0</pose>
        <geometry><cylinder><radius>0.25</radius><length>3</length></cylinder></geometry></collision></link>
    </model>
  </world>
</sdf>
"""
"""A small Gazebo world: four walls round a room, a turned divider and a pillar."""


def map_server_map(folder: Path) -> Path:
    """Write a 12 x 10 m map_server map (0.1 m cells: an outer wall, a block and a bar) into
    ``folder``; its YAML's path."""
    rows = np.full((100, 120), 254, dtype=np.uint8)
    rows[:3, :] = rows[-3:, :] = 0
    rows[:, :3] = rows[:, -3:] = 0
    rows[30:45, 20:40] = 0
    rows[55:60, 60:100] = 0
    (folder / "site.pgm").write_bytes(b"P5\n120 100\n255\n" + rows.tobytes())
    path = folder / "site.yaml"
    path.write_text("image: site.pgm\nresolution: 0.1\norigin: [2.0, -3.0, 0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n")
    return path


def world_source(name: str, folder: Path) -> tuple[str, dict[str, Any]]:
    """(env id, keywords) of world source ``name`` (:data:`SOURCES`); files it needs are written
    into ``folder``. BARN: worlds 0-4, the UST-10's 720 rays, noise off."""
    import bulletnav

    if name == "procedural":
        return "bulletnav/Warehouse-v0", {}
    if name == "aisles":
        return "bulletnav/WarehouseAisles-v0", {}
    if name == "yaml":
        return "bulletnav/Warehouse-v0", {"world": str(Path(bulletnav.__file__).parent / "assets" / "worlds" / "hall.yaml")}
    if name == "map_server":
        return "bulletnav/Warehouse-v0", {"world": str(map_server_map(folder)), "min_goal_distance": 1.0}
    if name == "sdf":
        path = folder / "site.world"
        path.write_text(SDF_WORLD)
        return "bulletnav/Warehouse-v0", {"world": str(path), "min_goal_distance": 1.0, "max_goal_distance": 4.0}
    if name == "barn":
        return "bulletnav/BARN-v0", {"lidar_rays": 720, "lidar_noise": 0.0, "world_idx": (0, 1, 2, 3, 4)}
    raise ValueError(f"unknown world source {name!r}; known: {', '.join(SOURCES)}")


def seeded_scans(env_id: str, kwargs: dict[str, Any], physics: str, seeds: range) -> tuple[list[np.ndarray], np.ndarray]:
    """The lidar's reading (m) after ``env.reset(seed=s)`` for each seed, and the poses (x, y, yaw) it was taken at."""
    import gymnasium as gym

    env = gym.make(env_id, physics=physics, **kwargs)
    scans, poses = [], []
    try:
        for seed in seeds:
            _, info = env.reset(seed=seed)
            scans.append(env.unwrapped.scene.sensors.lidar.read().astype(np.float64))
            poses.append(np.asarray(info["pose"], dtype=np.float64))
    finally:
        env.close()
    return scans, np.array(poses)


def bench_scans(seeds: range = range(20), sources: tuple[str, ...] = SOURCES) -> list[dict[str, Any]]:
    """Per world source: rays compared, the share within 1 cm, the 99th percentile and the
    largest difference (m), and the largest pose difference (m) between the profiles' resets."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for source in sources:
            env_id, kwargs = world_source(source, Path(tmp))
            ref, ref_poses = seeded_scans(env_id, kwargs, "default", seeds)
            kin, kin_poses = seeded_scans(env_id, kwargs, "kinematic", seeds)
            diff = np.abs(np.concatenate(ref) - np.concatenate(kin))
            rows.append({"source": source, "env_id": env_id, "resets": len(seeds), "rays": int(diff.size),
                         "within_1cm": float(np.mean(diff <= 0.01)), "p99_m": float(np.percentile(diff, 99)),
                         "max_m": float(diff.max()),
                         "pose_difference_m": float(np.max(np.hypot(*(ref_poses[:, :2] - kin_poses[:, :2]).T)))})
            log.info("scans %s: %.4f within 1 cm", source, rows[-1]["within_1cm"])
    return rows


MANOEUVRES: dict[str, tuple[tuple[float, float, float], ...]] = {
    # (share of top speed, share of top turn rate, seconds), from rest; then 1 s of zero command
    "straight": ((1.0, 0.0, 2.0),),
    "turn in place": ((0.0, 1.0, 1.0),),
    "arc": ((1.0, 0.5, 2.0),),
    "slow arc": ((0.3, 0.3, 3.0),),
    "full-speed stop": ((1.0, 0.0, 1.0),),
}
"""The command sequences driven in every profile; each ends with 1 s of zero command (the
full-speed stop is the straight run cut short: what is measured is where it comes to rest)."""


def drive(physics: str, robot: str, segments: tuple[tuple[float, float, float], ...]) -> tuple[float, float, float]:
    """Where ``robot`` ends (x, y, yaw; ``info["pose"]``) after ``segments`` and 1 s of zero
    command from rest at the origin of an empty 30 x 30 m floor, in profile ``physics``, driven
    through ``env.step`` (the goal, 17 m away, is never reached)."""
    import gymnasium as gym

    env = gym.make("bulletnav/Warehouse-v0", physics=physics, robot=robot, num_obstacles=0, world_size=(30, 30))
    try:
        _, info = env.reset(seed=1, options={"start": (0.0, 0.0, 0.0), "goal": (12.0, 12.0)})
        scene = env.unwrapped.scene
        (_, v_max), (_, w_max) = scene.command_limits
        hz = round(1.0 / scene.control_dt)
        commands = [(v * v_max, w * w_max) for v, w, seconds in segments for _ in range(round(seconds * hz))]
        for v, w in commands + [(0.0, 0.0)] * hz:
            _, _, _, _, info = env.step(scene.action_for(v, w))
        x, y, yaw = info["pose"]
        return float(x), float(y), float(yaw)
    finally:
        env.close()


def bench_manoeuvres(robots: tuple[str, ...] = ("article", "jackal")) -> list[dict[str, Any]]:
    """Per robot and manoeuvre: full physics' end pose, its distance from the start and the
    angle it turned, and for ``fast`` and ``kinematic`` the end point's distance from full
    physics' (m, and % of that distance where it drove at least 0.1 m) and the heading's
    difference (rad, and % of the angle turned where it turned at least 0.1 rad)."""
    rows = []
    for robot in robots:
        for name, segments in MANOEUVRES.items():
            ref = drive("default", robot, segments)
            distance, turned = math.hypot(ref[0], ref[1]), abs(ref[2])
            row: dict[str, Any] = {"robot": robot, "manoeuvre": name, "default_end": list(ref),
                                   "default_distance_m": distance, "default_turn_rad": turned}
            for physics in ("fast", "kinematic"):
                end = drive(physics, robot, segments)
                error = math.hypot(end[0] - ref[0], end[1] - ref[1])
                heading = abs(math.remainder(end[2] - ref[2], 2 * math.pi))
                row[physics] = {"end": list(end), "end_error_m": error,
                                "end_error_pct": 100.0 * error / distance if distance >= 0.1 else None,
                                "heading_error_rad": heading,
                                "heading_error_pct": 100.0 * heading / turned if turned >= 0.1 else None}
            rows.append(row)
    return rows


def rack_world(folder: Path) -> Path:
    """A 10 x 10 m room with one 0.9 m deep rack whose face stands 1.55 m ahead of the origin."""
    path = folder / "rack.yaml"
    path.write_text("name: rack\nsize: [10.0, 10.0]\nobstacles:\n"
                    "  - {type: box, center: [2.0, 0.0], size: [0.9, 3.0, 2.0], label: rack}\n")
    return path


def contact_target(target: str, folder: Path) -> tuple[str, dict[str, Any], tuple[float, float, float], Any, float]:
    """(env id, keywords, start pose, goal or None, distance from the start to the obstacle's face
    along the heading) of a full-speed drive into ``target``: 'wall' (an empty 10 x 10 m room,
    3 m to the north wall), 'rack' (:func:`rack_world`) or 'barn_cylinder' (a cylinder of BARN
    world 0 1.5 m ahead of the Jackal)."""
    if target == "wall":
        return ("bulletnav/Warehouse-v0", {"num_obstacles": 0, "world_size": (10, 10)}, (0.0, 2.0, math.pi / 2),
                (-3.0, -3.0), 5.0 - 2.0)
    if target == "rack":
        return "bulletnav/Warehouse-v0", {"world": str(rack_world(folder))}, (0.0, 0.0, 0.0), (-3.0, -3.0), 2.0 - 0.45
    if target == "barn_cylinder":
        from bulletnav.barn.world import barn_layout

        cyl = min(barn_layout(0).obstacles, key=lambda o: math.dist(o.center, (-2.25, 6.0)))
        return ("bulletnav/BARN-v0", {"world_idx": 0}, (cyl.center[0], cyl.center[1] - 1.5, math.pi / 2), None,
                1.5 - cyl.radius)
    raise ValueError(f"unknown contact target {target!r}; known: wall, rack, barn_cylinder")


def contact_step(physics: str, env_id: str, kwargs: dict[str, Any], start: tuple[float, float, float], goal: Any,
                 steps: int = 240) -> tuple[int | None, float, float]:
    """The control step at which a robot driven at full speed from ``start`` through
    ``env.step`` first reports a contact (``info["collision"]``; None: none in ``steps``), how
    far it had got along its heading then (m), and its nose's length ahead of the body centre (m)."""
    import gymnasium as gym

    env = gym.make(env_id, physics=physics, **kwargs)
    try:
        env.reset(seed=0, options={"start": start} if goal is None else {"start": start, "goal": goal})
        scene = env.unwrapped.scene
        action = scene.action_for(scene.command_limits[0][1], 0.0)
        c, s = math.cos(start[2]), math.sin(start[2])
        for k in range(steps):
            _, _, terminated, truncated, info = env.step(action)
            if info.get("collision"):
                x, y, _ = info["pose"]
                return k, (x - start[0]) * c + (y - start[1]) * s, float(scene.geometry.nose)
            if terminated or truncated:
                break
        return None, math.nan, float(scene.geometry.nose)
    finally:
        env.close()


def bench_contacts(targets: tuple[str, ...] = ("wall", "rack", "barn_cylinder")) -> list[dict[str, Any]]:
    """Per target and profile: the first contact's step, and where the nose was then against the
    obstacle's face (m past it; negative: short of it)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for target in targets:
            env_id, kwargs, start, goal, face = contact_target(target, Path(tmp))
            row: dict[str, Any] = {"target": target, "env_id": env_id, "face_m": face}
            for physics in ("default", "fast", "kinematic"):
                first, along, nose = contact_step(physics, env_id, kwargs, start, goal)
                row[physics] = {"first_contact_step": first, "nose_past_face_m": along + nose - face}
            rows.append(row)
    return rows


PAIR_SUITE = Path(__file__).resolve().parents[1] / "benchmark" / "suites" / "kinematic-pair.yaml"
"""The quick suite's worlds, episodes and seed, each world in both profiles, PID + A* and PPO."""


def bench_outcomes(out: Path, workers: int = 1, suite_path: Path = PAIR_SUITE) -> dict[str, Any]:
    """Run (or resume) the ``kinematic-pair`` suite into ``out`` and compare each world's two
    profiles: per world and controller, success and collision rates in each, the points between
    them, the share of episodes with the same outcome (success, collision, time-out), and the
    episodes whose outcome differs."""
    from bulletnav.benchmark.report import OUTCOME_WORDS, outcome_of
    from bulletnav.benchmark.runner import run_suite
    from bulletnav.benchmark.suite import load_suite

    suite = load_suite(str(suite_path))
    results = run_suite(suite, out, workers=workers, resume=(out / "episodes.jsonl").exists())
    rows = {(r["world"], r["controller"], r["episode"]): r for r in results["episodes"]}

    def outcome(r: dict[str, Any]) -> str:
        return OUTCOME_WORDS[outcome_of(r)]

    pairs = []
    for world in suite.worlds:
        if world.name.endswith(" kinematic"):
            continue
        kinematic = f"{world.name} kinematic"
        for controller in suite.controllers:
            ref = [rows[(world.name, controller.name, k)] for k in range(suite.episodes_of(world))]
            kin = [rows[(kinematic, controller.name, k)] for k in range(suite.episodes_of(world))]
            differ = [{"episode": a["episode"], "seed": a["seed"], "default": outcome(a), "kinematic": outcome(b)}
                      for a, b in zip(ref, kin) if outcome(a) != outcome(b)]
            n = len(ref)
            entry = {"world": world.name, "controller": controller.name, "episodes": n,
                     "default": {"success": sum(r["success"] for r in ref) / n, "collision": sum(r["collision"] for r in ref) / n},
                     "kinematic": {"success": sum(r["success"] for r in kin) / n,
                                   "collision": sum(r["collision"] for r in kin) / n},
                     "same_outcome": 1.0 - len(differ) / n, "differing": differ}
            entry["success_points"] = 100.0 * (entry["kinematic"]["success"] - entry["default"]["success"])
            entry["collision_points"] = 100.0 * (entry["kinematic"]["collision"] - entry["default"]["collision"])
            pairs.append(entry)
    same = sum(p["same_outcome"] * p["episodes"] for p in pairs) / max(1, sum(p["episodes"] for p in pairs))
    return {"suite": suite.name, "out": str(out), "pairs": pairs, "same_outcome_overall": same,
            "suite_provenance": results.get("provenance", {})}


def bench_kinematic(out: Path, seeds: range = range(20), workers: int = 1) -> dict[str, Any]:
    """All four tables (:func:`bench_scans`, :func:`bench_manoeuvres`, :func:`bench_contacts`,
    :func:`bench_outcomes`) in one record."""
    return {"benchmark": "kinematic_agreement", "scans": bench_scans(seeds), "manoeuvres": bench_manoeuvres(),
            "contacts": bench_contacts(), "outcomes": bench_outcomes(out, workers)}
