"""Sweeps on Ray Tune (``pytest -k sweep``): the sweep file's validation, and real Ray
clusters, not mocks -- a two-node local cluster for the trials' placement, a failing trial
and a search with early stopping, and an interrupted (Ctrl-C) sweep resumed from disk."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import hang
from bulletnav.errors import ConfigError, RunError
from bulletnav.sweep.results import bootstrap_ci, summarize_configs
from bulletnav.sweep.spec import SweepSpec
from hang import HANG_S
from rollouts import episode_rows

# a budget that trains for real but in seconds: 1 env, PPO updates every 64 steps, and episodes
# cut at 200 steps so an untrained policy's evaluations end in a fifth of the env's 1,000
TINY = {"algo": "ppo", "timesteps": 256, "n_envs": 1, "grid": {"n_steps": [64], "batch_size": [64]},
        "env_kwargs": {"max_episode_steps": 200},
        "eval_freq": 128, "eval_episodes": 1, "checkpoint_freq": 128, "evaluation": {"episodes": 2, "seed": 1000}}


def _write(tmp_path: Path, name: str, data) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return path


# --- the sweep file -----------------------------------------------------------------------

@pytest.mark.parametrize("data, field", [
    ({"timesteps": 10}, "'algo'"),
    ({"algo": "dqn"}, "'algo'"),
    ({"algo": "ppo", "seed": [1, 2]}, "'seed'"),
    ({"algo": "ppo", "seeds": []}, "'seeds'"),
    ({"algo": "ppo", "seeds": [1, 1]}, "'seeds'"),
    ({"algo": "ppo", "timesteps": -5}, "'timesteps'"),
    ({"algo": "ppo", "grid": {"learning_rate": 0.001}}, "'grid'"),
    ({"algo": "ppo", "search": {"learning_rate": {"lognormal": [1, 2]}}}, "'search'"),
    ({"algo": "ppo", "search": {"learning_rate": {"loguniform": [0.0, 1e-3]}}}, "'search'"),
    ({"algo": "ppo", "search": {"n_steps": {"randint": [512, 64]}}}, "'search'"),
    ({"algo": "ppo", "metric": "accuracy"}, "'metric'"),
    ({"algo": "ppo", "early_stopping": {"scheduler": "hyperband"}}, "'early_stopping'"),
    ({"algo": "ppo", "resources": {"cpu": -1}}, "'resources'"),
    ({"algo": "ppo", "hyperparams": "no/such/file.yml"}, "'hyperparams'"),
    ({"algo": "ppo", "vec_env": "threads"}, "'vec_env'"),
    ({"algo": "ppo", "evaluation": {"episodes": 0}}, "'evaluation'"),
    ("algo: ppo\ngrid: [", "not valid YAML"),
    ("- algo: ppo", "mapping"),
])
def test_sweep_file_errors_name_the_file_and_field(tmp_path, data, field):
    path = _write(tmp_path, "bad", data)
    with pytest.raises(ConfigError) as err:
        SweepSpec.from_file(path)
    assert str(path) in str(err.value) and field in str(err.value)


def test_sweep_cli_reports_a_malformed_file_without_a_traceback(tmp_path, capsys):
    from bulletnav.cli import main

    path = _write(tmp_path, "bad", {"algo": "ppo", "grid": {"learning_rate": 0.001}})
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "bulletnav sweep: error:" in err and "'grid'" in err and str(path) in err
    assert not (tmp_path / "out").exists()  # nothing started


def test_sweep_file_defaults_and_grid_expansion(tmp_path):
    spec = SweepSpec.from_file(_write(tmp_path, "grid", {
        "algo": "ppo", "seeds": [3, 4], "grid": {"learning_rate": [1e-3, 1e-4], "env_kwargs.reward_collision": [-20, -40]}}))
    assert spec.name == "grid" and spec.env_id == "bulletnav/Warehouse-v0" and spec.timesteps == 500_000
    assert spec.metric == "success_rate" and spec.evaluation_episodes == 200 and spec.evaluation_seed == 1000
    configs = spec.configurations()
    assert len(configs) == 4 and {c["learning_rate"] for c in configs} == {1e-3, 1e-4}
    assert {(c["learning_rate"], c["env_kwargs.reward_collision"]) for c in configs} == {
        (a, b) for a in (1e-3, 1e-4) for b in (-20, -40)}
    assert SweepSpec.from_record(json.loads(json.dumps(spec.to_dict()))) == spec
    assert SweepSpec.from_dict({"algo": "sac"}).configurations() == [{}]


def test_sweep_shipped_files_are_valid():
    root = Path(__file__).resolve().parents[1] / "docs" / "sweeps"
    files = sorted(root.glob("*.yaml"))
    assert files, "docs/sweeps/ holds the sweep files of docs/sweeps.md"
    for f in files:
        SweepSpec.from_file(f)


# --- the table ------------------------------------------------------------------------------

def test_sweep_bootstrap_interval_matches_an_independent_resampling():
    x = np.array([0.9, 0.95, 0.975, 0.99, 0.93])
    lo, hi = bootstrap_ci(x, resamples=20_000, seed=1)
    rng = np.random.default_rng(12345)  # an independent resampling, loop by loop
    means = np.array([rng.choice(x, size=x.size, replace=True).mean() for _ in range(20_000)])
    ref = np.quantile(means, [0.025, 0.975])
    assert abs(lo - ref[0]) < 0.004 and abs(hi - ref[1]) < 0.004
    assert lo < x.mean() < hi and x.min() <= lo and hi <= x.max()
    # by hand: resampled means of [0, 1] are 0, 0.5, 1 with chances 1/4, 1/2, 1/4, so the 2.5 % and
    # 97.5 % quantiles are 0 and 1, and the 30 % and 70 % ones both 0.5
    assert bootstrap_ci([0.0, 1.0], resamples=20_000) == (0.0, 1.0)
    assert bootstrap_ci([0.0, 1.0], level=0.4, resamples=20_000) == (0.5, 0.5)
    assert all(np.isnan(bootstrap_ci([0.5])))


def test_sweep_summary_groups_seeds_and_ranks_by_the_metric():
    rows = [{"config": {"lr": 1}, "seed": s, "status": "finished", "success_rate": v} for s, v in ((0, 0.5), (1, 0.7))]
    rows += [{"config": {"lr": 2}, "seed": 0, "status": "finished", "success_rate": 0.9},
             {"config": {"lr": 2}, "seed": 1, "status": "error", "success_rate": None}]
    best, other = summarize_configs(rows)
    assert best["config"] == {"lr": 2} and best["n"] == 1 and best["failed"] == 1 and best["ci95"] is None
    assert other["n"] == 2 and other["mean"] == pytest.approx(0.6) and other["seeds"] == [0, 1]
    assert other["ci95"][0] >= 0.5 and other["ci95"][1] <= 0.7
    assert summarize_configs(rows, mode="min")[0]["config"] == {"lr": 1}


# --- real Ray clusters --------------------------------------------------------------------

@pytest.fixture(scope="module")
def two_node_cluster():
    """A head with no CPUs (so no trial can run there) and two worker nodes of one CPU each."""
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    # no dashboard: nothing here reads it, and its web modules are one more process's imports to wait for
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    workers = [cluster.add_node(num_cpus=1) for _ in range(2)]
    ray.init(address=cluster.address)
    try:
        yield {"head": cluster.head_node.node_id, "workers": {w.node_id for w in workers}}
    finally:
        ray.shutdown()
        cluster.shutdown()


@pytest.mark.slow
def test_sweep_two_trials_run_on_the_two_worker_nodes(tmp_path, two_node_cluster):
    from bulletnav.sweep.run import SweepOptions, run_sweep

    spec = SweepSpec.from_dict({**TINY, "name": "two", "seeds": [0, 1]})
    record = run_sweep(spec, SweepOptions(out=tmp_path))
    rows = record["trials"]
    assert [r["status"] for r in rows] == ["finished", "finished"] and [r["seed"] for r in rows] == [0, 1]
    assert {r["node"] for r in rows} == two_node_cluster["workers"]  # one trial on each worker, none on the head
    for r in rows:
        assert r["timesteps"] >= spec.timesteps and Path(r["model"]).is_file()
        # the table's score is the saved model's: recomputed from episode rows that a loop written
        # here collects (not evaluate_model, run_episodes or summarize, which the sweep used)
        episodes = episode_rows(r["model"], spec.evaluation_episodes, spec.evaluation_seed, spec.env_id)
        assert [e["seed"] for e in episodes] == [1000, 1001]
        assert r["success_rate"] == sum(e["success"] for e in episodes) / len(episodes)
        assert r["mean_reward"] == pytest.approx(sum(e["reward"] for e in episodes) / len(episodes), rel=1e-9)
        assert r["mean_length"] == pytest.approx(sum(e["steps"] for e in episodes) / len(episodes), rel=1e-12)
        run = json.loads((Path(r["model"]).parent / "run.json").read_text())
        assert run["seed"] == r["seed"] and run["hyperparams"]["n_steps"] == 64 and run["n_envs"] == 1
    out = tmp_path / "two"
    with open(out / "trials.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 2 and {t["status"] for t in table} == {"finished"}
    (summary,) = record["summary"]
    assert summary["n"] == 2 and summary["mean"] == pytest.approx(np.mean([r["success_rate"] for r in rows]))
    assert (out / "summary.csv").is_file() and (out / "results.png").stat().st_size > 1000
    saved = json.loads((out / "results.json").read_text())
    assert saved["spec"]["name"] == "two" and len(saved["trials"]) == 2
    with pytest.raises(RunError, match="--resume"):  # the same name again would mix two sweeps
        run_sweep(spec, SweepOptions(out=tmp_path))


@pytest.mark.slow
def test_sweep_a_failing_trial_is_reported_and_the_others_finish(tmp_path, two_node_cluster):
    from bulletnav.sweep.run import SweepOptions, run_sweep

    spec = SweepSpec.from_dict({**TINY, "name": "fails", "grid": {**TINY["grid"], "learning_rate": [3e-4, "lin_oops"]}})
    record = run_sweep(spec, SweepOptions(out=tmp_path))
    by_lr = {r["config"]["learning_rate"]: r for r in record["trials"]}
    assert by_lr[3e-4]["status"] == "finished" and by_lr[3e-4]["success_rate"] is not None
    assert by_lr["lin_oops"]["status"] == "error" and "oops" in by_lr["lin_oops"]["error"]
    failed = next(s for s in record["summary"] if s["config"]["learning_rate"] == "lin_oops")
    assert failed["failed"] == 1 and failed["n"] == 0


@pytest.mark.slow
def test_sweep_optimize_writes_a_hyperparameter_file_train_accepts(tmp_path, two_node_cluster):
    from bulletnav.rl.hyperparams import load_hyperparams
    from bulletnav.sweep.run import SweepOptions, run_sweep

    spec = SweepSpec.from_dict({**TINY, "name": "opt", "grid": None,
                                "search": {"learning_rate": {"loguniform": [1e-5, 1e-3]}, "n_steps": {"choice": [64]},
                                           "batch_size": {"choice": [64]}},
                                "early_stopping": {"scheduler": "asha", "grace_period": 128}})
    record = run_sweep(spec, SweepOptions(out=tmp_path, optimize=2))
    lrs = [r["config"]["learning_rate"] for r in record["trials"]]
    assert len(lrs) == 2 and lrs[0] != lrs[1] and all(1e-5 <= lr <= 1e-3 for lr in lrs)
    best = record["best"]
    hp = load_hyperparams("ppo", env_id=spec.env_id, path=best["hyperparams"])
    assert hp["learning_rate"] == pytest.approx(best["config"]["learning_rate"]) and hp["n_steps"] == 64
    assert hp["policy_kwargs"]["net_arch"] == {"pi": [128, 128], "vf": [128, 128]}  # the rest is the base file's


@pytest.mark.slow
def test_sweep_interrupted_with_ctrl_c_resumes_without_rerunning_finished_trials(tmp_path):
    pytest.importorskip("ray")
    path = _write(tmp_path, "resume", {**TINY, "timesteps": 1024, "checkpoint_freq": 128, "eval_freq": 128,
                                       "seeds": [0, 1]})
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "bulletnav.cli", "sweep", str(path), "--out", str(out), "--num-cpus", "1"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    exp = out / "resume"
    first = None
    deadline = time.time() + HANG_S  # a hang detector, not a speed check: a loaded machine is slow to get there
    try:  # one CPU: the seed-0 trial runs first; interrupt once it is done and seed 1 has a checkpoint
        while time.time() < deadline and proc.poll() is None:
            done = list(exp.glob("*_seed0/checkpoint_*/heldout.json"))
            # seed 1's second report: by then Tune's driver has surely taken in the first (the
            # state a Ctrl-C saves); interrupting right at the first raced with it on a loaded machine
            started = list(exp.glob("*_seed1/checkpoint_000001/checkpoints/last.zip"))
            if done and started:
                first = done[0]
                break
            time.sleep(0.1)
        if first is None:
            proc.kill()
            pytest.fail(f"the sweep never reached the point to interrupt in {HANG_S:.0f} s: a hang? (a hang detector, not a "
                        "speed check)\n" + hang.communicate(proc, "the killed sweep", timeout=60)[0][-3000:], pytrace=False)
        proc.send_signal(signal.SIGINT)
        out_text, _ = hang.communicate(proc, "the sweep after its Ctrl-C")
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode != 0 and "--resume" in out_text
    assert not list(exp.glob("*_seed1/checkpoint_*/heldout.json"))  # seed 1 really was cut short
    finished_at = first.stat().st_mtime_ns
    # a guard against a hang, not a timing check: on a loaded 2-core machine the resumed trial took over 300 s
    resumed = hang.run([*cmd, "--resume", "--json"], "the resumed sweep")
    assert resumed.returncode == 0, resumed.stdout[-2000:] + resumed.stderr[-2000:]
    record = json.loads(resumed.stdout)  # --json: the whole of stdout is the one document (test_json_output)
    assert [r["status"] for r in record["trials"]] == ["finished", "finished"]
    assert first.stat().st_mtime_ns == finished_at  # the finished trial was not rerun
    run1 = json.loads((Path(record["trials"][1]["model"]).parent / "run.json").read_text())
    assert run1["resumed_from"] and 0 < run1["resumed_from"] < 1024  # seed 1 went on from its checkpoint
    assert run1["total_timesteps"] >= 1024
