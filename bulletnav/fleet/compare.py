"""Every fleet controller, with and without the safety shield, on the same seeded episodes.

:func:`run_comparison` runs each :class:`Entry` (a controller, its model, shield on or off) at
each fleet size on episodes seeded ``seed``, ``seed + 1``, ...; every entry meets the same
worlds, starts, errands, movers and events (checked: each row carries a fingerprint of its
episode's reset, and :func:`build_comparison` refuses rows of one episode that differ). Rows
go to ``episodes.jsonl`` as they finish, so an interrupted run goes on with ``resume=True``;
then ``comparison.json`` (settings, provenance, a summary per entry and size, every row) and
``comparison.md`` (one table per size) are written atomically.

What ``bulletnav fleet-compare`` runs; the committed tables are in ``docs/results/fleet/``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import BulletnavError, ConfigError
from bulletnav.fleet.metrics import METRICS, TYPICAL_ERRAND_S, rate_counts, run_fleet_episodes, summarize
from bulletnav.runs import PROJECT_ROOT, RowLog, reopen_rows, run_in_pool, run_provenance, write_strict_json

log = logging.getLogger(__name__)

CONTROLLER_NAMES = ("independent", "coordinated", "policy")


@dataclass(frozen=True)
class Entry:
    """One column of the comparison: a fleet controller, its model, the shield on or off."""

    label: str
    """Its name in the tables, e.g. ``"coordinated + shield"``."""
    controller: str
    """``independent``, ``coordinated`` or ``policy`` (:func:`~bulletnav.fleet.controllers.make_controller`)."""
    model: str | None = None
    """The policy controller's model file (a path relative to the project root, or absolute)."""
    shield: bool = False
    """Every robot behind the safety shield."""

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLER_NAMES:
            raise ConfigError(f"fleet comparison controller must be one of {', '.join(CONTROLLER_NAMES)}, "
                              f"got {self.controller!r}")
        if (self.controller == "policy") != (self.model is not None):
            raise ConfigError(f"fleet comparison entry {self.label!r}: a model goes with the policy controller "
                              "and only with it")


def parse_entries(specs: Sequence[str], shield: str = "both") -> list[Entry]:
    """Entries from the command line's controller specs: ``independent``, ``coordinated`` or
    ``policy=PATH`` (labelled by the model's file stem), each without and/or with the shield
    (``shield``: ``off``, ``on`` or ``both``).

    Raises:
        ConfigError: an unknown controller, a policy without a model file, a repeated spec.
    """
    if shield not in ("off", "on", "both"):
        raise ConfigError(f"--shield must be off, on or both, got {shield!r}")
    if not specs:
        raise ConfigError("--controllers needs at least one controller")
    shields = {"off": (False,), "on": (True,), "both": (False, True)}[shield]
    entries, seen = [], set()
    for spec in specs:
        name, _, model = spec.partition("=")
        if name == "policy":
            if not model:
                raise ConfigError(f"--controllers {spec!r}: the policy controller needs a model, policy=PATH")
            base = Path(model).stem
        elif model:
            raise ConfigError(f"--controllers {spec!r}: only the policy controller takes =PATH")
        else:
            base = name
        if spec in seen:
            raise ConfigError(f"--controllers names {spec!r} twice")
        seen.add(spec)
        for on in shields:
            entries.append(Entry(f"{base} + shield" if on else base, name, model or None, on))
    return entries


DEFAULT_CONTROLLERS = ("independent", "coordinated", "policy=models/ppo_dynamic.zip", "policy=models/ppo_fleet.zip")
"""What ``fleet-compare`` runs unless told otherwise: the two classical controllers, the shipped
single-robot policy zero-shot, and the policy trained in the fleet."""


def episode_fingerprint(infos: dict[str, dict[str, Any]]) -> str:
    """A short hash of an episode's reset: every robot's pose and first errand (rounded to a
    millimetre, so two controllers' envs built alike agree)."""
    parts = []
    for agent in sorted(infos):
        info = infos[agent]
        errand = info.get("errand") or {}
        parts.append([agent, [round(float(v), 3) for v in info["pose"]],
                      [round(float(v), 3) for v in errand.get("pick", ())],
                      [round(float(v), 3) for v in errand.get("drop", ())]])
    return hashlib.sha256(json.dumps(parts).encode()).hexdigest()[:16]


