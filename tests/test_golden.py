"""Warehouse-v0 stays bit-identical: seeded traces and the shipped policy's episodes against
references recorded before the restructure of issue 14 (``tests/golden_record.py``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from golden_record import GOLDEN, ROOT, SETTINGS, rollout_hash

REFERENCE = json.loads(GOLDEN.read_text())


@pytest.mark.parametrize("setting", sorted(SETTINGS))
def test_seeded_traces_are_bit_identical_to_the_references(setting):
    for seed, expected in REFERENCE["traces"][setting].items():
        assert rollout_hash(SETTINGS[setting], int(seed), REFERENCE["steps"]) == expected, (setting, seed)


def _per_episode(args: list[str]) -> list[dict]:
    out = subprocess.run([sys.executable, "-m", "bulletnav.cli", *args, "--json"], check=True, capture_output=True,
                         text=True, cwd=ROOT).stdout
    return json.loads(out)["per_episode"]


@pytest.mark.slow
def test_shipped_policy_reproduces_its_episodes_bit_for_bit():
    expected = REFERENCE["ppo_evaluate_seed_1000"]
    got = _per_episode(["evaluate", "--model", str(ROOT / "models/ppo_warehouse.zip"), "--episodes", str(len(expected))])
    assert [{k: e[k] for k in expected[0]} for e in got] == expected


@pytest.mark.slow
def test_pid_astar_reproduces_its_episodes_bit_for_bit():
    expected = REFERENCE["astar_navigate_seed_0"]
    got = _per_episode(["navigate", "--planner", "astar", "--episodes", str(len(expected))])
    assert [{k: e[k] for k in expected[0]} for e in got] == expected


def test_importing_bulletnav_pins_mkl_to_its_avx_kernels_unless_the_user_chose():
    """MKL's kernels differ by CPU in the last bits of their sums: the shipped policy's episodes
    above reproduce on an AVX-512 machine only with its AVX kernels, the ones they were recorded with."""
    code = "import os, bulletnav; print(os.environ['MKL_ENABLE_INSTRUCTIONS'])"
    env = {k: v for k, v in os.environ.items() if k != "MKL_ENABLE_INSTRUCTIONS"}

    def run(e: dict[str, str]) -> str:
        return subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                              env=e, cwd=ROOT).stdout.strip()

    assert run(env) == "AVX"
    assert run({**env, "MKL_ENABLE_INSTRUCTIONS": "SSE4_2"}) == "SSE4_2"
