"""``bulletnav bench env --env bulletnav/BARN-v0``: seeded resets (each rebuilds the world) against the
same bodies built in bare PyBullet, whose batched cylinders ``getNumBodies`` does not list.

References: world 0's cylinder count from BARN's world_0.world (209, counted by tests/test_barn_data.py's
regex over the file), and PyBullet's own ray casts in the bare client. No timing is asserted."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import pybullet as p
import pytest

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.bench.reset_bench import _cylinder_batch, _raw_build, _snapshot
from bulletnav.cli import main

WORLD_0_CYLINDERS = 209  # unit_cylinder_0 .. unit_cylinder_208 in BARN's world_0.world


def test_bench_env_barn_times_seeded_resets_and_the_bare_floor(capsys):
    assert main(["bench", "env", "--env", "bulletnav/BARN-v0", "--resets", "2", "--steps", "30", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)["ids"]["bulletnav/BARN-v0"]
    # floor, 4 walls, the robot and world 0's cylinders: the batched ones counted too
    assert row["bodies_per_world"] == WORLD_0_CYLINDERS + 6 and row["world_idx"] == 0
    for key in ("reset_ms", "unseeded_reset_ms", "switch_reset_ms", "raw_reset_ms", "raw_cylinders_ms", "scan_ms", "bullet_scan_ms",
                "steps_per_s_with_resets"):
        assert row[key] > 0.0 and math.isfinite(row[key])


def test_bare_rebuild_holds_the_envs_world():
    env = gym.make("bulletnav/BARN-v0", world_idx=0)
    env.reset(seed=0)
    scene = env.unwrapped.scene
    batch = _cylinder_batch(scene.layout)
    others = _snapshot(scene.client, scene.robot_body, frozenset(tuple(round(v, 4) for v in c) for c in batch[2]))
    starts = [[-4.3 + 0.1 * k, 4.0, 0.5] for k in range(43)]  # rays north through the clutter, 0.5 m up
    ends = [[x, 14.0, z] for x, _, z in starts]
    config = env.unwrapped.config
    rays = p.rayTestBatch(starts, ends, physicsClientId=scene.client)
    env.close()
    cid = p.connect(p.DIRECT)
    try:
        _raw_build(cid, config.physics, others, str(config.robot.urdf_path()), batch)
        bare = p.rayTestBatch(starts, ends, physicsClientId=cid)
    finally:
        p.disconnect(physicsClientId=cid)
    assert len(others) == 5 and len(batch[2]) == WORLD_0_CYLINDERS  # floor and walls listed; cylinders from the layout
    hits = [r[2] for r in rays]
    assert sum(h < 1.0 for h in hits) > len(hits) // 2  # the clutter is there ...
    assert [r[2] for r in bare] == pytest.approx(hits, abs=1e-6)  # ... and the bare world has it where the env does
