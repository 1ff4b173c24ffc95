"""Every registered id keeps its episodes bit for bit across changes to the reset path:
seeded rollouts and reset-heavy traces against ``tests/golden/env_ids.json``
(recorded by ``tests/golden_ids.py`` before the fast-reset work)."""

from __future__ import annotations

import json

import pytest

from golden_ids import GOLDEN, resets_hash, rollout_hash

REFERENCE = json.loads(GOLDEN.read_text())


@pytest.mark.parametrize("env_id", sorted(REFERENCE["traces"]))
def test_rollouts_are_bit_identical(env_id):
    for seed, expected in REFERENCE["traces"][env_id]["rollout"].items():
        assert rollout_hash(env_id, int(seed), REFERENCE["steps"]) == expected, (env_id, seed)


@pytest.mark.parametrize("env_id", sorted(REFERENCE["traces"]))
def test_reset_traces_are_bit_identical(env_id):
    for seed, expected in REFERENCE["traces"][env_id]["resets"].items():
        assert resets_hash(env_id, int(seed), REFERENCE["resets"], REFERENCE["peek"]) == expected, (env_id, seed)
