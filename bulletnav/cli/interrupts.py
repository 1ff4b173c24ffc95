"""Ctrl-C (SIGINT) and SIGTERM in a command: one line on stderr naming what was kept and how to
go on, exit status 128 + the signal's number (130 for Ctrl-C, 143 for SIGTERM), no traceback.

A command says, as it goes, what an interruption from that point on would keep and how to
continue (:func:`on_interrupt`, with :func:`continue_command` or :func:`rerun_command` for the
command to type); :func:`bulletnav.cli.main` turns the ``KeyboardInterrupt`` into that one
line. SIGTERM is made a ``KeyboardInterrupt`` in this process only (:func:`signals_as_interrupt`):
worker processes ignore SIGINT (the library's pools and vector envs start them so), and the
command stops them, so a Ctrl-C at the terminal, which reaches the whole process group, prints
nothing from them. The library itself never prints: it cleans up (workers stopped, files whole)
and lets the interrupt through.

Python runs a signal's handler only between steps of its own code, so a process inside a long C
call (an SQLite query over a hostile file) would not notice one. A watcher thread reads the
signal numbers that the C-level handler writes to a pipe (``signal.set_wakeup_fd``) the moment
they arrive; where the C call lets other threads run (SQLite's does), it ends the process at
once, with the same one line, when the main thread has not taken the signal within
:data:`GRACE_S`, and on any second signal.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence

from bulletnav.stdio import exit_now

EXIT_INTERRUPTED = 130
"""The exit status of a command interrupted by Ctrl-C (128 + SIGINT, what shells report)."""

GRACE_S = 1.0
"""How long (s) the watcher waits for the main thread to take a signal before it ends the
process itself (the main thread is then inside a C call that does not come back)."""

_argv: list[str] = []
_command = ""
_note: Callable[[], str] | None = None
received: list[int] = []
"""The signals this command has taken (SIGINT, SIGTERM), in order; the first sets the exit status."""
_taken = threading.Event()
_deferring = False
_library_owned = False
"""True while a library handles Ctrl-C itself (Ray Tune's first Ctrl-C saves and ends the
sweep): the watcher then ends nothing (:func:`library_handles_signals`)."""
_ending = threading.Lock()
_handlers: list[Callable] = []
"""The handlers :func:`signals_as_interrupt` has in force (a fork's child resets exactly these)."""
_main_pid = os.getpid()


def library_handles_signals() -> None:
    """From now on in this command, a library takes Ctrl-C and SIGTERM itself (it installs and
    restores its own handlers, ours among them): the watcher ends nothing, and a second signal
    is the library's too."""
    global _library_owned
    _library_owned = True


def _in_forked_child() -> None:
    """A child forked from a command (a fork-context worker) must not write its signals into
    the parent's wakeup pipe, nor end itself through the parent's handler: both are reset."""
    if os.getpid() == _main_pid:
        return
    try:
        signal.set_wakeup_fd(-1)
        for sig, default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL)):
            if signal.getsignal(sig) in _handlers:
                signal.signal(sig, default)
    except (ValueError, OSError):  # not the main thread of the child: nothing to reset there
        pass


os.register_at_fork(after_in_child=_in_forked_child)


def exit_status() -> int:
    """128 + the number of the first signal taken (130 for Ctrl-C, 143 for SIGTERM)."""
    return 128 + (received[0] if received else signal.SIGINT)


