"""Time limits on the child processes tests start: hang detectors, never a verdict on speed.

A test's child process (a CLI run, a second interpreter, a GUI child) gets ``HANG_S`` seconds,
900 unless ``BULLETNAV_TEST_HANG_S`` says otherwise: on a 2-core machine running two test suites
at once a child that takes 55 s alone took over 150 s, so a limit near the unloaded time made the
verdict depend on the load. Past the limit the test fails with a message that says it suspects a
hang, with the tail of what the process wrote, never with a bare ``TimeoutExpired``.
"""

from __future__ import annotations

import os
import signal
import subprocess
from typing import Any

import pytest

HANG_S = float(os.environ.get("BULLETNAV_TEST_HANG_S", "900"))
"""Seconds a test's child process may run before the test calls it a hang."""


def _text(data: str | bytes | None) -> str:
    if data is None:
        return ""
    return data.decode(errors="replace") if isinstance(data, bytes) else data


def hang_message(what: str, seconds: float, stdout: str | bytes | None = None, stderr: str | bytes | None = None) -> str:
    """The failure text for a child process that ran past its limit: a suspected hang, the
    limit, how to raise it, and the tail of its output."""
    return (f"{what} did not finish in {seconds:.0f} s: a hang? (this limit is a hang detector, not a speed "
            f"check; BULLETNAV_TEST_HANG_S={HANG_S:.0f} sets it on a very slow machine)\n"
            f"--- its stdout, last 3000 characters ---\n{_text(stdout)[-3000:]}\n"
            f"--- its stderr, last 3000 characters ---\n{_text(stderr)[-3000:]}")


def run(cmd: list[str], what: str | None = None, timeout: float | None = None, **kwargs: Any) -> subprocess.CompletedProcess:
    """``subprocess.run(cmd, capture_output=True, text=True, **kwargs)`` with the hang limit
    (``timeout``, default :data:`HANG_S`); past it the test fails as a suspected hang."""
    limit = HANG_S if timeout is None else timeout
    kwargs.setdefault("capture_output", True)
    kwargs.setdefault("text", True)
    try:
        return subprocess.run(cmd, timeout=limit, **kwargs)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(hang_message(what or " ".join(map(str, cmd))[:200], limit, exc.stdout, exc.stderr), pytrace=False)


def communicate(proc: subprocess.Popen, what: str, timeout: float | None = None) -> tuple[Any, Any]:
    """``proc.communicate()`` with the hang limit (``timeout``, default :data:`HANG_S`); past it
    the process is killed and the test fails as a suspected hang, with its output."""
    limit = HANG_S if timeout is None else timeout
    try:
        return proc.communicate(timeout=limit)
    except subprocess.TimeoutExpired:
        try:  # the whole process group where the process leads one (its workers too), else the process
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            proc.kill()
        out, err = proc.communicate()
        pytest.fail(hang_message(what, limit, out, err), pytrace=False)
