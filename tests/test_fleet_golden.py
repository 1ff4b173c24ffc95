"""The fleet's seeded episodes stay bit-identical: per-step hashes of every robot's pose,
observation, reward and info (errands, collision counts, collision kind), and every mover's
pose, against references recorded before the fleet's scene, movers and views were folded
into the single-robot code.

Record the references again (only on purpose, at a commit whose behaviour is the reference)::

    .venv/bin/python tests/test_fleet_golden.py --record
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bulletnav.fleet import fleet_v0

GOLDEN = Path(__file__).resolve().parent / "golden" / "fleet_traces.json"

CASES: dict[str, dict[str, Any]] = {
    # "again": steps of a second, unseeded episode after the first (same layout, scene reused)
    # three robots among forklifts, workers and pallet events, each on its own PID + A* navigator
    "dynamic_n3_independent": {"env": {"num_robots": 3, "dynamic": True}, "seed": 5, "steps": 400,
                               "controller": "independent", "again": 60},
    # two robots in a static aisle warehouse on fixed actions (they drive into things)
    "static_n2_fixed": {"env": {"num_robots": 2}, "seed": 11, "steps": 150, "controller": "fixed",
                        "again": 60},
    # pallet events every few seconds, robots steered straight at their goals
    "events_n3_pursuit": {"env": {"num_robots": 3, "dynamic": True, "pallet_events_per_min": 40.0},
                          "seed": 2, "steps": 400, "controller": "pursuit"},
}


def _floats(values) -> bytes:
    return struct.pack(f"<{len(values)}d", *values)


def _fixed(env, step: int) -> dict:
    """Actions that depend on the step only: turning, driving, reversing the turn."""
    out = {}
    for i, agent in enumerate(env.possible_agents):
        phase = (step // 25 + i) % 4
        out[agent] = np.array([(0.8, 0.3), (0.5, -0.6), (1.0, 0.0), (0.2, 1.0)][phase], dtype=np.float32)
    return out


def _pursuit(env) -> dict:
    """Steer each robot straight at its current goal (ground-truth pose, physical actions)."""
    if env.config.normalize_actions:
        raise AssertionError("the pursuit controller gives physical actions")
    scene = env._scene  # test-only reach into the scene and the tasks
    out = {}
    for i, agent in enumerate(env.possible_agents):
        state = scene.robots[i].state
        goal = env._tasks[i].goal
        heading = math.atan2(goal[1] - state.y, goal[0] - state.x)
        err = math.remainder(heading - state.yaw, 2 * math.pi)
        out[agent] = np.array([0.6 if abs(err) < 0.8 else 0.05, 2.0 * err], dtype=np.float64)
    return out


def _step_hash(env, obs: dict, rewards: dict, infos: dict) -> str:
    scene = env._scene  # test-only reach into the scene
    h = hashlib.sha256()
    for i, agent in enumerate(env.possible_agents):
        s = scene.robots[i].state
        h.update(_floats([s.x, s.y, s.yaw, *s.linear_velocity, s.angular_velocity[2]]))
        h.update(np.ascontiguousarray(obs[agent]).tobytes())
        h.update(_floats([rewards.get(agent, 0.0)]))
        h.update(json.dumps(infos[agent], sort_keys=True, default=repr).encode())
    if scene.dynamic:
        for m in scene.movers.active:
            h.update(_floats([*m.pose, m.speed, float(m.yielding)]))
        h.update(json.dumps(list(scene.events.log), sort_keys=True, default=repr).encode())
    return h.hexdigest()[:20]


def rollout(case: dict[str, Any]) -> dict[str, Any]:
    """Per-step hashes of one seeded episode, and its totals (for a readable failure)."""
    env = fleet_v0.parallel_env(**case["env"])
    try:
        obs, infos = env.reset(seed=case["seed"])
        controller = None
        if case["controller"] == "independent":
            from bulletnav.fleet.controllers import make_controller
            controller = make_controller("independent", env)
            controller.reset(infos)
        hashes = [_step_hash(env, obs, {}, infos)]
        for steps in (case["steps"], case.get("again", 0)):
            if steps and len(hashes) > 1:
                obs, infos = env.reset()
                if controller is not None:
                    controller.reset(infos)
                hashes.append(_step_hash(env, obs, {}, infos))
            for step in range(steps):
                if controller is not None:
                    actions = controller.act(obs, infos)
                elif case["controller"] == "fixed":
                    actions = _fixed(env, step)
                else:
                    actions = _pursuit(env)
                obs, rewards, _terms, _truncs, infos = env.step(actions)
                hashes.append(_step_hash(env, obs, rewards, infos))
        totals = {agent: {k: infos[agent][k] for k in sorted(infos[agent])
                          if k.startswith("collisions_") or k in ("errands_completed", "legs_completed")}
                  for agent in env.possible_agents}
        totals["events"] = len(env._scene.events.log) if env._scene.dynamic else 0
        totals["movers"] = len(env._scene.movers.active) if env._scene.dynamic else 0
        return {"hashes": hashes, "totals": totals}
    finally:
        env.close()


REFERENCE = json.loads(GOLDEN.read_text()) if GOLDEN.exists() else {}


@pytest.mark.parametrize("name", sorted(CASES))
def test_fleet_rollout_is_bit_identical_to_the_reference(name):
    expected = REFERENCE[name]
    got = rollout(CASES[name])
    first = next((k for k, (a, b) in enumerate(zip(got["hashes"], expected["hashes"])) if a != b), None)
    assert first is None, f"{name}: first differs at step {first}; totals now {got['totals']}, were {expected['totals']}"
    assert got == expected


def test_the_references_exercise_what_they_claim():
    assert REFERENCE["dynamic_n3_independent"]["totals"]["movers"] > 0
    assert REFERENCE["events_n3_pursuit"]["totals"]["events"] > 0
    assert REFERENCE["static_n2_fixed"]["totals"]["movers"] == 0


if __name__ == "__main__" and sys.argv[1:] == ["--record"]:
    GOLDEN.parent.mkdir(exist_ok=True)
    GOLDEN.write_text(json.dumps({name: rollout(case) for name, case in CASES.items()}, indent=1) + "\n")
    print(f"wrote {GOLDEN}")
