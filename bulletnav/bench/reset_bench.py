"""What a reset costs, and what throughput is left once episodes end as they do in training.

Three measurements per registered id, each printed by ``bulletnav bench env --json``:

- ``reset_ms``: median wall time of ``env.reset()`` over ``resets`` consecutive unseeded
  resets (the registered kwargs: a new warehouse every reset, its free-space grids, start and
  goal, movers and events), after one seeded reset that compiles and warms up everything.
- ``raw_reset_ms``: the floor a hand-written PyBullet env pays to rebuild the same world,
  measured on the very layouts the env drew: ``resetSimulation``, the physics settings, then
  every body the env's client holds after its reset (floor, walls, obstacles, mover and event
  pools, with the same collision and visual shapes and poses) and the robot's URDF, in a
  private client, with no Python planning at all. A reset cannot cost less than this while it
  rebuilds the scene; ``reset_ms - raw_reset_ms`` is what the env's own work adds.
- ``steps_per_s_with_resets``: random uniform actions, ``gym.make``'s time limit, every episode
  end followed by ``reset()`` as in training, with ``reset_share`` the share of wall time spent
  inside ``reset()``.

:func:`bench_vec` measures vectorised throughput: Gymnasium's ``make_vec`` (sync and async)
and Stable-Baselines3's ``DummyVecEnv`` / ``SubprocVecEnv`` at 1, 2 and 4 envs.
"""

from __future__ import annotations

import time
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

from bulletnav.bench.env_bench import step_with_resets
from bulletnav.sim.client import configure_physics

REGISTERED = ("bulletnav/Warehouse-v0", "bulletnav/WarehouseAisles-v0", "bulletnav/WarehouseDynamic-v0",
              "bulletnav/WarehouseMission-v0")
"""The registered ids, in the order the benchmark reports them."""


def _snapshot(cid: int, robot: int) -> list[tuple]:
    """Every body of client ``cid`` but the robot, as the arguments to create it again:
    (collision geometry, dimensions, visual geometry, dimensions, colour, position, orientation)."""
    bodies = []
    for k in range(p.getNumBodies(physicsClientId=cid)):
        body = p.getBodyUniqueId(k, physicsClientId=cid)
        if body == robot:
            continue
        col = p.getCollisionShapeData(body, -1, physicsClientId=cid)[0]
        vis = p.getVisualShapeData(body, physicsClientId=cid)
        pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=cid)
        shape = (col[2], tuple(col[3]))
        visual = (vis[0][2], tuple(vis[0][3]), tuple(vis[0][7])) if vis else None
        bodies.append((shape, visual, pos, orn))
    return bodies


def _raw_build(cid: int, physics: Any, bodies: list[tuple], urdf: str) -> None:
    """Rebuild ``bodies`` (from :func:`_snapshot`) and the robot from scratch in client ``cid``."""
    p.resetSimulation(physicsClientId=cid)
    configure_physics(cid, physics)
    for (geom, dims), visual, pos, orn in bodies:
        if geom == p.GEOM_PLANE:
            col = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        elif geom == p.GEOM_BOX:
            col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[d / 2 for d in dims], physicsClientId=cid)
        else:  # cylinder: (height, radius, 0)
            col = p.createCollisionShape(p.GEOM_CYLINDER, radius=dims[1], height=dims[0], physicsClientId=cid)
        vis = -1
        if visual is not None:
            vgeom, vdims, colour = visual
            if vgeom == p.GEOM_BOX:
                vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[d / 2 for d in vdims], rgbaColor=colour,
                                          physicsClientId=cid)
            elif vgeom == p.GEOM_CYLINDER:
                vis = p.createVisualShape(p.GEOM_CYLINDER, radius=vdims[1], length=vdims[0], rgbaColor=colour,
                                          physicsClientId=cid)
        p.createMultiBody(0.0, col, vis, pos, orn, physicsClientId=cid)
    p.loadURDF(urdf, [0, 0, 0], flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_USE_IMPLICIT_CYLINDER, physicsClientId=cid)


