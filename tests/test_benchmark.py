"""``bulletnav benchmark``: suite files, the metrics against hand computations, rows that are
the same at 1 and 2 workers and equal to the committed tiny results, resuming, the CLI."""

from __future__ import annotations

import gzip
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from bulletnav.benchmark.compare import compare_results, comparison_lines, load_results
from bulletnav.benchmark.metrics import (
    INTIMATE_M,
    EpisodeTrace,
    bootstrap_interval,
    cell_summary,
    drive_time,
    episode_metrics,
)
from bulletnav.benchmark.runner import build_results, run_suite
from bulletnav.benchmark.suite import SuiteError, load_suite, parse_suite
from bulletnav.cli import main
from bulletnav.errors import BulletnavError
from bulletnav.evaluation import EpisodeResult
from bulletnav.runs import run_in_pool

DATA = Path(__file__).resolve().parent / "data"
TINY = DATA / "benchmark_tiny.yaml"
GOLDEN = Path(__file__).resolve().parent / "golden" / "benchmark_tiny.json"


# ------------------------------------------------------------------ suites
def _suite(**over):
    raw = {"name": "t", "episodes": 2, "seed": 5, "worlds": [{"env": "bulletnav/Warehouse-v0"}],
           "controllers": [{"type": "navigator", "planner": "astar"}]}
    raw.update(over)
    return parse_suite(raw, "t.yaml")


@pytest.mark.parametrize("over, field", [
    ({"episodes": 0}, "'episodes'"),
    ({"worlds": []}, "'worlds'"),
    ({"worlds": [{"env": "CartPole-v1"}]}, "'worlds[0].env'"),
    ({"worlds": [{"env": "bulletnav/Warehouse-v0", "kwargs": {"lidar_rays": 10}}]}, "worlds[0].kwargs"),
    ({"controllers": [{"type": "navigator", "planner": "dijkstra"}]}, "'controllers[0].planner'"),
    ({"controllers": [{"type": "robot"}]}, "'controllers[0].type'"),
    ({"controllers": [{"type": "policy", "class": "nomodule"}]}, "'controllers[0].class'"),
    ({"controllers": [{"type": "model", "model": "x.zip", "shield": "yes"}]}, "'controllers[0].shield'"),
    ({"controllers": [{"type": "navigator"}, {"type": "navigator"}]}, "distinct names"),
    ({"colour": "red"}, "unknown field"),
])
def test_bad_suites_name_file_and_field(over, field):
    with pytest.raises(SuiteError, match="t.yaml") as err:
        _suite(**over)
    assert field in str(err.value)


def test_suite_names_and_counts():
    suite = _suite(worlds=[{"env": "bulletnav/WarehouseAisles-v0", "episodes": 3}, {"env": "bulletnav/Warehouse-v0"}],
                   controllers=[{"type": "navigator", "planner": "none"}, {"type": "model", "model": "shipped",
                                                                            "shield": True}])
    assert [w.name for w in suite.worlds] == ["aisles", "scattered"]
    assert [c.name for c in suite.controllers] == ["PID", "PPO + shield"]
    assert suite.total == (3 + 2) * 2
    assert load_suite("quick").name == "quick" and load_suite("standard").episodes == 200
    with pytest.raises(SuiteError, match="quick, shield-random, standard"):
        load_suite("nosuch")


# ------------------------------------------------------------------ metrics
def test_drive_time_is_the_trapezoid_or_the_triangle():
    # 4 m at 0.5 m/s, 2.5 m/s^2: 0.2 s ramps each way covering 0.05 m each, 3.9 m cruising
    assert drive_time(4.0, 0.5, 2.5) == pytest.approx(0.2 + 3.9 / 0.5 + 0.2)
    # 0.05 m never reaches top speed: accelerate half way, brake half way
    assert drive_time(0.05, 0.5, 2.5) == pytest.approx(2 * math.sqrt(0.025 / 2.5 * 2))
    assert drive_time(0.0, 0.5, 2.5) == 0.0


def _result(**kw) -> EpisodeResult:
    base = dict(episode=1, seed=0, initial_distance=3.0, shortest_path=3.0, steps=0, reward=0.0, final_distance=0.3,
                path_length=3.0, success=True, collision=False, spl=1.0, sim_time=0.0, wall_time=0.0)
    base.update(kw)
    return EpisodeResult(**base)


