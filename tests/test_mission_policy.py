"""The shipped mission policy: it loads with its settings and completes unseen missions."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import gymnasium as gym
import pytest

import bulletnav  # noqa: F401
from bulletnav.cli import SHIPPED_MODELS
from bulletnav.evaluation import run_episodes
from bulletnav.rl.envs import evaluation_env_kwargs
from bulletnav.rl.io import load_model
from bulletnav.rl.policy import SB3Policy

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / SHIPPED_MODELS["bulletnav/WarehouseMission-v0"]
needs_model = pytest.mark.skipif(not MODEL.is_file(), reason=f"{MODEL.name} is not in this checkout")


@pytest.mark.slow
@needs_model
def test_the_shipped_mission_policy_completes_unseen_missions():
    model, meta, vecnorm = load_model(str(MODEL))
    assert meta["env_id"] == "bulletnav/WarehouseMission-v0" and meta["env_kwargs"]["guidance"] == "floorplan"
    env = gym.make(meta["env_id"], **evaluation_env_kwargs(meta["env_kwargs"]))
    results = run_episodes(env, SB3Policy(model, vecnorm), episodes=3, seed=424_242)
    env.close()
    assert all(r.goals_total == 3 for r in results)
    assert sum(r.success for r in results) >= 2
    assert sum(r.goals_reached for r in results) >= 7
    # Each row's derived figures recomputed from its own raw ones: the simulated time is the
    # steps at 24 Hz, SPL is S * l / max(p, l), and success means every goal reached.
    for r in results:
        assert r.sim_time == pytest.approx(r.steps / 24, abs=1e-9)
        assert r.spl == pytest.approx(r.success * r.shortest_path / max(r.path_length, r.shortest_path), abs=1e-9)
        assert r.success == (r.goals_reached == r.goals_total)


TRAINED_ON = {"bulletnav/WarehouseAisles-v0": "bulletnav/WarehouseDynamic-v0"}
"""Shipped models trained on another id than the one they serve: the aisle world's is the dynamic
policy, trained on the same aisle warehouses with movers (the benchmark's ``model: shipped``)."""


def test_every_shipped_model_is_in_the_checkout():
    for env_id, path in SHIPPED_MODELS.items():
        assert (ROOT / path).is_file(), f"demo --env {env_id} would look for {path}"
        # its weights whole: hashlib's SHA-256 of the safe file is the digest its sidecar records
        zipped = ROOT / path
        meta = json.loads(zipped.with_suffix(".json").read_text())
        digest = hashlib.sha256(zipped.with_suffix(".safetensors").read_bytes()).hexdigest()
        assert meta["env_id"] == TRAINED_ON.get(env_id, env_id) and digest == meta["policy"]["weights_sha256"], path