def entry_env_kwargs(entry: Entry, base: dict[str, Any], root: Path) -> dict[str, Any]:
    """The fleet env's keyword arguments for ``entry``: ``base`` plus, for a policy, the env
    settings its model was trained with."""
    from bulletnav.fleet.controllers import model_env_kwargs

    kwargs = dict(model_env_kwargs(resolve(entry.model, root))) if entry.model else {}
    kwargs.update(base)
    return kwargs


def resolve(path: str | None, root: Path) -> str | None:
    """``path`` itself when absolute, else under ``root``."""
    if path is None:
        return None
    p = Path(path)
    return str(p if p.is_absolute() else root / p)


def run_chunk(entry: Entry, robots: int, base: dict[str, Any], seed: int, episodes: list[int],
              root: str) -> list[dict[str, Any]]:
    """Run ``episodes`` (consecutive indices) of ``entry`` with ``robots`` robots; one row each."""
    from bulletnav.fleet.controllers import make_controller

    first = episodes[0]
    if episodes != list(range(first, first + len(episodes))):
        raise BulletnavError(f"a chunk's episodes must be consecutive, got {episodes}")
    kwargs = entry_env_kwargs(entry, {**base, "num_robots": robots}, Path(root))
    if entry.model is not None:
        import torch

        # one thread: two workers on two cores with two threads each spend the policy's time
        # waiting for each other (4 ms a forward pass of 8 robots against 0.4 ms); the actions
        # are the same
        torch.set_num_threads(1)
    prints: list[str] = []

    def on_step(env: Any, infos: dict[str, dict[str, Any]]) -> None:
        if infos and all(float(info["time_s"]) == 0.0 for info in infos.values()):
            prints.append(episode_fingerprint(infos))

    result = run_fleet_episodes(
        kwargs, lambda env: make_controller(entry.controller, env, shield=entry.shield,
                                            model=resolve(entry.model, Path(root))),
        episodes=len(episodes), seed=seed + first, on_step=on_step)
    rows = []
    for row, fingerprint in zip(result["episodes"], prints, strict=True):
        rows.append({**row, "entry": entry.label, "robots": robots, "episode": first + row["episode"],
                     "fingerprint": fingerprint})
    return rows


def row_key(entry: str, robots: int, episode: int) -> str:
    return f"{robots}/{entry}/{episode}"


def plan_chunks(entries: list[Entry], robots: Sequence[int], episodes: int, done: set[str],
                size: int = 2) -> list[tuple[Entry, int, list[int]]]:
    """The (entry, robots, episodes) chunks still to run: episodes in blocks of ``size``, each
    block for every size and entry before the next block (so a run stopped early holds the same
    episodes of every entry, a fair comparison on fewer episodes), the largest fleets first
    within a block."""
    chunks = []
    for start in range(0, episodes, size):
        block = range(start, min(start + size, episodes))
        for n in sorted(robots, reverse=True):
            for entry in entries:
                todo = [k for k in block if row_key(entry.label, n, k) not in done]
                runs: list[list[int]] = []
                for k in todo:  # consecutive runs within the block
                    if runs and runs[-1][-1] == k - 1:
                        runs[-1].append(k)
                    else:
                        runs.append([k])
                chunks += [(entry, n, run) for run in runs]
    return chunks


