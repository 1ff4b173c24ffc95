"""Machinery of a run of many episodes that the benchmark runner and the fleet comparison share:
the row log (``episodes.jsonl``: :class:`RowLog`, :func:`read_rows`, :func:`reopen_rows`), the
process pool (:func:`run_in_pool`), the run's provenance and strict JSON files
(:func:`write_strict_json`)."""

from __future__ import annotations

import json
import logging
import math
import multiprocessing
import os
import platform
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from itertools import islice
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

PROJECT_ROOT = Path(__file__).resolve().parents[1]
"""Where ``models/`` lives (``model: shipped`` and relative model paths)."""


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Rows of an ``episodes.jsonl`` (a torn last line, from an interrupted run, is dropped)."""
    rows = []
    if path.is_file():
        for line in path.read_text().splitlines():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                log.warning("%s: dropping a torn line (an interrupted write)", path)
    return rows


def reopen_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of an ``episodes.jsonl`` to go on appending to: :func:`read_rows`, and a torn
    last line cut from the file (or the first new row would join it and be lost)."""
    rows = read_rows(path)
    if path.is_file():
        data = path.read_bytes()
        if data and not data.endswith(b"\n"):
            with path.open("r+b") as f:
                f.truncate(data.rfind(b"\n") + 1)
    return rows


class RowLog:
    """The rows of a run as they finish: each batch appended to ``path`` (one JSON line per
    row) in one ``write`` call, added to ``rows`` and reported through ``progress(done, total)``.
    Use as a context manager; the object it gives is the ``keep(new_rows)`` function.

    One ``write`` of the whole batch to a file opened for appending: a Ctrl-C or SIGTERM (their
    handlers run between Python steps, after a system call returns) never leaves half a row."""

    def __init__(self, path: Path, rows: list[dict[str, Any]], total: int,
                 progress: Callable[[int, int], None] | None = None) -> None:
        self.path, self.rows, self.total, self.progress = path, rows, total, progress

    def __enter__(self) -> Callable[[list[dict[str, Any]]], None]:
        self.fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        if self.progress is not None:
            self.progress(len(self.rows), self.total)
        return self.keep

    def keep(self, new: list[dict[str, Any]]) -> None:
        data = memoryview("".join(json.dumps(row, allow_nan=True) + "\n" for row in new).encode())
        while data:  # a regular file takes it all at once; a short write (a full disk) goes on
            data = data[os.write(self.fd, data):]
        self.rows.extend(new)
        if self.progress is not None:
            self.progress(len(self.rows), self.total)

    def __exit__(self, *exc: object) -> None:
        os.close(self.fd)


def ignore_interrupts() -> None:
    """A worker process's start: ignore SIGINT. A Ctrl-C at the terminal reaches the whole
    process group; the parent alone handles it and stops its workers (no traceback from each)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_in_pool(jobs: list[tuple[Callable, tuple]], workers: int, keep: Callable[[Any], None]) -> None:
    """Run each ``(function, args)`` job in a pool of ``workers`` processes (forkserver:
    nothing of this process's PyBullet state is inherited) and ``keep`` each result as it
    finishes. At most ``workers`` jobs are handed to the pool at a time, so a job's exception
    is raised here at once: the jobs not yet handed over never start (the running ones finish
    first). ``ProcessPoolExecutor`` would otherwise queue jobs ahead of its workers, and those
    would run after the failure. The workers ignore SIGINT (:func:`ignore_interrupts`); a
    ``KeyboardInterrupt`` here (Ctrl-C, or SIGTERM made one by the CLI) terminates them at once."""
    ctx = multiprocessing.get_context("forkserver")
    queue = iter(jobs)
    before = set(multiprocessing.active_children())  # the pool's workers are the children started after this
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=ignore_interrupts)
    try:
        pending = {pool.submit(fn, *args) for fn, args in islice(queue, workers)}
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                keep(future.result())
                pending.update(pool.submit(fn, *args) for fn, args in islice(queue, 1))
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: stop the workers now, not after their chunks
        stop_workers(set(multiprocessing.active_children()) - before)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def stop_workers(processes: Iterable[multiprocessing.Process]) -> None:
    """Terminate a pool's worker processes (their unfinished jobs are lost; nothing of theirs
    was written) and wait for them. The caller names them as the children this process started
    since the pool was made (``multiprocessing.active_children``): executors have no public way
    to stop their workers before Python 3.14."""
    processes = list(processes)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join()


def run_provenance(wall: float, workers: int, address: str | None) -> dict[str, Any]:
    from importlib.metadata import PackageNotFoundError, version

    from bulletnav.provenance import command_line, git_commit, machine

    commit = git_commit()
    versions = {}
    for package in ("bulletnav", "pybullet", "gymnasium", "stable-baselines3", "torch", "numpy"):
        try:
            versions[package] = version(package)
        except PackageNotFoundError:
            versions[package] = None
    return {"git_commit": commit.removesuffix("-dirty"), "dirty": commit.endswith("-dirty"), "versions": versions,
            "machine": machine(), "processor": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
            "wall_time_s": round(wall, 1), "workers": workers, "ray_address": address, "command": command_line()}


def write_strict_json(path: Path, data: Any) -> None:
    """Strict JSON (NaN as null), written atomically (:func:`bulletnav.files.write_bytes`)."""
    from bulletnav.files import write_bytes

    write_bytes(path, (json.dumps(strict_json(data), indent=1) + "\n").encode())


def strict_json(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json(v) for v in value]
    return value
