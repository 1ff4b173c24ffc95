"""Learning in the fleet (``bulletnav.fleet.vec``, ``learned``, ``training``): the vector-env
adapter against SB3's VecEnv API and against a plain fleet stepped by hand (autoreset,
``terminal_observation``), seeded runs equal step for step, batched inference against
per-robot ``predict``, and ``bulletnav fleet-train`` writing a loadable safe model and
resuming from its checkpoint."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from stable_baselines3.common.vec_env import VecEnv, VecMonitor, VecNormalize

from bulletnav.cli import main
from bulletnav.fleet import fleet_v0
from bulletnav.fleet.controllers import DEFAULT_FLEET_MODEL, make_controller, model_env_kwargs, policy_controller
from bulletnav.fleet.learned import SharedPolicyController
from bulletnav.fleet.vec import FleetVecEnv
from bulletnav.rl.io import load_model
from bulletnav.rl.policy import SB3Policy

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / DEFAULT_FLEET_MODEL
EMPTY = str(ROOT / "bulletnav" / "assets" / "worlds" / "empty.yaml")
ROOM = {"world": EMPTY, "pick_stations": [(2.0, 3.0), (-2.0, 3.0)], "drop_stations": [(3.0, -3.5), (-3.0, -3.5)]}
STEPS_PER_EPISODE = 12  # 0.5 s at 24 Hz


def _fleet_kwargs(num_robots: int = 2, duration_s: float = 0.5) -> dict:
    return {**model_env_kwargs(MODEL), **ROOM, "num_robots": num_robots, "duration_s": duration_s}


def _vec(fleets: int = 2, num_robots: int = 2, seed: int = 7) -> FleetVecEnv:
    kwargs = _fleet_kwargs(num_robots)
    venv = FleetVecEnv([lambda: fleet_v0.parallel_env(**kwargs) for _ in range(fleets)])
    venv.seed(seed)
    return venv


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(-1.0, 1.0, (n, 2)).astype(np.float32)


# ------------------------------------------------------------------ the adapter
def test_adapter_follows_the_vecenv_api():
    venv = _vec(fleets=2, num_robots=2)
    try:
        assert isinstance(venv, VecEnv) and venv.num_envs == 4
        assert venv.slots == [(0, "robot_0"), (0, "robot_1"), (1, "robot_0"), (1, "robot_1")]
        probe = fleet_v0.parallel_env(**_fleet_kwargs())
        assert venv.observation_space == probe.observation_space("robot_0")
        assert venv.action_space == probe.action_space("robot_0")
        probe.close()
        obs = venv.reset()
        assert obs.shape == (4, *venv.observation_space.shape) and obs.dtype == venv.observation_space.dtype
        assert all(venv.observation_space.contains(o) for o in obs)
        assert not np.shares_memory(obs, venv.reset())
        obs, rewards, dones, infos = venv.step(_actions(np.random.default_rng(0), 4))
        assert obs.shape == (4, *venv.observation_space.shape)
        assert rewards.shape == (4,) and rewards.dtype == np.float32 and np.all(np.isfinite(rewards))
        assert dones.shape == (4,) and dones.dtype == bool and not dones.any()
        assert len(infos) == 4 and all(isinstance(i, dict) and "reward_progress" in i for i in infos)
        # the reward is the sum of the fleet's named per-agent terms
        assert rewards[0] == pytest.approx(sum(v for k, v in infos[0].items() if k.startswith("reward_")), abs=1e-5)
        assert venv.get_attr("possible_agents") == [["robot_0", "robot_1"]] * 4
        assert venv.get_attr("num_agents", indices=[2]) == [2]
        assert venv.env_is_wrapped(VecEnv) == [False] * 4
        assert venv.env_method("observation_space", "robot_1", indices=0) == [venv.observation_space]
        assert venv.seed(100) == [100, 100, 101, 101]  # fleet k: seed + k
        # SB3's own wrappers stack on it
        wrapped = VecNormalize(VecMonitor(venv), norm_obs=False, norm_reward=True)
        assert wrapped.reset().shape == (4, *venv.observation_space.shape)
        wrapped.step(_actions(np.random.default_rng(1), 4))
        # SB3's VecMonitor scores each robot's episode: 12 steps (0.5 s at 24 Hz, by hand) and the
        # return summed here from the rewards the adapter handed out
        monitor = VecMonitor(venv)
        monitor.reset()
        rng, returns = np.random.default_rng(2), np.zeros(4)
        for step in range(1, STEPS_PER_EPISODE + 1):
            _, rewards, dones, infos = monitor.step(_actions(rng, 4))
            returns += rewards
            assert dones.all() == (step == STEPS_PER_EPISODE) and dones.any() == dones.all()
        for i in range(4):
            assert infos[i]["episode"]["l"] == 12
            assert infos[i]["episode"]["r"] == pytest.approx(returns[i], abs=1e-5)
    finally:
        venv.close()


def test_autoreset_matches_a_fleet_stepped_by_hand():
    """All agents end together; the done step carries the last observation as
    ``terminal_observation`` and returns the next episode's first, exactly as a plain fleet
    stepped and reset by hand (continuing its own generator) gives them."""
    rng = np.random.default_rng(3)
    actions = [_actions(rng, 2) for _ in range(STEPS_PER_EPISODE + 2)]
    venv = _vec(fleets=1, num_robots=2, seed=11)
    ref = fleet_v0.parallel_env(**_fleet_kwargs())
    try:
        obs = venv.reset()
        ref_obs, _ = ref.reset(seed=11)
        np.testing.assert_array_equal(obs, np.stack([ref_obs["robot_0"], ref_obs["robot_1"]]))
        for t, a in enumerate(actions):
            obs, rewards, dones, infos = venv.step(a)
            ref_obs, ref_rew, _, ref_trunc, _ = ref.step({"robot_0": a[0], "robot_1": a[1]})
            last = np.stack([ref_obs["robot_0"], ref_obs["robot_1"]])
            np.testing.assert_array_equal(rewards, np.array([ref_rew["robot_0"], ref_rew["robot_1"]], dtype=np.float32))
            if t + 1 == STEPS_PER_EPISODE:
                assert dones.all() and all(ref_trunc.values())
                for i in range(2):
                    np.testing.assert_array_equal(infos[i]["terminal_observation"], last[i])
                    assert infos[i]["TimeLimit.truncated"] is True
                ref_obs, _ = ref.reset()  # autoreset: no seed, the fleet's generator goes on
                np.testing.assert_array_equal(obs, np.stack([ref_obs["robot_0"], ref_obs["robot_1"]]))
                assert not np.array_equal(obs, last)
            else:
                assert not dones.any() and not any("terminal_observation" in i for i in infos)
                np.testing.assert_array_equal(obs, last)
    finally:
        venv.close()
        ref.close()


def test_seeded_runs_are_equal_step_for_step():
    def run() -> list[np.ndarray]:
        venv = _vec(fleets=2, num_robots=2, seed=5)
        rng = np.random.default_rng(9)
        try:
            out = [venv.reset()]
            for _ in range(STEPS_PER_EPISODE + 3):  # through an autoreset
                obs, rewards, dones, infos = venv.step(_actions(rng, 4))
                out += [obs, rewards, dones.astype(np.float32)]
                out += [i["terminal_observation"] for i in infos if "terminal_observation" in i]
            return out
        finally:
            venv.close()

    a, b = run(), run()
    assert len(a) == len(b) > 3 * STEPS_PER_EPISODE
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    # by hand: 0.5 s episodes at 24 Hz end together on step 12 and only there, each of the 4
    # robots then handing over one terminal observation (reset obs, then obs, rewards, dones per step)
    dones, k = [], 1
    for _ in range(STEPS_PER_EPISODE + 3):
        dones.append(a[k + 2])
        k += 3 + (4 if a[k + 2].any() else 0)
    assert k == len(a)
    assert [d.tolist() for d in dones] == [[float(t == 12)] * 4 for t in range(1, STEPS_PER_EPISODE + 4)]


# ------------------------------------------------------------------ batched inference
def test_batched_actions_match_per_robot_predict():
    """One forward pass for all robots gives each robot the action its own ``predict`` gives,
    to float32 rounding (a batch of N and a batch of 1 go through different matrix kernels,
    whose sums may differ in the last bits)."""
    env = fleet_v0.parallel_env(**_fleet_kwargs(num_robots=3, duration_s=1.0))
    controller = policy_controller(env, MODEL)
    assert isinstance(controller, SharedPolicyController)
    single = SB3Policy(controller.model, controller.normalizer)
    obs, infos = env.reset(seed=2000)
    controller.reset(infos)
    steps = 0
    try:
        while env.agents:
            batched = controller.act(obs, infos)
            for agent in env.agents:
                np.testing.assert_allclose(batched[agent], single.act(obs[agent], infos[agent]), rtol=0, atol=1e-6)
            obs, _, _, _, infos = env.step(batched)
            steps += 1
    finally:
        env.close()
    assert controller.forward_passes == steps == 24


# ------------------------------------------------------------------ fleet-train
def _tiny_hyperparams(tmp_path: Path) -> Path:
    """The shipped fine-tuning file with rollouts and updates small enough for a test."""
    src = ROOT / "bulletnav" / "rl" / "hyperparams" / "ppo_dynamic_finetune_movers.yml"
    data = yaml.safe_load(src.read_text())
    data["bulletnav/WarehouseDynamic-v0"].update(n_steps=32, batch_size=32, n_epochs=1)
    path = tmp_path / "tiny.yml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_fleet_train_writes_a_safe_model_and_resumes(tmp_path, capsys):
    out = tmp_path / "run"
    hp = _tiny_hyperparams(tmp_path)
    args = ["fleet-train", "--init-from", str(MODEL), "--robots", "2", "--duration", "1", "--seed", "3",
            "--hyperparams", str(hp), "--checkpoint-freq", "128", "--layouts-every", "2", "--no-progress", "--out", str(out)]
    assert main([*args, "--timesteps", "256"]) == 0
    assert "fleet-trained PPO for 256 agent steps" in capsys.readouterr().out
    for name in ("model.zip", "model.safetensors", "model.json", "model_vecnormalize.json", "run.json", "config.json",
                 "episodes.json", "checkpoints/last.zip", "checkpoints/last.json", "checkpoints/last_vecnormalize.json"):
        assert (out / name).is_file(), name
    assert not list(out.rglob("*.tmp")) and not list(out.rglob("*.pkl"))
    record = json.loads((out / "run.json").read_text())
    assert record["seed"] == 3 and record["total_timesteps"] == 256 and record["slots"] == 2
    assert record["command"] and record["git_commit"] and record["machine"] and record["versions"]["pettingzoo"]
    assert record["env_kwargs"]["reward_collision"] == -40.0  # the collision price of the fine-tuning file
    assert record["env_kwargs"]["layouts_every"] == 2 and record["env_kwargs"]["guidance"] == "floorplan"
    episodes = json.loads((out / "episodes.json").read_text())
    assert [e["timesteps"] for e in episodes] == [48, 96, 144, 192, 240]  # 24 steps x 2 robots each
    model, meta, normalizer = load_model(out / "model.zip")
    assert meta["format"] == "bulletnav-policy/1" and meta["fleet"]["num_robots"] == 2 and model.num_timesteps == 256
    assert normalizer is not None and meta["normalization"]["ret"] is not None
    init, _, _ = load_model(MODEL)
    moved = [not np.array_equal(a.detach().numpy(), b.detach().numpy())
             for a, b in zip(model.policy.parameters(), init.policy.parameters())]
    assert any(moved)  # it learned something
    # it drives the fleet through the policy controller, with the env settings its sidecar gives
    env = fleet_v0.parallel_env(**{**model_env_kwargs(out / "model.zip"), **ROOM, "num_robots": 2, "duration_s": 0.5})
    try:
        controller = make_controller("policy", env, model=out / "model.zip")
        obs, infos = env.reset(seed=0)
        actions = controller.act(obs, infos)
        assert set(actions) == {"robot_0", "robot_1"} and all(env.action_space(a).contains(v) for a, v in actions.items())
    finally:
        env.close()

    # an --out holding a run is refused without --resume
    assert main([*args, "--timesteps", "384"]) == 2
    assert "already holds a run" in capsys.readouterr().err
    # resume: from the checkpoint's step count, with the recorded settings, to the new total
    before = json.loads((out / "checkpoints" / "last.json").read_text())
    assert before["timesteps"] == 256
    assert main([*args, "--timesteps", "384", "--resume"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["resumed_from"] == 256 and record["total_timesteps"] == 384
    assert load_model(out / "model.zip")[0].num_timesteps == 384
    assert json.loads((out / "checkpoints" / "last.json").read_text())["timesteps"] == 384