def run_comparison(out: Path, entries: list[Entry], robots: Sequence[int] = (4, 8), episodes: int = 40,
                   seed: int = 1000, env_kwargs: dict[str, Any] | None = None, workers: int = 1,
                   resume: bool = False, progress: Callable[[int, int], None] | None = None,
                   root: Path | None = None, run: bool = True) -> dict[str, Any]:
    """Run every entry at every fleet size on ``episodes`` seeded episodes into ``out``.

    Args:
        out: directory for ``episodes.jsonl``, ``comparison.json`` and ``comparison.md``.
        entries: the columns (:func:`parse_entries`).
        robots: fleet sizes.
        episodes: episodes per entry and size, episode k seeded ``seed + k``.
        seed: the first episode's seed.
        env_kwargs: the fleet env's keyword arguments other than ``num_robots`` (e.g.
            ``duration_s``, ``dynamic``); a policy entry adds its model's env settings.
        workers: processes running chunks of episodes at once.
        resume: go on with the rows already in ``out``'s ``episodes.jsonl`` (the settings
            must be the same).
        progress: ``progress(done, total)`` after every chunk.
        root: where relative model paths are found (the project root by default).
        run: False runs no episode: the tables are written from the rows already in ``out``
            (a resumed run's settings must match), on the episodes every entry has at each
            size, so a run stopped early still gives a fair comparison on fewer episodes.

    The tables always cover only the episodes every entry has at a size (all of them once
    the run is complete).

    Raises:
        BulletnavError: ``out`` holds an earlier run and ``resume`` is off, or a run of other
            settings; bad settings; a model that cannot be loaded; ``run`` off and no rows
            of every entry at some size.
    """
    root = Path(root or PROJECT_ROOT)
    env_kwargs = dict(env_kwargs or {})
    _check_arguments(entries, robots, episodes, workers, env_kwargs, root)
    labels = [e.label for e in entries]
    settings = {"entries": [entry_record(e, root) for e in entries], "robots": list(robots), "episodes": episodes,
                "seed": seed, "env_kwargs": env_kwargs}
    log_path, rows = _open_run(out, settings, resume or not run, run)
    rows = [r for r in rows if r["entry"] in labels and r["robots"] in robots and r["episode"] < episodes]
    done = {row_key(r["entry"], r["robots"], r["episode"]) for r in rows}
    chunks = plan_chunks(entries, robots, episodes, done) if run else []
    total = len(entries) * len(robots) * episodes
    t0 = time.perf_counter()
    with RowLog(log_path, rows, total, progress) as keep:
        if workers == 1:
            for entry, n, eps in chunks:
                keep(run_chunk(entry, n, env_kwargs, seed, eps, str(root)))
        else:
            run_in_pool([(run_chunk, (entry, n, env_kwargs, seed, eps, str(root))) for entry, n, eps in chunks],
                        workers, keep)
    common = common_episodes(rows, labels, robots)
    if not run and not all(common.values()):
        raise BulletnavError(f"{out}: no episode that every entry has at "
                             f"{', '.join(str(n) for n, ks in common.items() if not ks)} robots: nothing to compare")
    results = build_comparison(settings, [r for r in rows if r["episode"] in common[r["robots"]]])
    results["provenance"] = run_provenance(time.perf_counter() - t0, workers, None)
    write_strict_json(out / "comparison.json", results)
    from bulletnav.files import write_bytes

    write_bytes(out / "comparison.md", comparison_markdown(results).encode())
    return results


def _check_arguments(entries: list[Entry], robots: Sequence[int], episodes: int, workers: int,
                     env_kwargs: dict[str, Any], root: Path) -> None:
    """Raise for bad settings of :func:`run_comparison`, and for an entry's missing model (now,
    not an hour in)."""
    if "num_robots" in env_kwargs:
        raise ConfigError("pass fleet sizes as robots=, not env_kwargs['num_robots']")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ConfigError(f"episodes must be a whole number >= 1, got {episodes!r}")
    if not robots or any(isinstance(n, bool) or not isinstance(n, int) or n < 1 for n in robots):
        raise ConfigError(f"robots must be fleet sizes >= 1, got {list(robots)!r}")
    if workers < 1:
        raise ConfigError(f"workers must be >= 1, got {workers}")
    labels = [e.label for e in entries]
    if not entries or len(set(labels)) != len(labels):
        raise ConfigError(f"entries must be non-empty with distinct labels, got {labels}")
    for entry in entries:
        if entry.model and not Path(resolve(entry.model, root)).is_file():
            raise BulletnavError(f"{entry.model}: model file not found (entry {entry.label!r})")