def bench_resets(env_id: str, resets: int = 200, seed: int = 0) -> dict[str, Any]:
    """Median env reset and raw PyBullet rebuild of the same worlds (see the module docstring)."""
    import bulletnav  # noqa: F401  (registers the ids)

    env = gym.make(env_id)
    env.reset(seed=seed)  # compiles the kernels, loads the caches: not timed
    env.reset()
    unwrapped = env.unwrapped
    cid = unwrapped.scene.client
    times, worlds = [], []
    clock = time.perf_counter
    for _ in range(resets):
        t0 = clock()
        env.reset()
        times.append(clock() - t0)
        worlds.append(_snapshot(cid, unwrapped.scene.robot_body))
    config = unwrapped.config
    physics, urdf = config.physics, str(config.robot.urdf_path())
    env.close()
    raw_cid = p.connect(p.DIRECT)
    try:
        raw = []
        _raw_build(raw_cid, physics, worlds[0], urdf)  # warm-up
        for bodies in worlds:
            t0 = clock()
            _raw_build(raw_cid, physics, bodies, urdf)
            raw.append(clock() - t0)
    finally:
        p.disconnect(physicsClientId=raw_cid)
    ms = np.array(times) * 1e3
    raw_ms = np.array(raw) * 1e3
    return {
        "resets": resets,
        "reset_ms": round(float(np.median(ms)), 2),
        "reset_ms_p90": round(float(np.percentile(ms, 90)), 2),
        "reset_ms_mean": round(float(ms.mean()), 2),
        "raw_reset_ms": round(float(np.median(raw_ms)), 2),
        "bodies_per_world": round(float(np.mean([len(w) + 1 for w in worlds])), 1),
    }


def bench_throughput(env_id: str, steps: int = 6000, seed: int = 0) -> dict[str, Any]:
    """Steps/s under random actions with every episode end reset, as in training, and the share
    of wall time spent in ``reset()``."""
    import bulletnav  # noqa: F401

    env = gym.make(env_id)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(env.action_space.low, env.action_space.high, size=(steps, 2)).astype(np.float32)
    env.reset(seed=seed)
    wall, in_reset, episodes = step_with_resets(env, actions)
    env.close()
    return {
        "steps": steps,
        "steps_per_s_with_resets": round(steps / wall, 1),
        "steps_per_s_between_resets": round(steps / (wall - in_reset), 1),
        "reset_share": round(in_reset / wall, 4),
        "episodes": episodes,
        "mean_episode_steps": round(steps / max(episodes, 1), 1),
    }


def bench_ids(env_ids: tuple[str, ...] = REGISTERED, resets: int = 200, steps: int = 6000,
              seed: int = 0) -> dict[str, dict[str, Any]]:
    """:func:`bench_resets` and :func:`bench_throughput` for each id."""
    return {env_id: {**bench_resets(env_id, resets, seed), **bench_throughput(env_id, steps, seed)}
            for env_id in env_ids}


def _vec_rate(make: Any, kind: str, n: int, steps: int, seed: int) -> float:
    """Env steps per second of ``steps`` vector steps of ``n`` envs (random actions, autoreset)."""
    rng = np.random.default_rng(seed)
    if kind in ("sync", "async"):
        envs = make(n, kind)
        space = envs.single_action_space
        envs.reset(seed=seed)
        actions = rng.uniform(space.low, space.high, size=(steps, n, 2)).astype(np.float32)
        t0 = time.perf_counter()
        for a in actions:
            envs.step(a)
    else:
        envs = make(n, kind)
        space = envs.action_space
        envs.seed(seed)
        envs.reset()
        actions = rng.uniform(space.low, space.high, size=(steps, n, 2)).astype(np.float32)
        t0 = time.perf_counter()
        for a in actions:
            envs.step(a)
    rate = steps * n / (time.perf_counter() - t0)
    envs.close()
    return rate


