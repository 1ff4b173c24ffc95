"""Ctrl-C (SIGINT) and SIGTERM in a command: one line on stderr naming what was kept and how to
go on, exit status 130, no traceback.

A command says, as it goes, what an interruption from that point on would keep and how to
continue (:func:`on_interrupt`, with :func:`continue_command` or :func:`rerun_command` for the
command to type); :func:`bulletnav.cli.main` turns the ``KeyboardInterrupt`` into that one
line. SIGTERM is made a ``KeyboardInterrupt`` in this process only (:func:`sigterm_as_interrupt`):
worker processes ignore SIGINT (the library's pools and vector envs start them so), and the
command stops them, so a Ctrl-C at the terminal, which reaches the whole process group, prints
nothing from them. The library itself never prints: it cleans up (workers stopped, files whole)
and lets the interrupt through.
"""

from __future__ import annotations

import contextlib
import shlex
import signal
import threading
from collections.abc import Callable, Iterator, Sequence

EXIT_INTERRUPTED = 130
"""The exit status of an interrupted command (128 + SIGINT, what shells report for Ctrl-C)."""

_argv: list[str] = []
_note: Callable[[], str] | None = None


def start(argv: Sequence[str]) -> None:
    """A new command: its arguments (as typed after ``bulletnav``), and no note yet."""
    global _argv, _note
    _argv, _note = list(argv), None


def on_interrupt(note: Callable[[], str] | None) -> None:
    """From now on an interruption prints ``note()`` (called then, so it can count what is on
    disk at that moment), e.g. ``"interrupted after 60 of 240 episodes; rows kept in ...;
    continue with: ..."``. None: the default, :func:`nothing_kept`."""
    global _note
    _note = note


def continue_command(drop: Sequence[str] = ("--overwrite",), add: Sequence[str] = ("--resume",)) -> str:
    """This command's arguments again, shell-quoted (``shlex.join``), without ``drop`` and with
    ``add`` (default: ``--resume`` in place of ``--overwrite``)."""
    words = [w for w in _argv if w not in drop]
    words += [a for a in add if a not in words]
    return shlex.join(["bulletnav", *words])


def rerun_command(add: Sequence[str] = ()) -> str:
    """This command again as typed (shell-quoted), with the options ``add`` that it lacks."""
    return shlex.join(["bulletnav", *_argv, *[a for a in add if a not in _argv]])


def nothing_kept() -> str:
    """The note of a command that keeps nothing of an unfinished run."""
    return f"interrupted; nothing was kept and nothing can be resumed; run again with: {rerun_command()}"


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within: SIGTERM raises ``KeyboardInterrupt`` as Ctrl-C does (in the main thread of this
    process only; elsewhere nothing changes). A SIGTERM the process was started ignoring stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    old = signal.getsignal(signal.SIGTERM)
    if old is None:  # a handler set outside Python: put the default back after
        old = signal.SIG_DFL
    elif old == signal.SIG_IGN:
        yield
        return
    signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Within: a Ctrl-C or SIGTERM waits (the line being printed is not cut by a second one)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


def interrupted_line(command: str) -> str:
    """The one line of an interrupted ``command``: ``bulletnav COMMAND: <the note>``."""
    try:
        text = (_note or nothing_kept)()
    except Exception as exc:  # noqa: BLE001 -- the line must come out whatever the note trips over
        text = f"interrupted ({type(exc).__name__} while counting what was kept: {exc})"
    return f"bulletnav {command}: {' '.join(text.split())}"
