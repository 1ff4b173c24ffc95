"""``bulletnav bench env --against COMMIT``: a commit it cannot measure is refused in one line
(exit code 2), and its self-contained measuring script runs on a tree of this very code.

No timing is asserted: only that the figures are there and positive.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from bulletnav.bench.reset_bench import PROBE, bench_against
from bulletnav.cli import main
from bulletnav.errors import BulletnavError

ROOT = Path(__file__).resolve().parents[1]


def _repo(tmp_path: Path, init: str) -> str:
    """A one-commit git repository whose ``bulletnav/__init__.py`` is ``init``; its commit hash."""
    (tmp_path / "bulletnav").mkdir()
    (tmp_path / "bulletnav" / "__init__.py").write_text(init)
    git = ["git", "-C", str(tmp_path), "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "bulletnav"], check=True)
    subprocess.run([*git, "commit", "-qm", "old"], check=True)
    return subprocess.run([*git, "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()


def test_a_bogus_commit_is_refused_in_one_line(capsys):
    code = main(["bench", "env", "--against", "no-such-commit-0123", "--rounds", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "'no-such-commit-0123'" in err and "not a commit" in err


def test_an_option_is_not_taken_for_a_commit(tmp_path):
    with pytest.raises(BulletnavError, match="not a commit"):
        bench_against("--output=/tmp/x", repo=str(ROOT))


def test_a_commit_whose_bulletnav_does_not_import_is_refused(tmp_path):
    commit = _repo(tmp_path, "raise ImportError('gone')\n")
    with pytest.raises(BulletnavError, match=r"commit .*cannot be measured \(cannot import bulletnav: ImportError: gone\)"):
        bench_against(commit, ("bulletnav/Warehouse-v0",), rounds=1, resets=1, steps=1, repo=str(tmp_path))


def test_a_commit_without_the_id_is_refused(tmp_path):
    commit = _repo(tmp_path, "import gymnasium\n")  # imports, registers nothing
    with pytest.raises(BulletnavError, match="not registered there: bulletnav/WarehouseMission-v0"):
        bench_against(commit, ("bulletnav/WarehouseMission-v0",), rounds=1, resets=1, steps=1, repo=str(tmp_path))


def test_the_probe_imports_nothing_of_the_tree_but_the_package():
    """The script is run inside old trees: it may use ``import bulletnav`` and the public
    Gymnasium API, nothing from bulletnav's modules."""
    source = PROBE.read_text()
    imports = [line.strip() for line in source.splitlines() if line.strip().startswith(("import ", "from "))]
    assert sorted(imports) == ["import bulletnav", "import gymnasium as gym", "import json", "import os", "import sys",
                               "import time"]


@pytest.mark.slow
def test_against_head_measures_both_sides(capsys):
    """The measuring script on this checkout and on HEAD's exported tree: every figure is there
    and positive (no timing is compared)."""
    code = main(["bench", "env", "--against", "HEAD", "--env", "bulletnav/WarehouseAisles-v0", "--rounds", "1",
                 "--resets", "2", "--steps", "30", "--json"])
    import json

    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["benchmark"] == "env_against" and out["rounds"] == 1 and len(out["before_commit"]) == 7
    assert len(out["load_average_1min"]) == 2
    row = out["ids"]["bulletnav/WarehouseAisles-v0"]
    for side in ("before", "after"):
        for key in ("reset_ms", "reset_ms_p90", "reset_cpu_ms", "steps_per_s_with_resets", "steps_per_s_between_resets",
                    "cpu_steps_per_s_with_resets", "cpu_steps_per_s_between_resets"):
            assert row[side][key] > 0, (side, key)
        assert 0 <= row[side]["reset_share"] < 1
    for key in ("steps_per_s_with_resets", "steps_per_s_between_resets", "cpu_steps_per_s_with_resets",
                "cpu_steps_per_s_between_resets", "reset", "reset_cpu"):
        assert row["speedup"][key] > 0 and len(row["ratios"][key]) == 1