def bench_vec(env_id: str = "bulletnav/Warehouse-v0", counts: tuple[int, ...] = (1, 2, 4), steps: int = 1000,
              seed: int = 0) -> dict[str, Any]:
    """Env steps/s of ``env_id`` at each number of envs: Gymnasium ``make_vec`` sync / async,
    SB3 ``DummyVecEnv`` / ``SubprocVecEnv`` (one torch-free process per env), ``steps`` vector
    steps each, resets included. Kinds are interleaved per count so machine drift hits all."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    import bulletnav  # noqa: F401

    def make(n: int, kind: str):
        if kind in ("sync", "async"):
            return gym.make_vec(env_id, num_envs=n, vectorization_mode=kind)
        cls = DummyVecEnv if kind == "sb3_dummy" else SubprocVecEnv
        return cls([lambda: gym.make(env_id)] * n)

    kinds = ("sync", "async", "sb3_dummy", "sb3_subproc")
    rows = []
    for n in counts:
        row = {"num_envs": n}
        for kind in kinds:
            row[f"{kind}_steps_per_s"] = round(_vec_rate(make, kind, n, steps, seed), 1)
        rows.append(row)
    single = rows[0]["sync_steps_per_s"] if rows and rows[0]["num_envs"] == 1 else None
    return {"benchmark": "env_vec", "env_id": env_id, "vector_steps": steps, "rows": rows,
            "reference_single_env_steps_per_s": single}


def bench_against(commit: str, env_ids: tuple[str, ...] = REGISTERED, rounds: int = 3, resets: int = 200,
                  steps: int = 6000, seed: int = 0, repo: str | None = None) -> dict[str, Any]:
    """:func:`bench_ids` of this checkout and of ``commit``, interleaved in one run.

    ``commit``'s tree is exported (``git archive``) to a temporary directory and given this
    checkout's copy of this module, so both sides are measured by the same code; each round
    runs both sides in fresh processes, in alternating order, so machine drift hits both alike.
    Per id, ``before`` and ``after`` hold the medians over rounds, ``speedup`` the median of the
    per-round ratios (after over before for steps/s, before over after for reset times).

    Raises:
        RuntimeError: ``commit`` cannot be exported (not a commit of ``repo``, no git).
    """
    import json
    import os
    import shutil
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    here = Path(__file__).resolve()
    root = Path(repo) if repo else here.parents[2]
    tmp = Path(tempfile.mkdtemp(prefix="bulletnav-before-"))
    try:
        archive = subprocess.run(["git", "-C", str(root), "archive", commit], capture_output=True)
        if archive.returncode != 0:
            raise RuntimeError(f"cannot export commit {commit!r} of {root}: {archive.stderr.decode().strip()}")
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive.stdout, check=True)
        shutil.copy(here, tmp / "bulletnav" / "bench" / "reset_bench.py")
        code = ("import json, sys; from bulletnav.bench.reset_bench import bench_ids; "
                f"print(json.dumps(bench_ids({tuple(env_ids)!r}, {resets}, {steps}, {seed})))")
        sides = {"before": tmp, "after": root}
        runs: dict[str, list[dict]] = {"before": [], "after": []}
        for r in range(rounds):
            for side in (("before", "after") if r % 2 == 0 else ("after", "before")):
                env = {**os.environ, "PYTHONPATH": str(sides[side])}
                out = subprocess.run([sys.executable, "-c", code], cwd=sides[side], env=env, capture_output=True,
                                     text=True, check=True)
                runs[side].append(json.loads(out.stdout.strip().splitlines()[-1]))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    result: dict[str, Any] = {"benchmark": "env_against", "before_commit": commit, "rounds": rounds, "resets": resets,
                              "steps": steps, "ids": {}}
    for env_id in env_ids:
        per = {side: [run[env_id] for run in runs[side]] for side in runs}
        row: dict[str, Any] = {}
        for side in ("before", "after"):
            row[side] = {key: round(float(np.median([r[key] for r in per[side]])), 2)
                         for key in ("reset_ms", "raw_reset_ms", "steps_per_s_with_resets", "reset_share")}
        row["speedup"] = {
            "steps_per_s_with_resets": round(float(np.median(
                [a["steps_per_s_with_resets"] / b["steps_per_s_with_resets"] for a, b in zip(per["after"], per["before"])])), 3),
            "reset": round(float(np.median([b["reset_ms"] / a["reset_ms"] for a, b in zip(per["after"], per["before"])])), 3),
        }
        result["ids"][env_id] = row
    return result