def start(argv: Sequence[str], command: str = "") -> None:
    """A new command: its arguments (as typed after ``bulletnav``), its name, no note and no
    signal yet."""
    global _argv, _note, _command, _library_owned
    _argv, _note, _command, _library_owned = list(argv), None, command, False
    received.clear()
    _taken.clear()


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
def signals_as_interrupt() -> Iterator[None]:
    """Within: SIGINT and SIGTERM raise ``KeyboardInterrupt`` (in the main thread of this process
    only; elsewhere nothing changes), and a watcher ends the process at once on a second signal
    or on one the main thread does not take within :data:`GRACE_S` (module docstring). A signal
    the process was started ignoring stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        received.append(signum)
        if len(received) > 1 and not _library_owned:  # asked twice: the cleanup of the first is not waited for
            _end_now(signum)
        _taken.set()
        raise KeyboardInterrupt(f"signal {signum}")

    old = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(sig)
        if handler == signal.SIG_IGN:
            continue
        old[sig] = signal.SIG_DFL if handler is None else handler  # a handler set outside Python: the default after
        signal.signal(sig, interrupt)
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    try:
        old_fd = signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    except (ValueError, OSError):  # not possible here: no watcher, the handlers alone
        os.close(read_end)
        os.close(write_end)
        read_end = write_end = -1
        old_fd = -1
    watcher = None
    _handlers.append(interrupt)
    try:
        if read_end >= 0:
            watcher = threading.Thread(target=_watch, args=(read_end, interrupt), name="bulletnav-signals", daemon=True)
            watcher.start()
        yield
    finally:
        _handlers.remove(interrupt)
        for sig, handler in old.items():
            signal.signal(sig, handler)
        if write_end >= 0:
            signal.set_wakeup_fd(old_fd)
            os.close(write_end)  # the watcher's read ends (EOF) and it returns
            if watcher is not None:
                watcher.join(timeout=1.0)
            os.close(read_end)


def _watch(read_end: int, handler: Callable) -> None:
    """The watcher thread: every signal number the C handler writes to the pipe, as it comes.
    Only signals whose Python handler is still ``handler`` count, and none once a library has
    said it handles them (:func:`library_handles_signals`): within :func:`deferred` the signal
    is deferred's, and Ray Tune puts our handler back after taking its own first Ctrl-C."""
    seen = 0
    while True:
        try:
            data = os.read(read_end, 64)
        except OSError:
            return
        if not data:
            return
        for signum in data:
            try:
                ours = signal.getsignal(signum) is handler and not _library_owned
            except ValueError:
                ours = False
            if not ours:
                continue
            seen += 1
            if seen >= 2 or not _taken_within(GRACE_S):
                _end_now(signum)


def _taken_within(seconds: float) -> bool:
    """Whether the main thread takes the signal within ``seconds``. After the wait the watcher
    yields once more: a main thread that held the GIL through a long call (so that this thread
    could not even time out until it returned) runs the handler as soon as it may."""
    if _taken.wait(seconds):
        return True
    time.sleep(0.05)  # lets the main thread run its pending handler
    return _taken.is_set()


def _end_now(signum: int) -> None:
    """End the process at once: the interrupted line (unless one is being printed), exit 128 +
    the first signal's number. Nothing is cleaned up: the caller asked twice, or the main
    thread is stuck in a C call."""
    if not _ending.acquire(blocking=False):  # the other thread is ending it already: one line
        return
    if signum not in received:
        received.append(signum)
    if not _deferring:
        try:
            line = interrupted_line(_command or "command", hurried=True)
            os.write(2, (line + "\n").encode(errors="replace"))
        except Exception:  # noqa: BLE001 -- nothing may stop the exit
            pass
    exit_now(exit_status())


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Within: a Ctrl-C or SIGTERM waits (the line being printed is not cut by a second one);
    one that came meanwhile ends the process at once after it (exit 128 + the first signal's
    number)."""
    global _deferring
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []

    def hold(signum, frame):
        held.append(signum)

    old = {sig: signal.signal(sig, hold) for sig in (signal.SIGINT, signal.SIGTERM)
           if signal.getsignal(sig) != signal.SIG_IGN}  # one the process ignores stays ignored
    _deferring = True
    try:
        yield
    finally:
        _deferring = False
        for sig, handler in old.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        if held:
            received.extend(held)
            exit_now(exit_status())


def interrupted_line(command: str, hurried: bool = False) -> str:
    """The one line of an interrupted ``command``: ``bulletnav COMMAND: <the note>``; ``hurried``:
    the process ends at once, nothing is cleaned up, so the note is not asked."""
    if hurried:
        return (f"bulletnav {command}: interrupted at once (a second signal, or one the command could not take "
                f"inside a long call); files being written may be incomplete; run again with: {rerun_command()}")
    try:
        text = (_note or nothing_kept)()
    except Exception as exc:  # noqa: BLE001 -- the line must come out whatever the note trips over
        text = f"interrupted ({type(exc).__name__} while counting what was kept: {exc})"
    return f"bulletnav {command}: {' '.join(text.split())}"