def _open_run(out: Path, settings: dict[str, Any], resume: bool, run: bool) -> tuple[Path, list[dict[str, Any]]]:
    """``out``'s episode log and the rows already in it, with ``settings.json`` written (a
    resumed run's earlier entries kept in it).

    Raises:
        BulletnavError: ``out`` holds an earlier run and ``resume`` is off, or a run of other
            settings; ``run`` off and no log.
    """
    out.mkdir(parents=True, exist_ok=True)
    log_path, meta_path = out / "episodes.jsonl", out / "settings.json"
    if not run and not log_path.is_file():
        raise BulletnavError(f"{out}: no {log_path.name} to make tables from (run the comparison first)")
    if log_path.exists() and not resume:
        raise BulletnavError(f"{out} holds an earlier run ({log_path.name}): pass --resume to go on with it, "
                             "or choose another --out")
    if resume and meta_path.is_file():
        check_resumable(json.loads(meta_path.read_text()), settings, meta_path)
    rows = reopen_rows(log_path)
    if resume and meta_path.is_file():  # entries of the earlier run that this one leaves out stay in the log
        kept = {e["label"]: e for e in json.loads(meta_path.read_text())["entries"]}
        kept.update({e["label"]: e for e in settings["entries"]})
        write_strict_json(meta_path, {**settings, "entries": list(kept.values())})
    else:
        write_strict_json(meta_path, settings)
    return log_path, rows


def common_episodes(rows: list[dict[str, Any]], labels: Sequence[str], robots: Sequence[int]) -> dict[int, set[int]]:
    """Per fleet size, the episodes every entry in ``labels`` has a row for."""
    out = {}
    for n in robots:
        have = [{r["episode"] for r in rows if r["robots"] == n and r["entry"] == label} for label in labels]
        out[n] = set.intersection(*have) if have else set()
    return out


def entry_record(entry: Entry, root: Path) -> dict[str, Any]:
    """``entry``'s fields plus its model file's sha256 (so a retrained model under the same
    name never joins rows of the one before) and, behind the shield, the shield's settings
    (so rows of a shield with other settings are never joined either)."""
    record: dict[str, Any] = asdict(entry)
    if entry.model:
        record["model_sha256"] = hashlib.sha256(Path(resolve(entry.model, root)).read_bytes()).hexdigest()
    if entry.shield:
        from bulletnav.fleet.controllers import FLEET_SHIELD

        record["shield_config"] = json.loads(json.dumps(asdict(FLEET_SHIELD)))
    return record


def check_resumable(earlier: dict[str, Any], settings: dict[str, Any], where: Path) -> None:
    """An earlier run's settings may be gone on with: the same sizes, episodes, seed and env;
    entries may be added or left out, but one label must mean the same entry (and model file).

    Raises:
        BulletnavError: naming what differs.
    """
    for key in ("robots", "episodes", "seed", "env_kwargs"):
        if earlier.get(key) != json.loads(json.dumps(settings[key])):
            raise BulletnavError(f"{where}: the earlier run has other settings ({key}: {earlier.get(key)!r}, now "
                                 f"{settings[key]!r}): choose another --out")
    before = {e["label"]: e for e in earlier.get("entries", [])}
    for entry in settings["entries"]:
        old = before.get(entry["label"])
        if old is not None and old != entry:
            raise BulletnavError(f"{where}: entry {entry['label']!r} of the earlier run is another controller or "
                                 f"model file ({old}, now {entry}): choose another --out")


