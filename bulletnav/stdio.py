"""The process's C-level standard streams: flushing C code's stdio buffers, and importing a
module whose C code prints while it loads without losing anyone else's output.

Imported by ``bulletnav/__init__.py`` before anything else of the package: it needs the standard
library only.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
import tempfile
from collections.abc import Sequence
from types import ModuleType


def flush_c_stdio() -> None:
    """``fflush(NULL)``: what C code (PyBullet) holds in its stdio buffers written out to the
    descriptors they now name (nothing where no C library can be asked)."""
    import ctypes

    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to ask (not on Linux or macOS)
        pass


def import_without_banner(name: str, banners: Sequence[bytes]) -> ModuleType:
    """Import module ``name`` with file descriptors 1 and 2 on temporary files, then put back
    on each descriptor what was written to it meanwhile, less the lines that start with one of
    ``banners``. Output of other threads (or C code) in that window is delayed, never lost;
    only the banner is dropped. The C stdio buffers are flushed before the descriptors come
    back, so a banner buffered because stdout is a pipe goes too."""
    for stream in (sys.stdout, sys.stderr):  # Python's own buffered output goes out first, where it belongs
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    saved: list[tuple[int, int, int]] = []  # (descriptor, its copy, the file holding its output)
    try:
        for fd in (1, 2):
            try:
                copy = os.dup(fd)
            except OSError:  # no such descriptor: nothing of the user's to protect there
                continue
            try:
                scratch = tempfile.TemporaryFile(prefix="bulletnav-import-")  # unnamed: gone when closed
                hold = os.dup(scratch.fileno())
                scratch.close()
            except OSError:  # nowhere to hold it: leave this descriptor alone (the banner shows)
                os.close(copy)
                continue
            saved.append((fd, copy, hold))
            os.dup2(hold, fd)
        try:
            return importlib.import_module(name)
        finally:
            flush_c_stdio()
    finally:
        for fd, copy, hold in saved:
            os.dup2(copy, fd)
            os.close(copy)
            try:
                os.lseek(hold, 0, os.SEEK_SET)
                with os.fdopen(hold, "rb", closefd=True) as f:
                    kept = f.read()
                for banner in banners:
                    kept = re.sub(re.escape(banner) + rb"[^\n]*\n?", b"", kept)
            except OSError:
                continue
            while kept:
                try:
                    kept = kept[os.write(fd, kept):]
                except OSError:  # the descriptor went away meanwhile: nothing to deliver to
                    break


def exit_now(status: int) -> None:
    """End the process at once with ``status`` (``os._exit``): Python's and C's buffered output
    written out first, nothing else run (no ``finally``, no ``atexit``). For a process that must
    not wait: a second Ctrl-C, a worker that could not start."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 -- a closed stream, a reentrant flush from a signal handler: exit anyway
            pass
    flush_c_stdio()
    os._exit(status)
