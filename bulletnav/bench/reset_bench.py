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

:func:`bench_against` (``bulletnav bench env --against COMMIT``) measures reset times and
steps/s with resets of an older commit and of this checkout, interleaved in fresh processes,
with a self-contained script (``against_probe.py``) that any commit's tree can run: it needs
only ``import bulletnav`` and the public Gymnasium API (no raw rebuild there: that needs the
scene's internals).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p

from bulletnav import AISLES_ENV_ID, BARN_ENV_ID, DYNAMIC_ENV_ID, ENV_ID, MISSION_ENV_ID
from bulletnav.bench.env_bench import step_with_resets
from bulletnav.errors import BulletnavError
from bulletnav.sim.client import configure_physics
from bulletnav.sim.world import STATIC_GROUP

REGISTERED = (ENV_ID, AISLES_ENV_ID, DYNAMIC_ENV_ID, MISSION_ENV_ID)
"""The registered ids, in the order the benchmark reports them (BARN's worlds, ``BARN_ENV_ID``,
have their resets timed by :func:`bench_barn_resets`: seeded, so they rebuild)."""


def _snapshot(cid: int, robot: int, skip: frozenset[tuple[float, float, float]] = frozenset()) -> list[tuple]:
    """Every body of client ``cid`` but the robot (and bodies standing at a position in ``skip``),
    as the arguments to create it again: (collision geometry, dimensions, visual geometry,
    dimensions, colour, position, orientation)."""
    bodies = []
    for k in range(p.getNumBodies(physicsClientId=cid)):
        body = p.getBodyUniqueId(k, physicsClientId=cid)
        if body == robot:
            continue
        pos, orn = p.getBasePositionAndOrientation(body, physicsClientId=cid)
        if tuple(round(v, 4) for v in pos) in skip:
            continue
        col = p.getCollisionShapeData(body, -1, physicsClientId=cid)[0]
        vis = p.getVisualShapeData(body, physicsClientId=cid)
        shape = (col[2], tuple(col[3]))
        visual = (vis[0][2], tuple(vis[0][3]), tuple(vis[0][7])) if vis else None
        bodies.append((shape, visual, pos, orn))
    return bodies


def _raw_build(cid: int, physics: Any, bodies: list[tuple], urdf: str, batch: tuple = ()) -> None:
    """Rebuild ``bodies`` (from :func:`_snapshot`) and the robot from scratch in client ``cid``;
    with ``batch`` = (radius, height, positions), also those cylinders, static and collision-only,
    in one batched ``createMultiBody`` as :class:`~bulletnav.barn.world.BarnPhysicsWorld` builds them."""
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
    if batch:
        radius, height, positions = batch
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=height, physicsClientId=cid)
        p.createMultiBody(0.0, col, -1, batchPositions=positions, useMaximalCoordinates=True, physicsClientId=cid)
    p.loadURDF(urdf, [0, 0, 0], flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_USE_IMPLICIT_CYLINDER, physicsClientId=cid)


def bench_resets(env_id: str, resets: int = 200, seed: int = 0) -> dict[str, Any]:
    """Median env reset and raw PyBullet rebuild of the same worlds (see the module docstring);
    BARN-v0's by :func:`bench_barn_resets`."""
    import bulletnav  # noqa: F401  (registers the ids)

    if env_id == BARN_ENV_ID:
        return bench_barn_resets(resets, seed)

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


def _cylinder_batch(layout: Any) -> tuple:
    """(radius, height, positions) of ``layout``'s cylinders, as BARN's world builds them."""
    cylinders = [o for o in layout.obstacles if o.kind == "cylinder"]
    radius, height = cylinders[0].radius, cylinders[0].height
    return radius, height, [[o.center[0], o.center[1], height / 2] for o in cylinders]


