"""Each registered id is evaluated by its own episode rules: the env that evaluation builds from
a model's training settings ends episodes exactly as ``gym.make(id)`` does.

Training may set ``collision_terminates`` (the hyperparameter files do, for learning);
:func:`~bulletnav.rl.envs.evaluation_env_kwargs` leaves it out, and ``gym.make`` then takes the
id's registered value. References: the ids' rules as documented (docs/worlds.md, docs/missions.md,
the env's docstring) written out by hand below, and ``gym.make(id)`` driven alongside.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.errors import ConfigError
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.rl.envs import evaluation_env_kwargs, make_env
from bulletnav.rl.hyperparams import load_hyperparams

MODELS = Path(__file__).resolve().parents[1] / "models"

RULES = {
    "bulletnav/Warehouse-v0": (False, 1000),
    "bulletnav/WarehouseAisles-v0": (True, 2400),
    "bulletnav/WarehouseDynamic-v0": (True, 2400),
    "bulletnav/WarehouseMission-v0": (True, None),
    "bulletnav/BARN-v0": (True, None),  # BARN's own 100 s clock ends an episode (bulletnav.barn.task)
}
"""Per id, by hand from its documentation: does a collision terminate (else it truncates), and
Gymnasium's time limit (the mission task truncates by itself, 1,200 steps per goal)."""


NO_HYPERPARAMS = frozenset({"bulletnav/BARN-v0"})
"""Ids the shipped hyperparameter files do not cover (yet): their models can only carry their sidecars' settings."""

END_FIELDS = ("collision_terminates", "goal_radius", "goals", "goal_order", "steps_per_goal")
"""The :class:`~bulletnav.config.TaskConfig` fields that decide how an episode ends (the others
shape the observation, which a model keeps from its training)."""


def _training_settings(env_id: str) -> list[dict]:
    """Training env settings a model of ``env_id`` can carry: none, either collision rule
    forced, each shipped hyperparameter file's, and the shipped models' sidecars for the id."""
    settings = [{}, {"collision_terminates": True}, {"collision_terminates": False}]
    for algo in ("ppo", "sac", "td3", "a2c"):
        try:
            settings.append(dict(load_hyperparams(algo, env_id).get("env_kwargs", {})))
        except ConfigError:
            assert env_id in NO_HYPERPARAMS, f"{algo}.yml has no hyperparameters for {env_id}"
    for sidecar in sorted(MODELS.glob("ppo_*.json")):
        meta = json.loads(sidecar.read_text())
        if isinstance(meta, dict) and meta.get("env_id") == env_id:
            settings.append(meta.get("env_kwargs", {}))
    return settings


def _rules(env: gym.Env) -> tuple[bool, int | None]:
    return env.unwrapped.config.task.collision_terminates, env.spec.max_episode_steps


def test_the_hand_table_covers_every_registered_id():
    registered = {env_id for env_id in gym.registry if env_id.startswith("bulletnav/")}
    assert registered == set(RULES)
    for env_id, (terminates, limit) in RULES.items():
        env = gym.make(env_id)
        try:
            assert _rules(env) == (terminates, limit)
        finally:
            env.close()


@pytest.mark.parametrize("env_id", sorted(RULES))
def test_the_evaluation_env_has_the_ids_own_rules_and_reward(env_id):
    reference = gym.make(env_id)
    try:
        own = reference.unwrapped.config
        for training in _training_settings(env_id):
            env = make_env(env_id, evaluation_env_kwargs(training))
            try:
                assert _rules(env) == RULES[env_id], training
                task = env.unwrapped.config.task
                assert {f: getattr(task, f) for f in END_FIELDS} == {f: getattr(own.task, f) for f in END_FIELDS}, training
                assert task.reward == own.task.reward, training  # the id's own reward
                assert env.unwrapped.config.task_name == own.task_name, training
            finally:
                env.close()
    finally:
        reference.close()


