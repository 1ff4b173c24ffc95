"""Running a suite: every controller on the same seeded episodes of every world, in parallel,
resumable, with the same rows whatever the number of workers.

Work is cut into chunks of episodes of one (world, controller) cell. A worker (this process,
a local process pool, or Ray tasks on a cluster) keeps one env and one controller per cell it
has seen. Episode ``k`` of a world is ``env.reset(seed=suite.seed + k)``, which rebuilds the
scene from scratch, and every controller resets per episode (RRT draws from a generator
seeded by the episode), so an episode's row depends on nothing but its cell and ``k``.
Finished rows are appended to ``DIR/episodes.jsonl`` as they arrive; ``resume`` skips them.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable, Sequence
from importlib import import_module
from pathlib import Path
from typing import Any

from bulletnav.benchmark.metrics import METRICS, EpisodeTrace, cell_summary, episode_metrics
from bulletnav.benchmark.suite import (
    ControllerSpec,
    Suite,
    SuiteError,
    WorldSpec,
    load_suite,
    replay_command,
    untrusted,
)
from bulletnav.errors import BulletnavError
from bulletnav.limits import inside
from bulletnav.provenance import git_commit
from bulletnav.runs import PROJECT_ROOT, RowLog, reopen_rows, run_in_pool, run_provenance, write_strict_json

log = logging.getLogger(__name__)

ROBOT_ACCEL = 2.6
"""The robot's peak acceleration (m/s^2; ``RobotConfig.max_wheel_torque``'s), for the time-optimal drive of SCT."""
PATH_EPISODES = 3
"""Rows keep the driven path (for the report's pictures) for the first this many episodes of a
cell and for every failure."""


def cell_key(world: str, controller: str, episode: int) -> str:
    return f"{world}\x1f{controller}\x1f{episode}"


MAX_CELLS = 16
"""Envs a worker keeps open at most: the least recently used is closed beyond this. Chunks come
world by world, so a cell is rarely needed again once the next ones have begun (a BARN suite
has 50 worlds x 6 controllers: 300 envs per worker otherwise); a cell made again gives the same
rows, for every episode is a seeded reset."""


class _Cells:
    """One worker's envs and controllers, made on first use per (world, controller), at most
    :data:`MAX_CELLS` open."""

    def __init__(self, suite: Suite, root: Path) -> None:
        self.suite, self.root = suite, root
        self.cells: dict[tuple[int, int], tuple[Any, Any]] = {}

    def get(self, w: int, c: int) -> tuple[Any, Any]:
        if (w, c) in self.cells:
            self.cells[(w, c)] = self.cells.pop((w, c))  # the most recently used last
        else:
            while len(self.cells) >= MAX_CELLS:
                env, _ = self.cells.pop(next(iter(self.cells)))
                env.close()
            self.cells[(w, c)] = make_cell(self.suite.worlds[w], self.suite.controllers[c], self.root,
                                           self.suite.trust_code)
        return self.cells[(w, c)]

    def close(self) -> None:
        for env, _ in self.cells.values():
            env.close()
        self.cells = {}


def make_cell(world: WorldSpec, controller: ControllerSpec, root: Path = PROJECT_ROOT,
              trust_code: bool = False) -> tuple[Any, Any]:
    """The env (behind the shield if asked) and the policy of one cell.

    Args:
        trust_code: import a policy class outside the allow-list (``--trust-code``).

    Raises:
        BulletnavError: a model file that cannot be loaded, a policy class outside the
            allow-list (without ``trust_code``) or that cannot be imported.
    """
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.rl.envs import EVALUATE_OBSTACLES, evaluation_env_kwargs

    kwargs: dict[str, Any] = {}
    policy_factory: Callable[[Any], Any]
    if controller.type == "navigator":
        from bulletnav.control.navigator import Navigator, NavigatorConfig

        def policy_factory(env):
            return Navigator(env.unwrapped.scene, NavigatorConfig(planner=controller.planner))
    elif controller.type == "dwa":
        from bulletnav.control.dwa import MoveBaseDWA, dwa_env_kwargs, load_dwa_params

        params = load_dwa_params(controller.params or None)
        kwargs = dwa_env_kwargs(params, {**world.kwargs, **controller.env})

        def policy_factory(env):
            return MoveBaseDWA(env.unwrapped.scene, params)
    elif controller.type == "model":
        import torch

        from bulletnav.rl.io import load_model
        from bulletnav.rl.policy import SB3Policy

        torch.set_num_threads(1)  # one thread: the same arithmetic in every worker, no oversubscription
        from bulletnav.rl.compat import check_model_fits

        model_path = controller.model_path(world.env, root)
        model, meta, vecnorm = load_model(model_path)
        kwargs = evaluation_env_kwargs(meta.get("env_kwargs", {}))
        if world.env == "bulletnav/Warehouse-v0":
            kwargs["num_obstacles"] = EVALUATE_OBSTACLES  # what `bulletnav evaluate` uses, unless the world says

        def policy_factory(env):
            check_model_fits(model, env, model_path, world.env)
            return SB3Policy(model, vecnorm)
    else:
        cls = policy_class(controller, trust_code)

        def policy_factory(env):
            return cls(env.unwrapped.scene, **controller.kwargs)
    env = gym.make(world.env, **{**kwargs, **world.kwargs, **controller.env})
    if controller.shield:
        from bulletnav.control.shield import ShieldWrapper

        env = ShieldWrapper(env)
    return env, policy_factory(env)


def policy_class(controller: ControllerSpec, trust_code: bool = False) -> type:
    """The class a ``policy`` controller names, imported only from the allow-list
    (:func:`bulletnav.benchmark.suite.untrusted`) unless ``trust_code``.

    Raises:
        BulletnavError: outside the allow-list, not importable, or not a class.
    """
    problem = None if trust_code else untrusted(controller.cls)
    if problem:
        raise SuiteError(f"controller {controller.name!r}: class {controller.cls!r}: {problem}")
    module_name, _, class_name = controller.cls.partition(":")
    try:
        cls = getattr(import_module(module_name), class_name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise BulletnavError(f"controller {controller.name!r}: cannot import {controller.cls!r} ({exc})") from None
    if not isinstance(cls, type):
        raise BulletnavError(f"controller {controller.name!r}: {controller.cls!r} is a {type(cls).__name__}, not a class")
    return cls


def run_chunk(cells: _Cells, w: int, c: int, episodes: list[int]) -> list[dict[str, Any]]:
    """Rows of ``episodes`` (indices k) of cell (world ``w``, controller ``c``)."""
    from bulletnav.evaluation import run_episodes

    suite = cells.suite
    world, controller = suite.worlds[w], suite.controllers[c]
    env, policy = cells.get(w, c)
    scene = env.unwrapped.scene
    top_speed = float(scene.command_limits[0][1])
    rows: list[dict[str, Any]] = []
    for k in episodes:
        trace = EpisodeTrace(scene.control_dt, top_speed)

        def on_reset(env_, info, trace=trace):
            trace.record(scene, info)

        def on_step(env_, info, trace=trace):
            trace.record(scene, info)

        def on_episode(result, trace=trace, k=k):
            row = episode_metrics(result, trace, ROBOT_ACCEL)
            row["episode"] = k
            if k >= PATH_EPISODES and result.success:
                row.pop("path")
            rows.append({"world": world.name, "controller": controller.name, **row})

        run_episodes(env, policy, 1, suite.seed + k, on_episode=on_episode, on_step=on_step, on_reset=on_reset)
    return rows


_PROCESS_CELLS: dict[str, _Cells] = {}


def _run_in_process(suite: Suite, root: str, w: int, c: int, episodes: list[int]) -> list[dict[str, Any]]:
    """A worker process's (or Ray task's) entry: its cached cells for this suite."""
    key = f"{suite.source}:{suite.sha256}"
    if key not in _PROCESS_CELLS:
        _PROCESS_CELLS[key] = _Cells(suite, Path(root))
    return run_chunk(_PROCESS_CELLS[key], w, c, episodes)


def plan_chunks(suite: Suite, done: set[str], workers: int) -> list[tuple[int, int, list[int]]]:
    """The (world, controller, episodes) chunks still to run, small enough to spread over
    ``workers`` and to lose little when interrupted."""
    chunks = []
    for w, world in enumerate(suite.worlds):
        n = suite.episodes_of(world)
        size = max(1, min(10, math.ceil(n / max(1, 2 * workers))))
        for c, controller in enumerate(suite.controllers):
            todo = [k for k in range(n) if cell_key(world.name, controller.name, k) not in done]
            chunks += [(w, c, todo[i:i + size]) for i in range(0, len(todo), size)]
    return chunks


def run_suite(suite: Suite, out: Path, workers: int = 1, address: str | None = None, resume: bool = False,
              progress: Callable[[int, int], None] | None = None, root: Path = PROJECT_ROOT,
              controllers: Sequence[str] | None = None, force: bool = False) -> dict[str, Any]:
    """Run ``suite`` into ``out`` (``episodes.jsonl`` as it goes, then ``results.json``) and
    return the results record. ``progress(done, total)`` is called after every chunk.

    Args:
        controllers: run only the suite's controllers of these names this time (``--controllers``);
            the others' episodes are left for a later run with ``resume`` (their cells stay empty).
        force: start afresh in an ``out`` that holds an earlier run or its results (its rows,
            ``results.json`` and report are replaced).

    Raises:
        BulletnavError: ``out`` holds an earlier run of another suite; holds an earlier run, and
            neither ``resume`` nor ``force`` is on; holds results (``results.json`` or the
            report) with no run to resume, and ``force`` is off; both ``resume`` and ``force``;
            a controller or model that cannot be loaded; a name in ``controllers`` that is not
            the suite's.
    """
    if workers < 1:
        raise BulletnavError(f"workers must be >= 1, got {workers}")
    names = [c.name for c in suite.controllers]
    unknown = [c for c in controllers or () if c not in names]
    if unknown:
        raise BulletnavError(f"--controllers: {unknown} not in {suite.source}; its controllers: {names}")
    out.mkdir(parents=True, exist_ok=True)
    try:  # a link named like one of the files must not carry the writes out of the folder
        log_path, meta_path, results_path = (inside(out, name) for name in ("episodes.jsonl", "suite.json", "results.json"))
    except ValueError as exc:
        raise BulletnavError(f"--out {out}: {exc}") from None
    if resume and force:
        raise BulletnavError("--resume goes on with the run in --out, --force starts it afresh: choose one")
    held = [name for name in ("results.json", "results.json.gz", "report.html") if (out / name).exists()]
    if log_path.exists() and not (resume or force):
        raise BulletnavError(f"{out} holds an earlier run ({log_path.name}): pass --resume to go on with it, "
                             "--force to start afresh over it, or choose another --out")
    if held and not log_path.exists() and not force:  # results (committed ones, say) and no run to go on with
        raise BulletnavError(f"{out} holds results ({', '.join(held)}) and no run to resume: pass --force to replace "
                             "them, or choose another --out (the default is runs/benchmark/<suite name>)")
    if force:  # the earlier run's rows, and a gzipped results file that would sit beside the new one
        for name in ("episodes.jsonl", "results.json.gz"):
            stale = inside(out, name)
            if stale.exists() or stale.is_symlink():
                stale.unlink()
    if resume and meta_path.is_file():
        earlier = json.loads(meta_path.read_text()).get("sha256")
        if earlier != suite.sha256:
            raise BulletnavError(f"{out} holds a run of another suite file (sha256 {str(earlier)[:12]}...), "
                                 f"not of {suite.source} ({suite.sha256[:12]}...): choose another --out")
    write_strict_json(meta_path, {"source": suite.source, "sha256": suite.sha256})
    rows = reopen_rows(log_path)
    done = {cell_key(r["world"], r["controller"], r["episode"]) for r in rows}
    chunks = plan_chunks(suite, done, workers)
    total = suite.total
    if controllers:
        chunks = [chunk for chunk in chunks if names[chunk[1]] in controllers]
        total = len(rows) + sum(len(eps) for _, _, eps in chunks)
    t0 = time.perf_counter()
    commit = git_commit()
    with RowLog(log_path, rows, total, progress) as keep_rows:
        def keep(new: list[dict[str, Any]]) -> None:  # each row names the checkout that ran it
            keep_rows([{**row, "commit": commit} for row in new])

        if address:
            _run_ray(suite, root, chunks, address, keep)
        elif workers == 1:
            cells = _Cells(suite, root)
            try:
                for w, c, eps in chunks:
                    keep(run_chunk(cells, w, c, eps))
            finally:
                cells.close()
        else:
            run_in_pool([(_run_in_process, (suite, str(root), w, c, eps)) for w, c, eps in chunks], workers, keep)
    results = build_results(suite, rows, root)
    results["provenance"] = run_provenance(time.perf_counter() - t0, workers, address)
    results["provenance"]["row_commits"] = row_commits(suite, rows)
    write_strict_json(results_path, results)
    return results


def row_commits(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, dict[str, int]]:
    """How many of each controller's rows (those :func:`build_results` keeps) each checkout ran:
    the ``commit`` a run stamps on the rows it adds to ``episodes.jsonl``, as
    :func:`~bulletnav.provenance.git_commit` gives it (``-dirty`` included). A run resumed at
    another commit mixes them, and the results say so; rows written before rows carried their
    commit count under ``"unrecorded"``. (The results' own rows leave the commit out, so a rerun
    at another commit gives the same rows.)"""
    counts: dict[str, dict[str, int]] = {}
    for row in _suite_rows(suite, rows).values():
        cell = counts.setdefault(row["controller"], {})
        commit = str(row.get("commit") or "unrecorded")
        cell[commit] = cell.get(commit, 0) + 1
    return {c.name: counts[c.name] for c in suite.controllers if c.name in counts}


def _suite_rows(suite: Suite, rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """The rows of ``suite``'s worlds and controllers, one per episode (the last written), by cell key."""
    worlds = {w.name for w in suite.worlds}
    controllers = {c.name for c in suite.controllers}
    return {cell_key(r["world"], r["controller"], r["episode"]): r for r in rows
            if r["world"] in worlds and r["controller"] in controllers}


