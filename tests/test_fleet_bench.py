"""bench fleet: every controller timed at every size, ratios against N = 1 (no timing asserted)."""

from __future__ import annotations

import math

from bulletnav.bench.fleet_bench import bench_fleet


def test_bench_fleet_rows_and_ratios():
    result = bench_fleet(sizes=(1, 2), steps=4, warmup=2, seed=3)
    rows = result["sizes"]
    assert [(r["controller"], r["robots"]) for r in rows] == [
        ("independent", 1), ("independent", 2), ("coordinated", 1), ("coordinated", 2), ("policy", 1), ("policy", 2)]
    for r in rows:
        assert r["step_ms"] > 0 and math.isclose(r["step_ms"], r["env_ms"] + r["controller_ms"], rel_tol=1e-9)
        assert math.isclose(r["per_robot_ms"], r["step_ms"] / r["robots"], rel_tol=1e-12)
        if r["robots"] == 1:
            assert r["per_robot_ratio"] == 1.0 and r["env_per_robot_ratio"] == 1.0
