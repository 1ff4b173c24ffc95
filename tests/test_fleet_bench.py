"""bench fleet: every controller timed at every size, ratios against N = 1 (no timing asserted).

The benchmark runs its real envs and controllers on a fake clock that advances by hand-set
costs: the env's step costs 4 + 2 N ms, the controllers' act 1 x N ms (independent), 3 + N ms
(coordinated) and 2 ms (policy, one batch for all robots). Every figure of the table is then
known by hand. (At 052a810 the test checked only sums the benchmark computes itself.)"""

from __future__ import annotations

import types

import pytest

from bulletnav.bench import fleet_bench

ENV_MS = {1: 6.0, 2: 8.0}  # 4 + 2 N
CONTROLLER_MS = {("independent", 1): 1.0, ("independent", 2): 2.0, ("coordinated", 1): 4.0, ("coordinated", 2): 5.0,
                 ("policy", 1): 2.0, ("policy", 2): 2.0}
# (controller, N): step ms, per-robot ms, per-robot ratio to N = 1, env per-robot ratio to N = 1
EXPECTED = {
    ("independent", 1): (7.0, 7.0, 1.0, 1.0), ("independent", 2): (10.0, 5.0, 5 / 7, 4 / 6),
    ("coordinated", 1): (10.0, 10.0, 1.0, 1.0), ("coordinated", 2): (13.0, 6.5, 0.65, 4 / 6),
    ("policy", 1): (8.0, 8.0, 1.0, 1.0), ("policy", 2): (10.0, 5.0, 0.625, 4 / 6),
}


def test_bench_fleet_rows_and_ratios_on_a_fake_clock(monkeypatch):
    now = [0.0]

    class CostedEnv(fleet_bench.FleetEnv):
        def step(self, actions):
            now[0] += (4.0 + 2.0 * self.fleet_config.num_robots) * 1e-3
            return super().step(actions)

    real_make = fleet_bench.make_controller

    def costed_controller(name, env, model=None):
        controller = real_make(name, env, model=model)
        cost = CONTROLLER_MS[(name, env.fleet_config.num_robots)] * 1e-3
        act = controller.act

        def costed_act(obs, infos):
            now[0] += cost
            return act(obs, infos)

        controller.act = costed_act
        return controller

    monkeypatch.setattr(fleet_bench, "time", types.SimpleNamespace(perf_counter=lambda: now[0]))
    monkeypatch.setattr(fleet_bench, "FleetEnv", CostedEnv)
    monkeypatch.setattr(fleet_bench, "make_controller", costed_controller)
    result = fleet_bench.bench_fleet(sizes=(1, 2), steps=4, warmup=2, seed=3)
    rows = result["sizes"]
    assert [(r["controller"], r["robots"]) for r in rows] == list(EXPECTED)
    for r in rows:
        key = (r["controller"], r["robots"])
        step, per_robot, ratio, env_ratio = EXPECTED[key]
        assert r["env_ms"] == pytest.approx(ENV_MS[r["robots"]]) and r["controller_ms"] == pytest.approx(CONTROLLER_MS[key])
        assert r["step_ms"] == pytest.approx(step) and r["step_ms_median"] == pytest.approx(step)
        assert r["per_robot_ms"] == pytest.approx(per_robot)
        assert r["env_per_robot_ms"] == pytest.approx(ENV_MS[r["robots"]] / r["robots"])
        assert r["per_robot_ratio"] == pytest.approx(ratio) and r["env_per_robot_ratio"] == pytest.approx(env_ratio)
        assert r["control_hz"] == 24 and r["realtime_factor"] == pytest.approx((1000 / 24) / step)
    assert (result["steps"], result["warmup"], result["seed"]) == (4, 2, 3)