class _View:
    def __init__(self):
        self.pose = (0.0, 0.0, 0.0)
        self.movers = ()


def test_straight_drive_metrics_against_hand_values():
    dt, v = 0.05, 0.5
    trace = EpisodeTrace(dt, top_speed=0.5)
    view = _View()
    n = 121  # 120 steps of 2.5 cm: 3 m straight along x at top speed
    for k in range(n):
        view.pose = (k * v * dt, 0.0, 0.0)
        trace.record(view, {})
    row = episode_metrics(_result(steps=n - 1, path_length=3.0), trace, accel=2.5)
    t = (n - 1) * dt
    assert row["time_s"] == pytest.approx(6.0)
    assert row["path_irregularity"] == 0.0 and row["jerk"] == pytest.approx(0.0, abs=1e-6)
    t_star = drive_time(3.0, 0.5, 2.5)  # 6.2 s: faster than possible from rest is capped at 1
    assert row["sct"] == pytest.approx(t_star / max(t, t_star)) and row["sct"] == 1.0
    assert row["barn_score"] == pytest.approx(6.0 / (2 * 6.0))  # t <= 2 t_opt: BARN's lower clip (run.py)
    assert math.isnan(row["min_separation_m"]) and row["intimate_robot_s"] == 0.0


def test_turning_and_a_slow_drive():
    trace = EpisodeTrace(0.1, top_speed=0.5)
    view = _View()
    for k in range(11):  # a quarter turn while driving 1 m
        view.pose = (0.1 * k, 0.0, math.pi / 2 * k / 10)
        trace.record(view, {})
    row = episode_metrics(_result(steps=10, path_length=1.0, shortest_path=1.0), trace, accel=2.5)
    assert row["path_irregularity"] == pytest.approx(math.pi / 2)
    t_opt = 1.0 / 0.5
    assert row["barn_score"] == pytest.approx(t_opt / (2 * t_opt))  # 1 s for t_opt = 2 s: clipped to 2 t_opt
    slow = EpisodeTrace(0.1, top_speed=0.5)
    for k in range(301):  # 30 s for the same metre: beyond 8 t_opt
        view.pose = (k / 300, 0.0, 0.0)
        slow.record(view, {})
    row = episode_metrics(_result(steps=300, path_length=1.0, shortest_path=1.0), slow, accel=2.5)
    assert row["barn_score"] == pytest.approx(t_opt / (8 * t_opt))
    assert row["sct"] == pytest.approx(drive_time(1.0, 0.5, 2.5) / 30.0)
    failed = episode_metrics(_result(steps=300, success=False, spl=0.0), slow, accel=2.5)
    assert failed["sct"] == failed["barn_score"] == failed["spl"] == 0.0


class _Mover:
    def __init__(self, kind, pose, size):
        self.kind, self.pose, self.size = kind, pose, size


def test_person_zones_are_counted_both_ways_and_collisions_by_kind():
    dt = 0.1
    trace = EpisodeTrace(dt, top_speed=0.5)
    view = _View()
    worker = _Mover("worker", (2.0, 0.0, 0.0), (0.5, 0.5, 1.7))
    view.movers = (worker,)
    xs = [0.0, 0.5, 1.0, 1.5, 1.6, 1.6, 1.6]  # drives up to 0.4 m from the worker, then stands
    for x in xs:
        view.pose = (x, 0.0, 0.0)
        trace.record(view, {})
    # after steps 1..6 the distances are 1.5, 1.0, 0.5, 0.4, 0.4, 0.4; moving on steps 1..4
    row = episode_metrics(_result(steps=6, path_length=1.6, min_separation=0.1), trace, accel=2.5)
    assert row["personal_robot_s"] == pytest.approx(3 * dt)  # 1.0, 0.5, 0.4 while moving
    assert row["intimate_robot_s"] == pytest.approx(1 * dt)  # 0.4 on the last moving step
    assert row["intimate_person_s"] == pytest.approx(2 * dt) and row["personal_person_s"] == pytest.approx(2 * dt)
    assert 0.4 < INTIMATE_M
    forklift = _Mover("forklift", (0.0, 3.0, 0.0), (1.1, 0.8, 2.0))
    view.movers = (worker, forklift)
    view.pose = (0.0, 2.5, 0.0)  # touching the forklift, far from the worker
    trace.record(view, {"collision": True, "collision_with": "dynamic"})
    assert trace.hit == "mover"
    view.pose = (1.8, 0.0, 0.0)
    trace.record(view, {"collision": True, "collision_with": "dynamic"})
    assert trace.hit == "person"
    trace.record(view, {"collision": True, "collision_with": "static"})
    assert trace.hit == "static"