def _run_ray(suite: Suite, root: Path, chunks: list, address: str, keep: Callable) -> None:
    """Run ``chunks`` as Ray tasks of one CPU each on the cluster at ``address``.

    Every node needs bulletnav installed and ``root`` (the project's models) at the same path,
    as on a shared file system. A connection this call opened is closed when it ends; one the
    caller already holds is left open.
    """
    import ray

    opened = not ray.is_initialized()
    if opened:
        _probe(address)
        try:
            ray.init(address=address, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise BulletnavError(f"--address {address}: cannot connect to a Ray cluster there ({exc})") from exc
    try:
        remote = ray.remote(num_cpus=1)(_run_in_process)
        pending = [remote.remote(suite, str(root), w, c, eps) for w, c, eps in chunks]
        while pending:
            finished, pending = ray.wait(pending, num_returns=1)
            keep(ray.get(finished[0]))
    finally:
        if opened:
            ray.shutdown()


def _probe(address: str, timeout_s: float = 5.0) -> None:
    """Refuse a ``HOST:PORT`` nobody listens on at once (Ray itself retries for minutes)."""
    import socket

    host, sep, port = address.rpartition(":")
    if not sep or "://" in address or not port.isdigit():
        return  # "auto", "ray://..." and other forms Ray resolves itself
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise BulletnavError(f"--address {address}: cannot connect to a Ray cluster there ({exc})") from None


def build_results(suite: Suite, rows: list[dict[str, Any]], root: Path = PROJECT_ROOT) -> dict[str, Any]:
    """The results record of ``rows``: rows sorted by world, controller and episode (the
    suite's order), a summary per cell, the suite, the metric definitions, and each failure's
    replay command."""
    order_w = {w.name: i for i, w in enumerate(suite.worlds)}
    order_c = {c.name: i for i, c in enumerate(suite.controllers)}
    unique = [{k: v for k, v in r.items() if k != "commit"} for r in _suite_rows(suite, rows).values()]
    ordered = sorted(unique, key=lambda r: (order_w[r["world"]], order_c[r["controller"]], r["episode"]))
    cells = []
    for world in suite.worlds:
        for controller in suite.controllers:
            cell = [r for r in ordered if r["world"] == world.name and r["controller"] == controller.name]
            cells.append({"world": world.name, "controller": controller.name, "summary": cell_summary(cell)})
    for row in ordered:
        if not row["success"]:
            world = suite.worlds[order_w[row["world"]]]
            controller = suite.controllers[order_c[row["controller"]]]
            row["replay"] = replay_command(suite, world, controller, row["seed"], root)
    results = {
        "suite": {"name": suite.name, "source": suite.source, "sha256": suite.sha256, "episodes": suite.episodes,
                  "seed": suite.seed,
                  "worlds": [_world_entry(suite, w) for w in suite.worlds],
                  "controllers": [{"name": c.name, "type": c.type, "planner": c.planner if c.type == "navigator" else None,
                                   "model": c.model or None, "class": c.cls or None, "shield": c.shield,
                                   **({"params": c.params or "barn"} if c.type == "dwa" else {}),
                                   **({"env": c.env} if c.env else {})}
                                  for c in suite.controllers]},
        "metrics": METRICS,
        "cells": cells,
        "episodes": ordered,
    }
    if any(w.group for w in suite.worlds):  # BARN's summary of its worlds, beside BARN's DWA rows
        from bulletnav.benchmark.barn import barn_sections

        results["barn"] = barn_sections(results["suite"]["worlds"], results["suite"]["controllers"], ordered)
    return results


def _world_entry(suite: Suite, w: WorldSpec) -> dict[str, Any]:
    """A world of the results' suite record (a BARN world also with its index and group)."""
    entry = {"name": w.name, "env": w.env, "kwargs": w.kwargs, "episodes": suite.episodes_of(w)}
    if w.group:
        entry.update(barn_world=w.barn_world, group=w.group)
    return entry


def replay(suite_path: str, world: str, controller: str, seed: int, trust_code: bool = False) -> dict[str, Any]:
    """Run one episode of a suite again (episode ``seed - suite.seed`` of ``world`` with
    ``controller``) and return its row (``trust_code``: as ``--trust-code``).

    Raises:
        SuiteError: no world or controller of that name in the suite.
    """
    suite = load_suite(suite_path, trust_code)
    names_w = [w.name for w in suite.worlds]
    names_c = [c.name for c in suite.controllers]
    if world not in names_w or controller not in names_c:
        raise SuiteError(f"{suite.source}: no world {world!r} / controller {controller!r}; worlds {names_w}, "
                         f"controllers {names_c}")
    cells = _Cells(suite, PROJECT_ROOT)
    try:
        return run_chunk(cells, names_w.index(world), names_c.index(controller), [seed - suite.seed])[0]
    finally:
        cells.close()