def bench_barn_resets(resets: int = 200, seed: int = 0, world_idx: int = 0) -> dict[str, Any]:
    """BARN-v0's resets on world ``world_idx``, timed three ways, and the bare PyBullet floor.

    - ``reset_ms``: median of ``resets`` seeded resets (``reset(seed=seed + k)``): every one
      rebuilds the world (floor, walls, the world's cylinders in one batched call, the robot),
      as every bulletnav env does on a seeded reset;
    - ``unseeded_reset_ms``: median of unseeded resets on the same world (the robot moved back,
      nothing rebuilt);
    - ``switch_reset_ms``: median of unseeded resets that switch world (``options={"world_idx"}``,
      alternating with the next world);
    - ``raw_reset_ms``: the same bodies built from scratch in a bare PyBullet client
      (``resetSimulation``, the physics settings, floor and walls, the cylinders by one batched
      ``createMultiBody``, the robot's URDF): the floor of a rebuilding reset;
      ``raw_cylinders_ms`` the batched cylinder call alone. Batched bodies are not listed by
      ``getNumBodies``, so the cylinders come from the layout, the other bodies from the client;
    - ``scan_ms`` / ``bullet_scan_ms``: one lidar scan from the start pose, by the env's caster
      and by PyBullet's ``rayTestBatch`` (:func:`_scan_costs`).
    """
    env = gym.make(BARN_ENV_ID, world_idx=world_idx)
    env.reset(seed=seed)  # compiles the kernels, loads the caches: not timed
    scene = env.unwrapped.scene
    clock = time.perf_counter

    def median_ms(call: Any, n: int) -> tuple[float, float]:
        times = []
        for k in range(n):
            t0 = clock()
            call(k)
            times.append(clock() - t0)
        ms = np.array(times) * 1e3
        return round(float(np.median(ms)), 2), round(float(np.percentile(ms, 90)), 2)

    seeded, seeded_p90 = median_ms(lambda k: env.reset(seed=seed + 1 + k), resets)
    layout = scene.layout
    batch = _cylinder_batch(layout)  # the batched bodies (getNumBodies lists a few of them at most)
    others = _snapshot(scene.client, scene.robot_body, frozenset(tuple(round(v, 4) for v in c) for c in batch[2]))
    unseeded, _ = median_ms(lambda k: env.reset(), resets)
    switch, _ = median_ms(lambda k: env.reset(options={"world_idx": (world_idx + 1 - k % 2) % 300}), min(resets, 40))
    config = env.unwrapped.config
    physics, urdf = config.physics, str(config.robot.urdf_path())
    scan = _scan_costs(env, resets)
    env.close()
    raw_cid = p.connect(p.DIRECT)
    try:
        _raw_build(raw_cid, physics, others, urdf, batch)  # warm-up
        raw, _ = median_ms(lambda k: _raw_build(raw_cid, physics, others, urdf, batch), resets)
        cylinders = []
        for _ in range(min(resets, 40)):  # the batched call alone, each in an empty world
            p.resetSimulation(physicsClientId=raw_cid)
            configure_physics(raw_cid, physics)
            t0 = clock()
            col = p.createCollisionShape(p.GEOM_CYLINDER, radius=batch[0], height=batch[1], physicsClientId=raw_cid)
            p.createMultiBody(0.0, col, -1, batchPositions=batch[2], useMaximalCoordinates=True, physicsClientId=raw_cid)
            cylinders.append(clock() - t0)
    finally:
        p.disconnect(physicsClientId=raw_cid)
    return {"resets": resets, "world_idx": world_idx, "reset_ms": seeded, "reset_ms_p90": seeded_p90,
            "unseeded_reset_ms": unseeded, "switch_reset_ms": switch, "raw_reset_ms": raw,
            "raw_cylinders_ms": round(float(np.median(cylinders)) * 1e3, 2), "bodies_per_world": len(others) + len(batch[2]) + 1,
            **scan}


