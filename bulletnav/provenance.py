"""Where a result came from: the command, the code's git commit and the machine.

Stamped on training runs and benchmark results, so that every figure committed under
``docs/`` or ``models/`` says how to reproduce it.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path


def git_commit() -> str:
    """``HEAD`` of the checkout the package runs from, with ``-dirty`` when tracked files
    differ from it; ``"unknown"`` outside a git checkout."""
    try:
        root = Path(__file__).resolve().parents[1]
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, timeout=10)
        if sha.returncode != 0:
            return "unknown"
        return sha.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def machine() -> str:
    """Architecture, OS, core count and Python version, e.g. ``x86_64 Linux, 2 cores, python 3.11.7``."""
    return f"{platform.machine()} {platform.system()}, {os.cpu_count()} cores, python {platform.python_version()}"


def command_line() -> str:
    """The command as the user typed it: ``bulletnav ...`` for the console script and for
    ``python -m bulletnav.cli`` (whose ``argv[0]`` is the path of ``bulletnav/cli/__main__.py``)."""
    argv0 = sys.argv[0] if sys.argv else ""
    is_cli = argv0.endswith("bulletnav") or argv0.replace("\\", "/").endswith("bulletnav/cli/__main__.py")
    return " ".join(["bulletnav", *sys.argv[1:]]) if is_cli else " ".join(sys.argv)


def provenance() -> dict[str, str]:
    """``command``, ``git_commit`` and ``machine`` of the current process."""
    return {"command": command_line(), "git_commit": git_commit(), "machine": machine()}