@pytest.mark.parametrize("model", ["ppo_warehouse", "ppo_dynamic", "ppo_mission"])
def test_evaluate_model_builds_the_env_with_the_ids_rules(model, monkeypatch):
    """The library's evaluation (``bulletnav evaluate``'s, a sweep's held-out score) on each
    shipped model's own id: the env it builds carries the id's rules."""
    import bulletnav.rl.evaluate as evaluate

    meta = json.loads((MODELS / f"{model}.json").read_text())
    built = []

    def capture(*args, **kwargs):
        env = make_env(*args, **kwargs)
        built.append(_rules(env))
        return env

    monkeypatch.setattr(evaluate, "make_env", capture)
    monkeypatch.setattr(evaluate, "run_episodes", lambda *args, **kwargs: [])
    evaluate.evaluate_model(MODELS / f"{model}.zip", meta["env_id"], episodes=1)
    assert built == [RULES[meta["env_id"]]]


def _drive_straight(env: gym.Env, seed: int, action: np.ndarray) -> tuple[list[float], bool, bool, dict]:
    env.reset(seed=seed)
    rewards = []
    while True:
        _, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        if terminated or truncated:
            return rewards, terminated, truncated, info


@pytest.mark.parametrize("env_id", sorted(RULES))
def test_driving_into_a_wall_ends_by_the_ids_rule(env_id):
    """Full speed ahead from a seeded start until something is hit, in the evaluation env of a
    model trained under the opposite collision rule and in ``gym.make(id)``: the same
    episode step for step, ended by the collision as the id's rule says."""
    terminates, _ = RULES[env_id]
    evaluation = make_env(env_id, evaluation_env_kwargs({"collision_terminates": not terminates}))
    reference = gym.make(env_id)
    try:
        action = np.array([reference.action_space.high[0], 0.0], dtype=np.float32)
        for seed in range(10):  # the first seed whose straight drive hits something
            rewards, terminated, truncated, info = _drive_straight(reference, seed, action)
            if info["end_reason"] == "collision":
                break
        assert info["end_reason"] == "collision" and info["collision"]
        assert (terminated, truncated) == (terminates, not terminates)
        assert _same_episode(_drive_straight(evaluation, seed, action), (rewards, terminated, truncated, info))
    finally:
        evaluation.close()
        reference.close()


def _same_episode(a: tuple, b: tuple) -> bool:
    """Rewards, end flags and the last ``info`` equal (arrays compared element-wise)."""
    if a[:3] != b[:3] or a[3].keys() != b[3].keys():
        return False
    return all(np.array_equal(a[3][k], b[3][k]) if isinstance(a[3][k], np.ndarray) else a[3][k] == b[3][k]
               for k in a[3])


class _Ahead:
    """Full speed ahead, no turn (a policy for :func:`run_episodes`)."""

    def __init__(self, speed: float) -> None:
        self.action = np.array([speed, 0.0], dtype=np.float32)

    def reset(self, info: dict) -> None:
        pass

    def act(self, obs, info: dict) -> np.ndarray:
        return self.action


def test_the_published_metrics_do_not_depend_on_the_collision_flag():
    """Terminated or truncated, a collision ends the episode at the same step, and evaluation
    scores from ``info``: the same episodes under either rule give the same results."""
    by_rule = {}
    for terminates in (False, True):
        env = gym.make("bulletnav/WarehouseAisles-v0", collision_terminates=terminates)
        try:
            results = run_episodes(env, _Ahead(float(env.action_space.high[0])), episodes=3, seed=1000)
        finally:
            env.close()
        summary = summarize(results)
        by_rule[terminates] = [
            {k: v for k, v in row.items() if k != "wall_time"} for row in summary.pop("per_episode")
        ], {k: v for k, v in summary.items() if "wall" not in k}
    assert any(row["collision"] for row in by_rule[True][0])  # the rule is exercised
    assert json.dumps(by_rule[False], sort_keys=True) == json.dumps(by_rule[True], sort_keys=True)  # NaN as NaN