def _scan_costs(env: Any, n: int) -> dict[str, Any]:
    """Median ms of one lidar scan from the robot's start pose: the env's own (its caster, BARN-v0's
    ``"exact"``) and PyBullet's ``rayTestBatch`` of the same rays from the same link, in this process."""
    scene = env.unwrapped.scene
    lidar = scene.sensors.lidar
    cfg = lidar.config
    ray_to = [[cfg.max_range * np.cos(a), cfg.max_range * np.sin(a), 0.0] for a in lidar.angles]
    ray_from = [[0.0, 0.0, 0.0]] * len(ray_to)
    cid, body = scene.client, scene.robot_body
    link = next(j for j in range(p.getNumJoints(body, physicsClientId=cid))
                if p.getJointInfo(body, j, physicsClientId=cid)[12].decode() == "lidar_link")

    def bullet() -> None:
        p.rayTestBatch(ray_from, ray_to, parentObjectUniqueId=body, parentLinkIndex=link,
                       collisionFilterMask=STATIC_GROUP, physicsClientId=cid)

    times: dict[str, list[float]] = {"own": [], "bullet": []}
    for _ in range(n):  # interleaved, so load from other processes hits both alike
        for name, call in (("own", lidar.cast), ("bullet", bullet)):
            t0 = time.perf_counter()
            call()
            times[name].append(time.perf_counter() - t0)
    own, pyb = (float(np.median(times[k])) * 1e3 for k in ("own", "bullet"))
    return {"lidar_caster": cfg.caster, "lidar_rays": cfg.num_rays, "scan_ms": round(own, 3),
            "bullet_scan_ms": round(pyb, 3), "scan_speedup": round(pyb / own, 2)}


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


PROBE = Path(__file__).with_name("against_probe.py")
"""The self-contained measuring script both sides of :func:`bench_against` run."""

AGAINST_KEYS = ("reset_ms", "reset_ms_p90", "reset_cpu_ms", "steps_per_s_with_resets", "steps_per_s_between_resets",
                "cpu_steps_per_s_with_resets", "cpu_steps_per_s_between_resets", "reset_share", "episodes")
"""The probe's figures that :func:`bench_against` reports per side (medians over rounds)."""

RATIO_KEYS = ("steps_per_s_with_resets", "steps_per_s_between_resets", "cpu_steps_per_s_with_resets",
              "cpu_steps_per_s_between_resets")
"""Throughputs compared per round as after over before (reset times: before over after)."""


def _git(root: Path, *args: str) -> subprocess.CompletedProcess:
    """``git -C root args``; a missing git is a :class:`BulletnavError`."""
    try:
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True)
    except OSError as exc:
        raise BulletnavError(f"cannot run git: {exc}") from None


def _export(commit: str, root: Path, dest: Path) -> str:
    """Export ``commit`` of the repository at ``root`` into ``dest``; returns its full hash.

    Raises:
        BulletnavError: not a commit of ``root`` (or no git), or the export fails.
    """
    if not commit or commit.startswith("-"):
        raise BulletnavError(f"--against {commit!r}: not a commit")
    resolved = _git(root, "rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}")
    if resolved.returncode != 0:
        raise BulletnavError(f"--against {commit!r}: not a commit of {root}")
    full = resolved.stdout.decode().strip()
    archive = _git(root, "archive", full)
    if archive.returncode != 0:
        last = (archive.stderr.decode().strip().splitlines() or ["git archive failed"])[-1]
        raise BulletnavError(f"--against {commit!r}: cannot export it ({last})")
    untar = subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, capture_output=True)
    if untar.returncode != 0:
        raise BulletnavError(f"--against {commit!r}: cannot unpack its tree ({untar.stderr.decode().strip()})")
    return full


def _probe(python: str, tree: Path, spec: dict[str, Any], label: str) -> dict[str, Any]:
    """Run :data:`PROBE` in a fresh ``python`` process on ``tree`` (its working directory and
    ``PYTHONPATH``); its JSON answer.

    Raises:
        BulletnavError: the probe refuses the tree (import, unregistered id) or fails.
    """
    env = {**os.environ, "PYTHONPATH": str(tree)}
    argument = json.dumps({**spec, "tree": str(tree)})
    out = subprocess.run([python, "-c", PROBE.read_text(), argument], cwd=tree, env=env, capture_output=True,
                         text=True)
    lines = out.stdout.strip().splitlines()
    try:
        answer = json.loads(lines[-1]) if lines else None
    except ValueError:
        answer = None
    if not isinstance(answer, dict):
        last = (out.stderr.strip().splitlines() or [f"exit code {out.returncode}, no answer"])[-1]
        raise BulletnavError(f"{label}: cannot be measured ({last})")
    if "error" in answer:
        raise BulletnavError(f"{label}: cannot be measured ({answer['error']})")
    return answer


