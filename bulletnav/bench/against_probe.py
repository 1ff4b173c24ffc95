"""The measuring script of ``bulletnav bench env --against COMMIT``: self-contained, so that it
runs unchanged inside any commit's tree.

:func:`bulletnav.bench.reset_bench.bench_against` runs this file's source with ``python -c``
in a fresh process whose working directory and ``PYTHONPATH`` are one tree (the exported old
commit, or this checkout). It imports nothing of bulletnav but the package itself (importing
it registers the ids) and uses only the public Gymnasium API every commit has:
``gymnasium.make`` of a registered id, ``env.reset`` / ``env.step``, ``env.action_space.seed``
and ``sample``. So both sides are measured by the very same code, whatever the old tree holds.

One argument, a JSON object: ``tree`` (the directory bulletnav must be imported from),
``ids``, ``resets``, ``steps``, ``seed``, and ``check`` (true: only import and look the ids up).
It prints one JSON line: ``{"bulletnav": file, "ids": {id: figures}}``, or ``{"error": why}``
(and exits 3) when the tree cannot be imported, an id is not registered there, or a
measurement fails. Per id:

- ``reset_ms`` (median), ``reset_ms_p90``, ``reset_ms_mean``: ``resets`` consecutive unseeded
  ``reset()`` calls after one seeded reset and one unseeded one (warm-up, not timed);
- ``steps_per_s_with_resets``: ``steps`` actions drawn beforehand from the action space seeded
  with ``seed`` (``action_space.sample``), every episode end followed by ``reset()`` as in
  training, from a reset seeded with ``seed``; ``steps_per_s_between_resets`` leaves the
  resets' time out, ``reset_share`` is their share of the wall time, ``episodes`` the episodes
  ended;
- ``reset_cpu_ms``, ``cpu_steps_per_s_with_resets``, ``cpu_steps_per_s_between_resets``: the
  same with the process's CPU time (``time.process_time``) in place of wall time, which a
  machine loaded by other processes inflates less (PyBullet's direct client runs in this
  process's thread).

This module is never imported by the package; it is read as text.
"""

import json
import os
import sys
import time


def _median(values):
    ms = sorted(values)
    n = len(ms)
    return (ms[(n - 1) // 2] + ms[n // 2]) / 2 if n else float("nan")


def _measure(gym, env_id, resets, steps, seed):
    clock, cpu = time.perf_counter, time.process_time
    env = gym.make(env_id)
    try:
        env.reset(seed=seed)  # compiles and loads whatever the tree caches: not timed
        env.reset()
        times, cpu_times = [], []
        for _ in range(resets):
            t0, c0 = clock(), cpu()
            env.reset()
            times.append(clock() - t0)
            cpu_times.append(cpu() - c0)
        env.action_space.seed(seed)
        actions = [env.action_space.sample() for _ in range(steps)]
        env.reset(seed=seed)
        in_reset = cpu_in_reset = 0.0
        episodes = 0
        t0, c0 = clock(), cpu()
        for a in actions:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                t1, c1 = clock(), cpu()
                env.reset()
                in_reset += clock() - t1
                cpu_in_reset += cpu() - c1
                episodes += 1
        wall, cpu_wall = clock() - t0, cpu() - c0
    finally:
        env.close()
    ms = sorted(t * 1e3 for t in times)
    n = len(ms)
    return {
        "resets": resets,
        "reset_ms": round(_median(ms), 3),
        "reset_ms_p90": round(ms[min(n - 1, int(round(0.9 * (n - 1))))], 3) if n else float("nan"),
        "reset_ms_mean": round(sum(ms) / n, 3) if n else float("nan"),
        "reset_cpu_ms": round(_median([t * 1e3 for t in cpu_times]), 3),
        "steps": steps,
        "steps_per_s_with_resets": round(steps / wall, 1),
        "steps_per_s_between_resets": round(steps / (wall - in_reset), 1),
        "cpu_steps_per_s_with_resets": round(steps / cpu_wall, 1),
        "cpu_steps_per_s_between_resets": round(steps / (cpu_wall - cpu_in_reset), 1),
        "reset_share": round(in_reset / wall, 4),
        "episodes": episodes,
    }


def main(argv):
    spec = json.loads(argv[1])
    tree = os.path.realpath(spec["tree"])
    try:
        import gymnasium as gym

        import bulletnav
    except Exception as exc:  # any import failure of the old tree is a reason to refuse it
        return {"error": f"cannot import bulletnav: {type(exc).__name__}: {exc}"}
    where = os.path.realpath(bulletnav.__file__)
    if not where.startswith(tree + os.sep):
        return {"error": f"bulletnav was imported from {where}, not from the tree {tree}"}
    missing = [env_id for env_id in spec["ids"] if env_id not in gym.registry]
    if missing:
        return {"error": f"not registered there: {', '.join(missing)}"}
    if spec.get("check"):
        return {"bulletnav": where, "ids": {}}
    out = {}
    for env_id in spec["ids"]:
        try:
            out[env_id] = _measure(gym, env_id, int(spec["resets"]), int(spec["steps"]), int(spec["seed"]))
        except Exception as exc:
            return {"error": f"{env_id} failed: {type(exc).__name__}: {exc}"}
    return {"bulletnav": where, "ids": out}


if __name__ == "__main__":
    result = main(sys.argv)
    print(json.dumps(result))
    sys.exit(3 if "error" in result else 0)
