"""Every registered id runs under Gymnasium's ``make_vec`` (sync and async): a seeded batch
is the same twice and equals the single envs seeded alike, autoreset follows Gymnasium's
next-step rule, and ``info`` comes back as per-env arrays with their masks."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401
from bulletnav.bench.reset_bench import REGISTERED

STEPS = 6
LIMIT = 4  # a short time limit, so both envs end and autoreset within the rollout


def _rollout(env_id: str, mode: str, seed: int = 5):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, max_episode_steps=LIMIT)
    try:
        rng = np.random.default_rng(seed)
        space = envs.single_action_space
        obs, info = envs.reset(seed=seed)
        out = [(obs, info)]
        for _ in range(STEPS):
            out.append(envs.step(rng.uniform(space.low, space.high, size=(2, 2)).astype(np.float32)))
        return out
    finally:
        envs.close()


def _check_distances(out) -> None:
    """Every batched goal distance (and the reset's initial distance) is the Euclidean distance
    from that env's true pose to its goal, computed here from the batch's own info."""
    for entry in out:
        info = entry[-1]
        for i in range(2):
            (x, y, _), (gx, gy) = info["pose"][i], info["goal"][i]
            assert info["distance_to_goal"][i] == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)
    for i in range(2):
        (x, y, _), (gx, gy) = out[0][1]["pose"][i], out[0][1]["goal"][i]
        assert out[0][1]["initial_distance"][i] == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)


@pytest.mark.parametrize("env_id", REGISTERED)
def test_make_vec_sync_is_seeded_autoresets_and_batches_info(env_id):
    first, second = _rollout(env_id, "sync"), _rollout(env_id, "sync")
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a[0], b[0])  # observations, bit for bit
        if len(a) == 5:
            np.testing.assert_array_equal(a[1], b[1])  # rewards
    # env i of the batch is the single env reset with seed + i
    single = gym.make(env_id)
    try:
        assert first[0][0].shape == (2, *single.observation_space.shape)
        for i in range(2):
            obs, info = single.reset(seed=5 + i)
            np.testing.assert_array_equal(first[0][0][i], obs)
            assert first[0][1]["initial_distance"][i] == info["initial_distance"]
    finally:
        single.close()
    # the time limit truncates both at step LIMIT; the next step is the reset (reward 0, not done)
    _, _, terminated, truncated, info = first[LIMIT]
    assert (terminated | truncated).all()
    obs, reward, terminated, truncated, info = first[LIMIT + 1]
    np.testing.assert_array_equal(reward, 0.0)
    assert not terminated.any() and not truncated.any()
    assert info["distance_to_goal"].shape == (2,) and info["_distance_to_goal"].all()
    _check_distances(first)


@pytest.mark.parametrize("env_id", ["bulletnav/Warehouse-v0", "bulletnav/WarehouseDynamic-v0"])
def test_make_vec_async_gives_the_sync_batch(env_id):
    sync, async_ = _rollout(env_id, "sync"), _rollout(env_id, "async")
    for a, b in zip(sync, async_):
        np.testing.assert_array_equal(a[0], b[0])
        if len(a) == 5:
            np.testing.assert_array_equal(a[1], b[1])
    _check_distances(async_)  # the async batch's info is the envs' own, entry for entry