def test_bootstrap_interval_matches_scipys_percentile_bootstrap():
    """The cell intervals against SciPy's percentile bootstrap of the mean (200,000 resamples),
    NaN entries dropped. The benchmark draws 2,000 resamples: an end of its interval is off by
    about 0.06 standard errors of the mean from Monte-Carlo noise alone, so 0.25 of them is
    over 4 of that noise's own standard deviations. Two cases by hand. (At 052a810:
    reproducibility and bracketing the mean only.)"""
    from scipy.stats import bootstrap

    rng = np.random.default_rng(0)
    for values in (rng.random(50), rng.exponential(2.0, 30), (rng.random(40) < 0.8).astype(float)):
        ref = bootstrap((values,), np.mean, confidence_level=0.95, n_resamples=200_000, method="percentile",
                        random_state=np.random.default_rng(1)).confidence_interval
        tolerance = 0.25 * values.std() / math.sqrt(len(values))
        lo, hi = bootstrap_interval(np.concatenate([values, [math.nan] * 5]))
        assert abs(lo - ref.low) < tolerance and abs(hi - ref.high) < tolerance, (lo, hi, ref, tolerance)
    assert bootstrap_interval(np.full(10, 0.7)) == pytest.approx((0.7, 0.7))
    # resampled means of [0, 1]: 0, 0.5, 1 with chances 1/4, 1/2, 1/4: the 2.5 % and 97.5 % points are 0 and 1
    assert bootstrap_interval(np.array([0.0, 1.0])) == (0.0, 1.0)
    # of [0, 0, 0, 0, 1]: k / 5 with k ~ Binomial(5, 0.2), P(k <= 2) = 0.942, P(k <= 3) = 0.993: 0 and 0.6
    assert bootstrap_interval(np.array([0.0, 0.0, 0.0, 0.0, 1.0])) == pytest.approx((0.0, 0.6))
    assert all(math.isnan(v) for v in bootstrap_interval(np.array([math.nan])))
    summary = cell_summary([{**{k: 0.0 for k in ("min_separation_m",)}, **_zero_row(success=s)} for s in (1, 1, 0, 1)])
    assert summary["success"]["mean"] == 0.75 and summary["episodes"] == 4


def _zero_row(**over):
    from bulletnav.benchmark.metrics import METRICS

    row = {k: 0.0 for k in METRICS}
    row.update(over)
    return row


# ------------------------------------------------------------------ runs
def _rows(results):
    return [{k: v for k, v in r.items()} for r in results["episodes"]]


