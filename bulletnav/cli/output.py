"""What the commands print and write: ``--json``'s one document, report figures, output files.

``--json``'s contract: stdout carries exactly one JSON document and nothing else. :func:`json_mode`
holds the document that :func:`print_json` hands it and sends everything else written to stdout
to stderr -- Python's prints and C code writing on file descriptor 1 alike (PyBullet's GUI thread
prints its OpenGL and thread messages there) -- and prints the document once stdout is stdout again.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from collections.abc import Iterator

from bulletnav.errors import BulletnavError
from bulletnav.stdio import flush_c_stdio

_held: list[str] | None = None
"""The document of the ``--json`` run in progress (None: no run, :func:`print_json` prints at once)."""


def to_json(obj) -> str:
    """Strict JSON: NaN (nothing to average) becomes null."""

    def clean(o):
        if isinstance(o, float) and o != o:
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o

    return json.dumps(clean(obj), allow_nan=False)


def print_json(obj) -> None:
    """Print ``obj`` as the command's JSON document (:func:`to_json`); within :func:`json_mode`, on
    stdout once the command is done.

    Raises:
        RuntimeError: the command printed a document already (a bug: one document per run).
    """
    text = to_json(obj)
    if _held is None:
        print(text)
    elif _held:
        raise RuntimeError("a --json command printed a second JSON document")
    else:
        _held.append(text)


@contextlib.contextmanager
def json_mode() -> Iterator[None]:
    """Run a ``--json`` command within: stdout (Python's ``sys.stdout`` and file descriptor 1)
    goes to stderr, and on a normal exit the document :func:`print_json` was given is printed
    on the real stdout (nothing when the command failed)."""
    global _held
    stdout = sys.stdout
    stdout.flush()
    flush_c_stdio()
    saved = os.dup(1)
    os.dup2(2, 1)
    _held = held = []
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        _held = None
        stdout.flush()
        sys.stderr.flush()
        flush_c_stdio()
        os.dup2(saved, 1)
        os.close(saved)
    for text in held:
        print(text)


def fmt(x: float, spec: str = ".2f") -> str:
    """``x`` formatted, or n/a for NaN (nothing to average)."""
    return "n/a" if x != x else format(x, spec)


def outcome(r) -> str:
    """An episode result's outcome in capitals."""
    return "SUCCESS" if r.success else ("COLLISION" if r.collision else "TIMEOUT")


def safety_line(s: dict) -> str:
    """One report line of the safety metrics of :func:`bulletnav.evaluation.summarize`."""
    separation = s["min_separation_m"]
    separation_text = "n/a (no movers)" if separation != separation else f"{separation:.2f} m"
    return (f"collisions static {s['collision_static_rate'] * 100:.1f} %  dynamic {s['collision_dynamic_rate'] * 100:.1f} %   "
            f"timeouts {s['timeout_rate'] * 100:.1f} %   min separation {separation_text}   "
            f"near misses {s['near_miss_rate'] * 100:.1f} % of steps   episode time {s['episode_time_s']:.1f} s")


def shield_line(s: dict) -> str:
    """One report line of the shield's figures of :func:`bulletnav.evaluation.summarize`."""
    return (f"replaced the command on {s['shield_rate'] * 100:.2f} % of steps, "
            f"mean change {fmt(s['shield_change_mean'], '.3f')} m/s (wheel rim speeds, when it acted)")


class EpisodeBar:
    """A run's progress bar of episodes on stderr (none when not ``show``), made at the first
    :meth:`update` (a resumed run's bar starts at the episodes already done). Use as a context
    manager around the run: the bar is closed at the end, and left off the screen when a
    ``KeyboardInterrupt`` ends the run (the interrupted line says where it stopped)."""

    def __init__(self, desc: str, show: bool = True) -> None:
        self.desc, self.show = desc, show
        self.bar = None

    def update(self, done: int, total: int) -> None:
        """``done`` of ``total`` episodes finished (a runner's ``progress`` callback)."""
        if not self.show:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=done, unit="episode", desc=self.desc, file=sys.stderr)
        self.bar.update(done - self.bar.n)

    def __enter__(self) -> EpisodeBar:
        return self

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        if self.bar is not None:
            if kind is not None and issubclass(kind, KeyboardInterrupt):
                self.bar.leave = False
            self.bar.close()


def holds_run(path) -> bool:
    """Whether ``path`` is there and not an empty folder (it then holds another run's outputs)."""
    from pathlib import Path

    path = Path(path)
    return path.exists() and (not path.is_dir() or any(path.iterdir()))


def refuse_existing_files(args: argparse.Namespace, *options: str) -> None:
    """Output files (``--video``, ``--plot``) that exist already are refused unless ``--overwrite``."""
    for option in options:
        value = getattr(args, option, None)
        if value:
            refuse_existing_file(option, value, getattr(args, "overwrite", False))


def refuse_existing_file(option: str, path, overwrite: bool) -> None:
    """``path``, an output file of ``--option``, is refused if it exists, unless ``overwrite``."""
    from pathlib import Path

    if Path(path).exists() and not overwrite:
        raise BulletnavError(f"--{option} {path}: the file already exists (another run's?); pass --overwrite "
                             "to replace it, or choose another name")
