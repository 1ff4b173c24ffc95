"""The shipped BARN policy (models/ppo_barn.*): it loads from its safe files, is the network the
model card describes (the Jackal's 72-ray, 270-degree scan and outline), and acts on
``bulletnav/BARN-v0`` deterministically. Its scores are the model card's (models/ppo_barn.md),
measured by ``bulletnav evaluate``, not asserted here."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.barn.data import TRAIN_WORLDS
from bulletnav.rl.envs import evaluation_env_kwargs
from bulletnav.rl.features import footprint_distances
from bulletnav.rl.io import load_model
from bulletnav.rl.policy import SB3Policy

MODEL = Path(__file__).resolve().parent.parent / "models" / "ppo_barn.zip"


def test_barn_policy_loads_and_acts_deterministically_on_barn():
    model, meta, vecnorm = load_model(MODEL)
    assert meta["env_id"] == "bulletnav/BARN-v0" and meta["env_kwargs"]["world_idx"] == "train"
    extractor = model.policy.features_extractor
    assert (extractor.robot, extractor.num_rays, extractor.lidar_range) == ("jackal", 72, 30.0)
    # the Jackal's front face 0.254 m ahead of the centre, its lidar 0.055 m: 0.199 m along the
    # rays next to straight ahead (+-1.9 deg) within a few tenths of a millimetre
    foot = extractor.footprint.numpy()
    assert foot[35] == pytest.approx(0.254 - 0.055, abs=5e-4) and foot[36] == pytest.approx(0.254 - 0.055, abs=5e-4)
    np.testing.assert_allclose(foot, footprint_distances(72, 270.0, robot="jackal"), rtol=1e-6)
    env = gym.make("bulletnav/BARN-v0", **evaluation_env_kwargs(meta["env_kwargs"]))
    try:
        obs, info = env.reset(seed=0)
        assert info["world_idx"] in TRAIN_WORLDS
        policy = SB3Policy(model, vecnorm)
        for _ in range(3):
            first, second = policy.act(obs, info), policy.act(obs.copy(), info)
            np.testing.assert_array_equal(first, second)
            assert env.action_space.contains(np.asarray(first, dtype=np.float32))
            obs, _, terminated, truncated, info = env.step(first)
            assert not (terminated or truncated)
    finally:
        env.close()