def build_comparison(settings: dict[str, Any], rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The comparison record: ``settings``, a summary per (size, entry) with the throughput's
    standard error over episodes, and every row in a fixed order.

    Raises:
        BulletnavError: two entries met different episodes (their reset fingerprints differ).
    """
    labels = [e["label"] for e in settings["entries"]]
    by_episode: dict[tuple[int, int], dict[str, str]] = {}
    for r in rows:
        by_episode.setdefault((r["robots"], r["episode"]), {})[r["entry"]] = r["fingerprint"]
    for (n, k), prints in sorted(by_episode.items()):
        if len(set(prints.values())) > 1:
            raise BulletnavError(f"{n} robots, episode {k} (seed {settings['seed'] + k}): the entries met different "
                                 f"episodes (reset fingerprints {prints}); the comparison would not be fair")
    ordered = sorted(rows, key=lambda r: (r["robots"], labels.index(r["entry"]) if r["entry"] in labels else 99,
                                          r["episode"]))
    cells = []
    for n in settings["robots"]:
        for label in labels:
            mine = [r for r in ordered if r["robots"] == n and r["entry"] == label]
            if not mine:
                continue
            summary = summarize(mine)
            tput = np.array([r["throughput_per_hour"] for r in mine], dtype=float)
            summary["throughput_se"] = float(tput.std(ddof=1) / math.sqrt(len(tput))) if len(tput) > 1 else math.nan
            summary["wall_s"] = float(sum(r.get("wall_s", 0.0) for r in mine))
            cells.append({"robots": n, "entry": label, **summary})
    return {"settings": settings, "metrics": METRICS, "cells": cells, "episodes": ordered}


def comparison_markdown(results: dict[str, Any]) -> str:
    """One markdown table per fleet size: throughput, collisions by kind, deadlocks, separation."""
    s = results["settings"]
    prov = results.get("provenance", {})
    counts = {c["episodes"] for c in results["cells"]}
    if counts == {s["episodes"]}:
        title = f"# Fleet comparison: {s['episodes']} episodes per entry, seeds {s['seed']}-{s['seed'] + s['episodes'] - 1}"
    else:  # tables of a run not finished: the episodes every entry has
        title = (f"# Fleet comparison (not finished): {' / '.join(str(c) for c in sorted(counts))} of "
                 f"{s['episodes']} episodes per entry, the ones every entry has (`episodes` column), "
                 f"seeds from {s['seed']}")
    lines = [title, "", f"Env: `{json.dumps(s['env_kwargs'], sort_keys=True)}`. "
             f"Command: `{prov.get('command', '?')}`; commit {prov.get('git_commit', '?')}"
             f"{' (dirty)' if prov.get('dirty') else ''}; {prov.get('machine', '?')}.", ""]
    counts_rate = rate_counts(float(s["env_kwargs"].get("duration_s", TYPICAL_ERRAND_S)))
    if not counts_rate:
        lines += [f"Errands per hour left out (`-`): episodes of {s['env_kwargs']['duration_s']:g} s end before a robot "
                  f"can be expected to finish one errand (~{TYPICAL_ERRAND_S:g} s), so the rate would say how early the "
                  "run was cut; comparison.json keeps the numbers.", ""]
    for n in s["robots"]:
        cells = [c for c in results["cells"] if c["robots"] == n]
        if not cells:
            continue
        lines += [f"## {n} robots", "",
                  "| controller | errands/h (± s.e.) | per robot | robot-robot | static | mover | person | deadlocks "
                  "| min sep. m | errand s | near misses | shield rate | episodes |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for c in cells:
            rate = (f"{c['throughput_per_hour']:.1f} ± {_num(c['throughput_se'], '.1f')} "
                    f"| {c['throughput_per_robot_per_hour']:.1f}") if counts_rate else "- | -"
            lines.append(f"| {c['entry']} | {rate} | {c['collisions_robot_robot']} "
                         f"| {c['collisions_static']} | {c['collisions_mover']} | {c['collisions_person']} "
                         f"| {c['deadlocks']} | {_num(c['min_separation_m'], '.2f')} | {_num(c['errand_time_s'], '.1f')} "
                         f"| {c['near_misses']} | {_num(c['shield_rate'], '.3f')} | {c['episodes']} |")
        lines.append("")
    return "\n".join(lines)


def _num(value: Any, fmt: str) -> str:
    return "-" if value is None or (isinstance(value, float) and not math.isfinite(value)) else format(value, fmt)


__all__ = ["DEFAULT_CONTROLLERS", "Entry", "build_comparison", "check_resumable", "common_episodes", "comparison_markdown",
           "entry_record", "episode_fingerprint", "parse_entries", "plan_chunks", "run_chunk", "run_comparison"]