def _median(values: list[float]) -> float:
    return float(np.median(values)) if values else float("nan")


def _against_row(before: list[dict], after: list[dict]) -> dict[str, Any]:
    """One id's figures over rounds: each side's medians, the per-round ratios (after over
    before for steps/s, before over after for reset times: above 1 is faster), their median
    (``speedup``) and spread."""
    row: dict[str, Any] = {side: {key: round(_median([r[key] for r in runs]), 3) for key in AGAINST_KEYS}
                           for side, runs in (("before", before), ("after", after))}
    faster = {key: [a[key] / b[key] for a, b in zip(after, before)] for key in RATIO_KEYS}
    ratios = {**faster, "reset": [b["reset_ms"] / a["reset_ms"] for a, b in zip(after, before)],
              "reset_cpu": [b["reset_cpu_ms"] / a["reset_cpu_ms"] for a, b in zip(after, before)]}
    row["speedup"] = {key: round(_median(values), 3) for key, values in ratios.items()}
    row["ratios"] = {key: [round(v, 3) for v in values] for key, values in ratios.items()}
    return row


def bench_against(commit: str, env_ids: tuple[str, ...] = REGISTERED, rounds: int = 3, resets: int = 200,
                  steps: int = 6000, seed: int = 0, repo: str | None = None,
                  python: str | None = None) -> dict[str, Any]:
    """Reset times and steps/s with resets of ``commit``'s code and of this checkout, interleaved.

    ``commit``'s tree is exported (``git archive``) to a temporary directory. Both sides are
    measured by :data:`PROBE` (``bulletnav/bench/against_probe.py``), a self-contained script
    that needs nothing of either tree but ``import bulletnav`` and the public Gymnasium API,
    run by ``python`` (default: this interpreter) with the side's tree as working directory and
    ``PYTHONPATH``. The old tree is checked first (it imports, every id is registered); each
    round then runs both sides in fresh processes, in alternating order, so machine drift hits
    both alike. Per id, ``before`` and ``after`` hold the medians over rounds, ``speedup`` the
    median of the per-round ratios and ``ratios`` every round's (after over before for steps/s,
    before over after for reset times); ``load_average_1min`` the machine's load at start and end.

    Raises:
        BulletnavError: ``commit`` cannot be measured: not a commit of ``repo`` (default: the
            checkout holding this module), no git, its bulletnav does not import with this
            environment, or one of ``env_ids`` is not registered there.
    """
    root = Path(repo).resolve() if repo else Path(__file__).resolve().parents[2]
    python = python or sys.executable
    spec = {"ids": list(env_ids), "resets": resets, "steps": steps, "seed": seed}
    load = [round(os.getloadavg()[0], 2)]
    tmp = Path(tempfile.mkdtemp(prefix="bulletnav-before-"))
    try:
        full = _export(commit, root, tmp)
        sides = {"before": tmp, "after": root}
        labels = {"before": f"commit {commit}", "after": f"this checkout ({root})"}
        for side in ("before", "after"):
            _probe(python, sides[side], {**spec, "check": True}, labels[side])
        runs: dict[str, list[dict]] = {"before": [], "after": []}
        for r in range(rounds):
            for side in (("before", "after") if r % 2 == 0 else ("after", "before")):
                runs[side].append(_probe(python, sides[side], spec, labels[side])["ids"])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    load.append(round(os.getloadavg()[0], 2))
    head = _git(root, "rev-parse", "--short", "HEAD").stdout.decode().strip()
    dirty = bool(_git(root, "status", "--porcelain", "--untracked-files=no").stdout.strip())
    return {"benchmark": "env_against", "before_commit": full[:7], "after_commit": head + ("+changes" if dirty else ""),
            "rounds": rounds, "resets": resets, "steps": steps, "seed": seed, "measured_by": "bulletnav/bench/against_probe.py",
            "load_average_1min": load,
            "ids": {env_id: _against_row([run[env_id] for run in runs["before"]], [run[env_id] for run in runs["after"]])
                    for env_id in env_ids}}
