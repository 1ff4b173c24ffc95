"""The hang detector of the tests' child processes (tests/hang.py): past its limit a child is
killed and the test fails saying it suspects a hang, with the child's output, never with a bare
``TimeoutExpired``; within it, the result is the child's own."""

from __future__ import annotations

import subprocess
import sys

import pytest

import hang

SLEEPER = "import sys, time; print('started', flush=True); print('on stderr', file=sys.stderr, flush=True); time.sleep(60)"


def test_a_child_past_its_limit_fails_the_test_as_a_suspected_hang_with_its_output():
    with pytest.raises(pytest.fail.Exception) as failed:
        hang.run([sys.executable, "-c", SLEEPER], "the sleeper", timeout=2)
    text = str(failed.value)
    assert text.startswith("the sleeper did not finish in 2 s: a hang?")
    assert "started" in text and "on stderr" in text and "BULLETNAV_TEST_HANG_S" in text

    proc = subprocess.Popen([sys.executable, "-c", SLEEPER], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    with pytest.raises(pytest.fail.Exception) as failed:
        hang.communicate(proc, "the sleeping process", timeout=2)
    assert str(failed.value).startswith("the sleeping process did not finish in 2 s: a hang?") and "started" in str(failed.value)
    assert proc.returncode is not None and proc.returncode < 0  # killed, not left running


def test_a_child_within_its_limit_gives_its_own_result():
    done = hang.run([sys.executable, "-c", "import sys; print('out'); sys.exit(3)"], "a quick child", timeout=60)
    assert (done.returncode, done.stdout) == (3, "out\n")
