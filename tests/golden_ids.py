"""Golden references of the registered ids besides ``Warehouse-v0`` (and a reset-heavy trace of
``Warehouse-v0`` too): what a change to the reset path must leave bit-identical.

    python tests/golden_ids.py            # record tests/golden/env_ids.json (before a change)

Two kinds of trace per id, each a SHA-256 over everything an agent or consumer sees:
- ``rollout``: seeded random actions for ``STEPS`` steps; each episode end resets, alternately
  seeded and unseeded (the latter continue ``np_random``: training's resets);
- ``resets``: ``RESETS`` resets in a row (seeded, then unseeded), each followed by ``PEEK``
  random steps: covers many layouts, starts, goals and mover draws cheaply.
Every observation, reward, flag, every ``info`` entry (recursively; body ids excluded, they
name objects, not behaviour), the layout's obstacles and the movers' views go into the hash.
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

GOLDEN = Path(__file__).resolve().parent / "golden" / "env_ids.json"
IDS = ("bulletnav/Warehouse-v0", "bulletnav/WarehouseAisles-v0", "bulletnav/WarehouseDynamic-v0",
       "bulletnav/WarehouseMission-v0")
SEEDS = (3, 11)
STEPS = 300
RESETS = 25
PEEK = 5


def feed(h, value) -> None:
    """Hash ``value`` (numbers, arrays, strings, None, sequences, mappings, dataclasses) exactly."""
    if isinstance(value, np.ndarray):
        h.update(value.dtype.str.encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif value is None:
        h.update(b"N")
    elif isinstance(value, (bool, np.bool_)):
        h.update(b"T" if value else b"F")
    elif isinstance(value, (float, int, np.floating, np.integer)):
        h.update(struct.pack("<d", float(value)))
    elif isinstance(value, str):
        h.update(value.encode() + b"\0")
    elif isinstance(value, dict):
        for key in sorted(value):
            if key != "body":
                h.update(str(key).encode() + b"=")
                feed(h, value[key])
    elif isinstance(value, (tuple, list)):
        h.update(b"[")
        for v in value:
            feed(h, v)
        h.update(b"]")
    elif hasattr(value, "__dataclass_fields__"):
        feed(h, {k: getattr(value, k) for k in value.__dataclass_fields__})
    else:
        raise TypeError(type(value))


def _feed_scene(h, env) -> None:
    scene = env.unwrapped.scene
    feed(h, scene.layout.obstacles)
    feed(h, scene.movers)


def rollout_hash(env_id: str, seed: int, steps: int = STEPS) -> str:
    env = gym.make(env_id)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    feed(h, (obs, info))
    _feed_scene(h, env)
    episode = 0
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(env.action_space.low, env.action_space.high)
                                                            .astype(np.float32))
        feed(h, (obs, reward, terminated, truncated, info))
        if terminated or truncated:
            episode += 1
            obs, info = env.reset(seed=seed + 1000 * episode if episode % 2 else None)
            feed(h, (obs, info))
            _feed_scene(h, env)
    env.close()
    return h.hexdigest()


def resets_hash(env_id: str, seed: int, resets: int = RESETS, peek: int = PEEK) -> str:
    env = gym.make(env_id)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    for k in range(resets):
        obs, info = env.reset(seed=seed if k == 0 else None)
        feed(h, (obs, info))
        _feed_scene(h, env)
        for _ in range(peek):
            obs, reward, terminated, truncated, info = env.step(
                rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32))
            feed(h, (obs, reward, terminated, truncated, info))
            if terminated or truncated:
                break
    env.close()
    return h.hexdigest()


def record() -> dict:
    return {env_id: {"rollout": {str(s): rollout_hash(env_id, s) for s in SEEDS},
                     "resets": {str(s): resets_hash(env_id, s) for s in SEEDS}} for env_id in IDS}


def main() -> int:
    import subprocess

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    data = {"recorded_at_commit": commit, "steps": STEPS, "resets": RESETS, "peek": PEEK, "traces": record()}
    tmp = GOLDEN.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(GOLDEN)
    print(f"wrote {GOLDEN}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
