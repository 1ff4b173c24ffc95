"""Record the golden references of ``bulletnav/Warehouse-v0`` (run once, before a refactor).

    python tests/golden_record.py

Writes ``tests/golden/warehouse_v0.json``: SHA-256 hashes of seeded rollouts (observation
bytes, reward, and the info entries that existed when the references were made) for a few
env settings, and the shipped PPO policy's per-episode results on the first 30 evaluation
episodes at ``evaluate``'s default seed,
and PID + A*'s on the first 10 of ``navigate``'s. ``tests/test_golden.py`` checks them bit for bit.
"""

from __future__ import annotations

import hashlib
import json
import struct
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import bulletnav  # noqa: F401

ROOT = Path(__file__).resolve().parent.parent
GOLDEN = Path(__file__).resolve().parent / "golden" / "warehouse_v0.json"

INFO_KEYS = ("reward_progress", "reward_goal", "reward_collision", "reward_time", "reward_heading", "reward_stuck",
             "reward_proximity", "distance_to_goal", "collision", "is_success", "path_length", "initial_distance",
             "goal", "pose")
"""The info entries of Warehouse-v0 as released; new entries may be added, these must not change."""

SETTINGS = {
    "default": {},
    "odometry_pose_noisy": {"pose_source": "odometry", "lidar_noise": 0.02, "odometry_noise": 0.002},
    "normalized_40_obstacles_layouts_every_3": {"normalize_actions": True, "num_obstacles": 40, "layouts_every": 3},
}
SEEDS = (0, 7, 123)
STEPS = 300


def _feed(h, value) -> None:
    if isinstance(value, np.ndarray):
        h.update(value.dtype.str.encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, (bool, np.bool_)):
        h.update(b"T" if value else b"F")
    elif isinstance(value, (float, int, np.floating, np.integer)):
        h.update(struct.pack("<d", float(value)))
    elif isinstance(value, (tuple, list)):
        for v in value:
            _feed(h, v)
    else:
        raise TypeError(type(value))


def rollout_hash(kwargs: dict, seed: int, steps: int = STEPS) -> str:
    """Hash of ``steps`` steps of seeded random actions (new episode seeded ``seed + k`` on each end)."""
    env = gym.make("bulletnav/Warehouse-v0", **kwargs)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    episode = 0
    obs, info = env.reset(seed=seed)
    _feed(h, obs)
    for key in INFO_KEYS:
        _feed(h, info[key])
    for _ in range(steps):
        action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        _feed(h, obs)
        _feed(h, reward)
        _feed(h, (terminated, truncated))
        for key in INFO_KEYS:
            _feed(h, info[key])
        if terminated or truncated:
            episode += 1  # alternate seeded and unseeded resets (the latter continue np_random)
            obs, info = env.reset(seed=seed + 1000 * episode if episode % 2 else None)
            _feed(h, obs)
            for key in INFO_KEYS:
                _feed(h, info[key])
    env.close()
    return h.hexdigest()


EPISODE_KEYS = ("seed", "initial_distance", "shortest_path", "steps", "reward", "final_distance", "path_length",
                "success", "collision", "spl")


def _navigator_episodes() -> list[dict]:
    import subprocess

    out = subprocess.run([sys.executable, "-m", "bulletnav.cli", "navigate", "--planner", "astar", "--episodes", "10",
                          "--json"], check=True, capture_output=True, text=True, cwd=ROOT).stdout
    return [{k: e[k] for k in (*EPISODE_KEYS, "replans")} for e in json.loads(out)["per_episode"]]


def rerecord_navigator(reason: str) -> int:
    """Re-record only the classical navigator's episodes (after a change to the navigator,
    never to the env: the traces and the shipped policy's episodes stay as recorded)."""
    golden = json.loads(GOLDEN.read_text())
    golden["astar_navigate_seed_0"] = _navigator_episodes()
    golden.setdefault("navigator_rerecorded", []).append(reason)
    GOLDEN.write_text(json.dumps(golden, indent=1) + "\n")
    print(f"re-recorded the navigator's episodes in {GOLDEN}")
    return 0


def main() -> int:
    if sys.argv[1:2] == ["--navigator"]:
        return rerecord_navigator(" ".join(sys.argv[2:]) or "unspecified")
    traces = {name: {str(s): rollout_hash(kw, s) for s in SEEDS} for name, kw in SETTINGS.items()}
    import subprocess

    out = subprocess.run([sys.executable, "-m", "bulletnav.cli", "evaluate", "--model", str(ROOT / "models/ppo_warehouse.zip"),
                          "--episodes", "30", "--json"], check=True, capture_output=True, text=True).stdout
    per = json.loads(out)["per_episode"]
    episodes = [{k: e[k] for k in EPISODE_KEYS} for e in per]
    out = subprocess.run([sys.executable, "-m", "bulletnav.cli", "navigate", "--planner", "astar", "--episodes", "10",
                          "--json"], check=True, capture_output=True, text=True).stdout
    nav = [{k: e[k] for k in (*EPISODE_KEYS, "replans")} for e in json.loads(out)["per_episode"]]
    GOLDEN.parent.mkdir(exist_ok=True)
    GOLDEN.write_text(json.dumps({"steps": STEPS, "info_keys": INFO_KEYS, "settings": SETTINGS, "traces": traces,
                                  "ppo_evaluate_seed_1000": episodes,
                                  "astar_navigate_seed_0": nav}, indent=1) + "\n")
    print(f"wrote {GOLDEN}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