@pytest.fixture(scope="module")
def tiny_one(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "one"
    return run_suite(load_suite(str(TINY)), out, workers=1), out


@pytest.mark.slow
def test_tiny_results_are_the_committed_ones_at_1_and_2_workers(tiny_one, tmp_path):
    one, _ = tiny_one
    two = run_suite(load_suite(str(TINY)), tmp_path / "two", workers=2)
    expected = json.loads(GOLDEN.read_text())
    strict_one = json.loads((tiny_one[1] / "results.json").read_text())
    strict_two = json.loads((tmp_path / "two" / "results.json").read_text())
    assert strict_one["episodes"] == strict_two["episodes"] == expected["episodes"]
    assert strict_one["cells"] == strict_two["cells"] == expected["cells"]
    assert len(one["episodes"]) == 8 and {r["controller"] for r in one["episodes"]} == {"PID", "PPO + shield"}
    assert two["provenance"]["workers"] == 2


@pytest.mark.slow
def test_an_interrupted_run_resumes_without_rerunning(tiny_one, tmp_path):
    _, done = tiny_one
    out = tmp_path / "resumed"
    out.mkdir()
    lines = (done / "episodes.jsonl").read_text().splitlines()
    shutil.copy(done / "suite.json", out / "suite.json")
    (out / "episodes.jsonl").write_text("\n".join(lines[:5]) + "\n" + lines[5][:40])  # 5 rows, a torn sixth
    seen = []
    with pytest.raises(BulletnavError, match="--resume"):
        run_suite(load_suite(str(TINY)), out, workers=1)
    results = run_suite(load_suite(str(TINY)), out, workers=1, resume=True, progress=lambda d, t: seen.append(d))
    assert seen[0] == 5 and seen[-1] == 8  # five kept, three run
    assert len(results["episodes"]) == 8
    resumed = json.loads((out / "results.json").read_text())
    assert resumed["episodes"] == json.loads(GOLDEN.read_text())["episodes"]  # the committed rows, to the bit
    other = dict(json.loads((out / "suite.json").read_text()), sha256="0" * 64)
    (out / "suite.json").write_text(json.dumps(other))
    with pytest.raises(BulletnavError, match="another suite"):
        run_suite(load_suite(str(TINY)), out, workers=1, resume=True)


@pytest.mark.slow
def test_a_run_resumed_at_another_commit_names_both_in_results_and_report(tiny_one, tmp_path, monkeypatch):
    """Rows carry the checkout that ran them (in ``episodes.jsonl``, not in the results' rows, which
    stay the committed ones); a run resumed at another commit counts each commit's rows per
    controller, and the report says the rows come from more than one checkout."""
    import bulletnav.benchmark.runner as runner
    from bulletnav.benchmark.report import write_report

    _, done = tiny_one
    out = tmp_path / "mixed"
    out.mkdir()
    shutil.copy(done / "suite.json", out / "suite.json")
    old = [json.loads(line) for line in (done / "episodes.jsonl").read_text().splitlines()]
    kept = [dict(r, commit="a" * 40) for r in old if r["controller"] == "PID"][:3]  # three rows "from" commit a
    (out / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in kept))
    monkeypatch.setattr(runner, "git_commit", lambda: "b" * 40 + "-dirty")
    results = run_suite(load_suite(str(TINY)), out, workers=1, resume=True)
    written = json.loads((out / "results.json").read_text())
    assert written["episodes"] == json.loads(GOLDEN.read_text())["episodes"]  # no commit in the results' rows
    assert results["provenance"]["row_commits"] == {"PID": {"a" * 40: 3, "b" * 40 + "-dirty": 1},
                                                   "PPO + shield": {"b" * 40 + "-dirty": 4}}
    stamped = [json.loads(line)["commit"] for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert stamped == ["a" * 40] * 3 + ["b" * 40 + "-dirty"] * 5
    page = write_report(results, out / "report.html").read_text()
    assert "more than one checkout" in page and "aaaaaaaaaaaa</code>: PID (3)" in page
    assert "bbbbbbbbbbbb</code>: PID (1), PPO + shield (4)" in page
    single = json.loads((done / "results.json").read_text())
    assert "more than one checkout" not in write_report(single, tmp_path / "single.html").read_text()


@pytest.mark.slow
def test_cli_prints_the_headline_and_writes_the_report(tiny_one, tmp_path, capsys):
    results = json.loads((tiny_one[1] / "results.json").read_text())
    assert main(["benchmark", str(TINY), "--out", str(tmp_path / "cli"), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["episodes"] == results["episodes"] == json.loads(GOLDEN.read_text())["episodes"]
    assert (tmp_path / "cli" / "report.html").is_file()
    failures = [r for r in results["episodes"] if not r["success"]]
    for row in failures:
        assert row["replay"].startswith("bulletnav ") and f"--seed {row['seed']}" in row["replay"]


@pytest.mark.slow
def test_an_out_folder_with_results_is_refused_and_force_starts_afresh(tiny_one, tmp_path, capsys):
    """A folder that holds results and no run (the committed docs/benchmark/) is refused without
    --force, in one line with exit status 2, and left as it was; --force starts afresh over an
    earlier run (a stale row is gone, the committed rows are back); --resume with --force is refused."""
    _, done = tiny_one
    held = tmp_path / "held"
    held.mkdir()
    shutil.copy(done / "results.json", held / "results.json")
    before = (held / "results.json").read_bytes()
    assert main(["benchmark", str(TINY), "--out", str(held)]) == 2
    err = capsys.readouterr().err
    assert "holds results (results.json) and no run to resume: pass --force" in err and len(err.strip().splitlines()) == 1
    assert (held / "results.json").read_bytes() == before and not (held / "episodes.jsonl").exists()
    with pytest.raises(BulletnavError, match="choose one"):
        run_suite(load_suite(str(TINY)), held, workers=1, resume=True, force=True)
    earlier = tmp_path / "earlier"
    shutil.copytree(done, earlier)
    rows = (earlier / "episodes.jsonl").read_text().splitlines()
    stale = json.loads(rows[0])
    stale["success"] = 1 - stale["success"]
    (earlier / "episodes.jsonl").write_text("\n".join([json.dumps(stale)] + rows[1:]) + "\n")
    assert main(["benchmark", str(TINY), "--out", str(earlier)]) == 2
    assert "--force to start afresh" in capsys.readouterr().err
    assert main(["benchmark", str(TINY), "--out", str(earlier), "--force", "--json"]) == 0
    capsys.readouterr()
    assert json.loads((earlier / "results.json").read_text())["episodes"] == json.loads(GOLDEN.read_text())["episodes"]


@pytest.mark.slow
def test_compare_puts_a_rerun_beside_the_committed_rows(tiny_one, tmp_path, capsys):
    """A rerun of the tiny suite beside its committed golden results (and a gzipped copy of them):
    every episode ended the same way and every row is identical, no figure outside the committed
    interval; a committed file with one episode's outcome flipped counts one episode fewer."""
    _, done = tiny_one
    out = tmp_path / "rerun"
    shutil.copytree(done, out)
    golden = json.loads(GOLDEN.read_text())
    gz = tmp_path / "committed.json.gz"
    gz.write_bytes(gzip.compress(GOLDEN.read_bytes()))
    assert main(["benchmark", str(TINY), "--out", str(out), "--report-only", "--compare", str(gz), "--json"]) == 0
    comparison = json.loads(capsys.readouterr().out)["comparison"]
    assert comparison["episodes"] == {"compared": 8, "same_outcome": 8, "identical": 8}
    assert comparison["outside"] == 0 and len(comparison["cells"]) == len(golden["cells"])
    flipped = json.loads(GOLDEN.read_text())
    row = flipped["episodes"][3]
    row["success"], row["timeout"] = 1 - row["success"], row["success"]
    (tmp_path / "flipped.json").write_text(json.dumps(flipped))
    assert main(["benchmark", str(TINY), "--out", str(out), "--report-only", "--compare", str(tmp_path / "flipped.json")]) == 0
    text = capsys.readouterr().out
    assert "8 episodes in both: 7 ended the same way, 7 rows identical" in text
    assert "| world | controller | success: here / committed [95 %]" in text
    assert "comparison" not in json.loads((out / "results.json").read_text())  # the run's own record


def test_compare_counts_and_intervals_by_hand(tmp_path):
    """Two hand-made records: a cell whose success (0.8) lies above the other's interval
    [0.25, 0.75] and whose SPL (0.5) lies inside [0.4, 0.6]; of two episodes in both, both ended
    the same way and one row differs in its time; one episode and one cell only in the new run."""
    def cell(world, s, s_lo, s_hi, spl):
        return {"world": world, "controller": "PID", "summary": {
            "success": {"mean": s, "lo": s_lo, "hi": s_hi, "n": 4}, "spl": {"mean": spl, "lo": 0.4, "hi": 0.6, "n": 4}}}

    def row(k, t, success=1):
        return {"world": "a", "controller": "PID", "episode": k, "seed": 10 + k, "success": success, "collision": 0,
                "timeout": 1 - success, "time_s": t, "min_separation_m": float("nan")}

    new = {"cells": [cell("a", 0.8, 0.5, 1.0, 0.5), cell("b", 1.0, 1.0, 1.0, 0.9)],
           "episodes": [row(0, 5.0), row(1, 6.0, 0), row(2, 7.0)]}
    old = {"cells": [cell("a", 0.5, 0.25, 0.75, 0.45)], "episodes": [row(0, 5.0), row(1, 6.5, 0)],
           "provenance": {"git_commit": "abc123"}}
    c = compare_results(new, old)
    assert c["episodes"] == {"compared": 2, "same_outcome": 2, "identical": 1}
    figures = c["cells"][0]["metrics"]
    assert figures["success"] == {"new": 0.8, "old": 0.5, "old_lo": 0.25, "old_hi": 0.75, "inside": False}
    assert figures["spl"]["inside"] and c["outside"] == 1
    assert c["only_new"] == [["b", "PID"]] and c["only_old"] == [] and c["old_commit"] == "abc123"
    lines = comparison_lines(c, "old.json")
    assert lines[0].startswith("compared with old.json (abc123): 1 cells in both, 2 episodes in both: 2 ended the same way")
    assert "| a | PID | ! 0.800 / 0.500 [0.250, 0.750] | 0.500 / 0.450 [0.400, 0.600] |" in lines


@pytest.mark.parametrize("content, why", [
    (b"not json", "not JSON"),
    (b'{"cells": []}', "not a benchmark's results"),
    (b"[1, 2]", "not a benchmark's results"),
    (b'{"cells": [{"world": "w", "controller": "c"}], "episodes": []}', "is not a results cell"),
    (b'{"cells": [{"world": "w", "controller": "c", "summary": {"success": {"mean": "x"}}}], "episodes": []}',
     "not a number"),
    (b'{"cells": [], "episodes": [], "provenance": {"git_commit": 5}}', "not a commit name"),
])
def test_compare_refuses_a_file_that_is_not_results_in_one_line(tmp_path, capsys, content, why):
    bad = tmp_path / "other.json"
    bad.write_bytes(content)
    with pytest.raises(BulletnavError, match=why):
        load_results(bad)
    assert main(["benchmark", str(TINY), "--out", str(tmp_path / "x"), "--compare", str(bad)]) == 2
    err = capsys.readouterr().err
    assert why in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "x").exists()
    gz = tmp_path / "cut.json.gz"
    gz.write_bytes(gzip.compress(b'{"cells": [], "episodes": []}')[:-6])
    with pytest.raises(BulletnavError, match="cannot read it"):
        load_results(gz)
    with pytest.raises(BulletnavError, match="no such results file"):
        load_results(tmp_path / "missing.json")


def test_build_results_orders_rows_and_keeps_one_per_episode():
    suite = load_suite(str(TINY))
    rows = [{"world": w.name, "controller": c.name, "episode": k, **_zero_row(success=1)}
            for w in reversed(suite.worlds) for c in suite.controllers for k in (1, 0, 1)]
    results = build_results(suite, rows)
    keys = [(r["world"], r["controller"], r["episode"]) for r in results["episodes"]]
    assert keys == [(w.name, c.name, k) for w in suite.worlds for c in suite.controllers for k in (0, 1)]


@pytest.mark.slow
def test_tiny_suite_through_a_ray_cluster_gives_the_committed_rows(tmp_path):
    """``--address``: a real local cluster (a head with no CPUs, two one-CPU worker nodes), the
    benchmark connecting to it by address as a user would, every episode on a worker node."""
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    # no dashboard, as the sweep tests' cluster: nothing here reads it, and in the suite its process
    # takes CPU from the other test worker
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    for _ in range(2):
        cluster.add_node(num_cpus=1)
    try:
        cluster.wait_for_nodes()
        address = cluster.address
        results = run_suite(load_suite(str(TINY)), tmp_path / "ray", workers=2, address=address)
        assert not ray.is_initialized()  # the connection the run opened is closed
    finally:
        cluster.shutdown()
    expected = json.loads(GOLDEN.read_text())
    written = json.loads((tmp_path / "ray" / "results.json").read_text())
    assert written["episodes"] == expected["episodes"] and written["cells"] == expected["cells"]
    assert results["provenance"]["ray_address"] == address


def test_an_address_with_no_cluster_is_one_clear_error(tmp_path):
    pytest.importorskip("ray")
    with pytest.raises(BulletnavError, match="--address 127.0.0.1:1: cannot connect"):
        run_suite(load_suite(str(TINY)), tmp_path / "none", workers=1, address="127.0.0.1:1")


def test_pool_raises_a_jobs_error_without_starting_the_queued_jobs(tmp_path):
    """A failing job stops the run at once: before this, the pool ran every queued job (hours of
    a fleet comparison) and only then raised, its results thrown away."""
    import os

    made = [tmp_path / f"job{k}" for k in range(6)]
    jobs = [(math.sqrt, (-1.0,))] + [(os.mkdir, (str(p),)) for p in made]
    kept = []
    with pytest.raises(ValueError, match="math domain error"):
        run_in_pool(jobs, 1, kept.append)
    assert kept == []  # the failing job was the only one handed over: no result was kept
    assert not any(p.exists() for p in made)  # one worker: nothing else was handed over before the failure


# ------------------------------------------------------------------ the report's maps
def test_report_movers_are_where_the_simulation_put_them():
    """The report re-creates a dynamic episode's movers from its seed and the robot's recorded
    track; against the simulation itself (the scene's movers after 600 steps of PID + A* that
    make forklifts and workers yield to the robot) the poses agree to the bit, from every pose
    and from the row's one-in-three path alike."""
    import gymnasium as gym

    from bulletnav.benchmark.report import robot_track
    from bulletnav.control.navigator import Navigator, NavigatorConfig
    from bulletnav.sim.movers import kinematic_poses

    env = gym.make("bulletnav/WarehouseDynamic-v0")
    try:
        obs, info = env.reset(seed=4000000)
        scene = env.unwrapped.scene
        nav = Navigator(scene, NavigatorConfig(planner="astar"))
        nav.reset(info)
        specs = scene.mover_specs
        assert len(specs) == len(scene.movers) >= 2
        xy, yields = [scene.pose[:2]], 0
        for _ in range(600):
            obs, _, terminated, truncated, info = env.step(nav.act(obs, info))
            yields += sum(m.yielding for m in scene.movers)
            xy.append(scene.pose[:2])
            if terminated or truncated:
                break
        assert yields > 0  # the movers' motion depends on where the robot was
        steps = len(xy) - 1
        truth = [m.pose for m in scene.movers]
        full = kinematic_poses(specs, xy[:steps], scene.control_dt, scene.geometry.radius)
        assert [track[-1] for track in full] == truth
        row = {"steps": steps, "path": [[round(x, 3), round(y, 3)] for x, y in xy[:: max(1, len(xy) // 200)]]}
        assert len(row["path"]) < len(xy) / 2
        from_row = kinematic_poses(specs, robot_track(row), scene.control_dt, scene.geometry.radius)
        assert max(math.dist(track[-1][:2], pose[:2]) for track, pose in zip(from_row, truth)) < 0.01
    finally:
        env.close()


def _legend_colours(legend: str) -> dict[str, set[str]]:
    """Legend entry -> the colours (``#rrggbb``, lower case) its sample draws with."""
    import re

    out = {}
    for key, body in re.findall(r"<li data-key=(\w+)>(.*?)</li>", legend):
        out[key] = {c.lower() for c in re.findall(r"(?:stroke|fill)='(#[0-9A-Fa-f]{6})'", body)}
    return out


def test_report_maps_draw_in_the_legend_colours_and_movers_in_dynamic_worlds():
    """A dynamic world's map, drawn as the report draws it: every path outcome, the goal, the
    racks, each forklift and worker are drawn in the colour the legend's sample shows and names,
    the three outcomes and the goal, racks and movers in distinct colours; movers sit where
    :func:`kinematic_poses` puts them at the episode's end."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.colors import to_hex
    from matplotlib.figure import Figure

    from bulletnav.benchmark import report
    from bulletnav.sim.movers import kinematic_poses
    from bulletnav.viz.plots import draw_layout

    scenes = report.Scenes()
    try:
        scene = scenes.get({"name": "dynamic", "env": "bulletnav/WarehouseDynamic-v0", "kwargs": {}}, 4000001)
    finally:
        scenes.close()
    assert scene.mover_specs
    sx, sy, _ = scene.start
    path = [[sx + 0.01 * i, sy] for i in range(51)]  # 50 steps east
    legend = _legend_colours(report.legend_html(movers=True))
    assert set(legend) >= {"success", "collision", "timeout", "goal", "obstacle", "forklift", "worker", "start"}
    html_legend = report.legend_html(movers=True)
    for key, name in report.COLOUR_NAMES.items():
        if key in legend:
            assert report.PALETTE[key].lower() in legend[key], key
            assert name in html_legend
    drawn = {}
    for outcome in ("success", "collision", "timeout"):
        row = {"success": int(outcome == "success"), "collision": int(outcome == "collision"), "steps": 50, "path": path}
        fig = Figure()
        ax = fig.add_subplot()
        report.draw_episode(ax, scene, row, draw_layout)
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)") and len(ax.get_xticks()) > 1  # to scale, in metres
        lines = {line.get_gid(): line for line in ax.get_lines()}
        drawn[outcome] = to_hex(lines[f"path_{outcome}"].get_color())
        patches = ax.patches
        goal = [p for p in patches if p.get_gid() == "goal"]
        drawn["goal"] = {to_hex(p.get_facecolor() if p.get_fill() else p.get_edgecolor()) for p in goal}
        # the zone's fill as pale as the legend's sample of it
        assert [p.get_alpha() for p in goal if p.get_fill()] == [report.GOAL_ALPHA]
        assert f"fill-opacity='{report.GOAL_ALPHA}'" in report.legend_html(movers=False)
        movers = [p for p in patches if p.get_gid() in ("forklift", "worker")]
        assert len(movers) == len(scene.mover_specs)
        for kind in ("forklift", "worker"):
            drawn[kind] = {to_hex(p.get_facecolor()) for p in movers if p.get_gid() == kind}
        obstacles = {to_hex(p.get_facecolor()) for p in patches if p.get_gid() is None and p.get_zorder() == 1}
        drawn["obstacle"] = obstacles
    for outcome in ("success", "collision", "timeout"):
        assert drawn[outcome] in legend[outcome], outcome
    assert drawn["goal"] == {report.PALETTE["goal"].lower()} and drawn["goal"] <= legend["goal"]
    assert drawn["obstacle"] == {report.PALETTE["obstacle"].lower()} and drawn["obstacle"] <= legend["obstacle"]
    kinds = {s.kind for s in scene.mover_specs}
    for kind in kinds:
        assert drawn[kind] == {report.PALETTE[kind].lower()} and drawn[kind] <= legend[kind]
    distinct = [report.PALETTE[k] for k in ("success", "collision", "timeout", "goal", "obstacle", "forklift", "worker")]
    assert len(set(distinct)) == len(distinct)
    # the movers' footprints are centred where the kinematics put them after the 50 steps
    ends = [track[-1] for track in kinematic_poses(scene.mover_specs, report.robot_track(row), scene.control_dt,
                                                   scene.robot_radius)]
    centres = [np.mean(p.get_xy()[:4], axis=0) if p.get_gid() == "forklift" else np.array(p.center) for p in movers]
    assert max(math.dist(c, e[:2]) for c, e in zip(centres, ends)) < 1e-9


def test_report_replay_commands_break_only_between_arguments():
    """A replay command as the report shows it: one span per shell argument, quoted arguments
    with blanks kept whole, the text (what a copy gives) the command itself on one line."""
    import html
    import re
    import shlex

    from bulletnav.benchmark.report import command_html, shell_words

    command = shlex.join(["python", "-c", "import json; print(json.dumps(1))", "--world", "a b/it's.yaml", "--seed", "7"])
    words = shell_words(command)
    assert [shlex.split(w)[0] for w in words] == ["python", "-c", "import json; print(json.dumps(1))", "--world",
                                                    "a b/it's.yaml", "--seed", "7"]
    assert " ".join(words) == command
    code = command_html(command)
    spans = re.findall(r"<span>(.*?)</span>", code)
    assert len(spans) == 7
    text = html.unescape(re.sub(r"<[^>]+>", "", code))
    assert text == command and "\n" not in text
