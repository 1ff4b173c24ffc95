"""``bulletnav benchmark barn``: suites that name BARN worlds, BARN's summary of their rows beside
BARN's DWA rows, the per-world plot, and barn_score as BARN's score."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np
import pytest

from bulletnav.barn import data, metric
from bulletnav.barn.metric import OutRow
from bulletnav.benchmark.barn import (
    DWA_NAME,
    DWA_NOTE,
    barn_sections,
    out_rows,
    overall,
    per_world,
    plot_metric,
    plot_success_pair,
)
from bulletnav.benchmark.suite import SuiteError, load_suite, parse_suite, replay_command


class Straight:
    """Full speed ahead, no turning: a policy whose BARN outcome is known by the world (a
    straight line from the start passes world 93 and hits a cylinder of world 0)."""

    def __init__(self, scene, speed: float = 1.0) -> None:
        self.speed = speed

    def reset(self, info) -> None:
        pass

    def act(self, obs, info) -> np.ndarray:
        return np.array([self.speed, 0.0], dtype=np.float32)


def _suite(world: dict, where: str = "b.yaml", **over):
    raw = {"name": "b", "episodes": 3, "seed": 5, "worlds": [world], "controllers": [{"type": "navigator"}], **over}
    return parse_suite(raw, where)


# ------------------------------------------------------------------ suites
def test_barn_worlds_expand_to_one_world_per_index_with_its_runs():
    suite = _suite({"env": "bulletnav/BARN-v0", "barn_worlds": "test", "episodes": 10})
    assert [w.barn_world for w in suite.worlds] == list(range(0, 300, 6))  # report_test.py's 50 test worlds
    assert suite.worlds[1].name == "barn-006" and suite.worlds[1].kwargs == {"world_idx": 6}
    assert {w.group for w in suite.worlds} == {"barn"} and suite.total == 50 * 10
    listed = _suite({"name": "mine", "env": "bulletnav/BARN-v0", "barn_worlds": [93, 0]})
    assert [(w.name, w.barn_world, listed.episodes_of(w)) for w in listed.worlds] == [("mine-093", 93, 3), ("mine-000", 0, 3)]
    train = _suite({"env": "bulletnav/BARN-v0", "barn_worlds": "train"})
    assert len(train.worlds) == 250 and not {w.barn_world for w in train.worlds} & set(range(0, 300, 6))
    command = replay_command(listed, listed.worlds[0], listed.controllers[0], 7, Path("/x"))
    assert command == ("bulletnav navigate --planner astar --env bulletnav/BARN-v0 --world-idx 93 --seed 7 --episodes 1 "
                       "--video episode.mp4")
    shipped = load_suite("barn")
    assert shipped.total == 50 * 10 * 9 and shipped.controllers[5].model_path("bulletnav/BARN-v0", Path("/r")) == \
        Path("/r/models/ppo_barn.zip")
    assert [c.type for c in shipped.controllers] == ["navigator"] * 2 + ["dwa"] * 3 + ["model", "navigator", "navigator", "model"]
    assert all(c.env.get("min_speed") == -0.5 for c in shipped.controllers if c.type != "model")
    assert load_suite("barn-quick").worlds[0].group == "barn"


@pytest.mark.parametrize("world, field", [
    ({"env": "bulletnav/Warehouse-v0", "barn_worlds": "test"}, "'worlds[0].barn_worlds' is for env bulletnav/BARN-v0"),
    ({"env": "bulletnav/BARN-v0", "barn_worlds": "tests"}, "'worlds[0].barn_worlds' must be one of ['all', 'test', 'train']"),
    ({"env": "bulletnav/BARN-v0", "barn_worlds": []}, "'worlds[0].barn_worlds' must be one of"),
    ({"env": "bulletnav/BARN-v0", "barn_worlds": [0, 300]}, "'worlds[0].barn_worlds[1]' must be an integer from 0 to 299"),
    ({"env": "bulletnav/BARN-v0", "barn_worlds": [6, True]}, "'worlds[0].barn_worlds[1]'"),
    ({"env": "bulletnav/BARN-v0", "barn_worlds": [6, 12, 6]}, "names BARN world(s) [6] more than once"),
    ({"env": "bulletnav/BARN-v0", "barn_worlds": [6], "kwargs": {"world_idx": 6}}, "give one"),
    ({"env": "bulletnav/Warehouse-v0", "kwargs": {"world_idx": 6}}, "'worlds[0].kwargs.world_idx' is for bulletnav/BARN-v0"),
    ({"env": "bulletnav/BARN-v0", "kwargs": {"world_idx": -1}}, "'worlds[0].kwargs.world_idx' must be an integer from 0"),
])
def test_bad_barn_world_selections_name_file_field_and_value(world, field):
    with pytest.raises(SuiteError, match="b.yaml") as err:
        _suite(world)
    assert field in str(err.value) and "\n" not in str(err.value)


# ------------------------------------------------------------------ BARN's summary
def _report_t_opt() -> dict[int, float]:
    return {i: metric.optimal_time(data.load_world(i).path_cells, metric.REPORT_START) for i in metric.TEST_WORLDS}


def test_dwa_row_is_report_test_pys_summary_of_barns_rows():
    rows = data.dwa_rows()
    summary = metric.summarise(rows, _report_t_opt())
    figures = overall(rows)
    assert (figures["success"]["mean"], figures["collision"]["mean"], figures["timeout"]["mean"],
            figures["time_s"]["mean"], figures["metric"]["mean"]) == (summary.success, summary.collision, summary.timeout,
                                                                      summary.time_s, summary.metric)
    # BARN's report_test.py (commit bf5a226) on res/dwa_out.txt, run by hand (tests/test_barn_metric.py)
    line = "Avg Time: 34.0925, Avg Metric: 0.1592, Avg Success: 0.8500, Avg Collision: 0.0560, Avg Timeout: 0.0940"
    assert figures["line"] == line and figures["worlds"] == 50 and figures["runs"] == 500
    for f in ("success", "collision", "timeout", "time_s", "metric"):
        assert figures[f]["lo"] < figures[f]["mean"] < figures[f]["hi"]
    worlds = [{"name": f"barn-{i:03d}", "group": "barn", "barn_world": i, "episodes": 10} for i in metric.TEST_WORLDS]
    (section,) = barn_sections(worlds, ["PID + A*"], [])
    dwa = section["controllers"][1]
    assert (dwa["name"], dwa["source"], dwa["overall"]["line"]) == (DWA_NAME, "published", line)
    assert "Gazebo" in dwa["note"] and "not run here" in dwa["note"] and DWA_NOTE
    assert section["controllers"][0]["overall"]["line"] is None  # no rows yet: nothing made up
    assert dwa["per_world"][0]["world"] == 0 and dwa["per_world"][0]["runs"] == 10


def _report_test_line(text: str) -> str:
    """BARN's report_test.py (commit bf5a226), transcribed: t_opt from (-2, 3) along the world's
    path to (-2, 13) over 2 m/s, each run's metric success x t_opt / clip(t, 2 t_opt, 8 t_opt),
    then means over worlds of per-world means (the time over successful runs)."""
    def gazebo(x, y):
        return x * 0.15 + (-0.075 - 30 * 0.15), y * 0.15 + (0.075 + 5)

    runs: dict[int, list[tuple[bool, bool, bool, float, float]]] = {}
    for line in text.splitlines():
        w, ok, hit, out, t = line.split()[:5]
        cells = data.load_world(int(w)).path_cells
        pts = [(-2.0, 3.0), *(gazebo(float(a), float(b)) for a, b in cells), (-2.0, 13.0)]
        t_opt = sum(math.dist(p, q) for p, q in zip(pts, pts[1:])) / 2
        m = int(ok) * t_opt / min(max(float(t), 2 * t_opt), 8 * t_opt)
        runs.setdefault(int(w), []).append((ok == "1", hit == "1", out == "1", float(t), m))
    times = [np.mean([r[3] for r in rs if r[0]]) for rs in runs.values() if any(r[0] for r in rs)]

    def avg(k):
        return np.mean([np.mean([r[k] for r in rs]) for rs in runs.values()])

    return (f"Avg Time: {np.mean(times):.4f}, Avg Metric: {avg(4):.4f}, Avg Success: {avg(0):.4f}, "
            f"Avg Collision: {avg(1):.4f}, Avg Timeout: {avg(2):.4f}")


def test_published_anchors_lics_ki_rows_scored_as_report_test_py_and_inventec_as_reported():
    """LiCS-KI's 500 published rows, scored by report_test.py's formula transcribed here, give the
    issue's 98.0 % / 1.8 % / 0.4889 / 7.7 s; the section's LiCS-KI entry says the same line. Inventec
    published only its summary (4 t_opt clip): the entry carries it as published, without intervals."""
    lics = next(p for p in data.PUBLISHED if p.name.startswith("LiCS-KI"))
    line = _report_test_line(lics.rows_file.read_text())
    assert line == "Avg Time: 7.7362, Avg Metric: 0.4889, Avg Success: 0.9800, Avg Collision: 0.0180, Avg Timeout: 0.0020"
    worlds = [{"name": f"barn-{i:03d}", "group": "barn", "barn_world": i, "episodes": 10} for i in metric.TEST_WORLDS]
    (section,) = barn_sections(worlds, ["PID + A*"], [])
    names = [e["name"] for e in section["controllers"]]
    assert names == ["PID + A*", DWA_NAME, "LiCS-KI 2024 (published rows)", "Inventec 2023 (as reported)"]
    entry = section["controllers"][2]
    assert entry["overall"]["line"] == line and entry["all_line"] == line and entry["clip"] == 2.0
    inventec = section["controllers"][3]
    assert inventec["clip"] == 4.0 and inventec["per_world"] == []
    assert (inventec["overall"]["success"]["mean"], inventec["overall"]["metric"]["mean"]) == (0.99, 0.2445)
    assert inventec["overall"]["success"]["lo"] is None
    # on a part of the test worlds only the rows' entries come (a summary of all 50 cannot be split)
    (part,) = barn_sections(worlds[:5], ["PID + A*"], [])
    assert [e["name"] for e in part["controllers"]] == names[:3]


def test_agreement_of_a_dwa_here_with_barns_rows_by_hand():
    """A 'DWA' whose rows are BARN's own, but with two worlds' runs all failed: success 4 points
    lower (2 worlds x 100 % / 50), the same times elsewhere, and within 0.3 in 48 of 50 worlds
    unless those two worlds were already under 0.3 in BARN's rows."""
    rows = data.dwa_rows()
    changed = {0, 6}
    mine = [{"controller": "DWA", "world": f"barn-{r.world:03d}", "world_idx": r.world,
             "success": r.success and r.world not in changed, "collision": r.collided,
             "timeout": r.timeout or (r.world in changed and not r.collided), "barn_time_s": r.time_s} for r in rows]
    worlds = [{"name": f"barn-{i:03d}", "group": "barn", "barn_world": i, "episodes": 10} for i in metric.TEST_WORLDS]
    (section,) = barn_sections(worlds, [{"name": "DWA", "type": "dwa"}], mine)
    a = section["controllers"][0]["agreement"]
    by_world = {w: [r for r in rows if r.world == w] for w in changed}
    lost = sum(np.mean([r.success for r in by_world[w]]) for w in changed) / 50
    assert a["success_points"] == pytest.approx(-100 * lost)
    apart = sorted(w for w in changed if np.mean([r.success for r in by_world[w]]) > 0.3)
    assert a["worlds_apart"] == apart and a["worlds_within"] == 50 - len(apart) and a["worlds_needed"] == 35
    assert a["agrees"] == (abs(a["success_points"]) <= 10 and abs(a["time_ratio"] - 1) <= 0.3)
    # a navigator gets no agreement figures: it is not the same planner
    (section,) = barn_sections(worlds, [{"name": "DWA", "type": "navigator"}], mine)
    assert "agreement" not in section["controllers"][0]


def test_per_world_and_overall_figures_by_hand():
    t_opt = {3: 10.0, 7: 20.0}
    rows = [OutRow(3, True, False, False, 15.0),   # clipped to 2 t_opt = 20 s: 10 / 20 = 0.5
            OutRow(3, True, False, False, 50.0),   # 10 / 50 = 0.2
            OutRow(3, False, True, False, 4.0),    # a collision: 0
            OutRow(3, False, False, True, 100.0),  # a time-out: 0
            OutRow(7, True, False, False, 80.0),   # 20 / 80 = 0.25
            OutRow(7, True, False, False, 80.0)]
    w3, w7 = per_world(rows, t_opt)
    assert (w3["world"], w3["runs"], w7["runs"]) == (3, 4, 2)
    assert w3["success"]["mean"] == 0.5 and w3["collision"]["mean"] == 0.25 and w3["timeout"]["mean"] == 0.25
    assert w3["time_s"]["mean"] == pytest.approx(32.5) and w3["time_s"]["n"] == 2  # the successful runs' times
    assert w3["metric"]["mean"] == pytest.approx((0.5 + 0.2) / 4)
    assert w7["metric"] == {"mean": 0.25, "lo": 0.25, "hi": 0.25, "n": 2}  # two equal runs: no spread
    o = overall(rows, t_opt)
    # report_test.py: means over the two worlds of their means, not over the six runs
    assert o["success"]["mean"] == pytest.approx((0.5 + 1.0) / 2)
    assert o["collision"]["mean"] == pytest.approx(0.125) and o["timeout"]["mean"] == pytest.approx(0.125)
    assert o["time_s"]["mean"] == pytest.approx((32.5 + 80.0) / 2)
    assert o["metric"]["mean"] == pytest.approx((0.175 + 0.25) / 2)
    assert o["line"] == "Avg Time: 56.2500, Avg Metric: 0.2125, Avg Success: 0.7500, Avg Collision: 0.1250, Avg Timeout: 0.1250"
    # the interval resamples runs within each world: world 7 never varies, world 3's success rate runs 0-1
    assert o["success"]["lo"] >= (0.0 + 1.0) / 2 and o["success"]["hi"] <= (1.0 + 1.0) / 2
    assert o["success"]["lo"] < o["success"]["mean"] < o["success"]["hi"]


def test_the_plot_is_written(tmp_path):
    from PIL import Image

    rows = [OutRow(0, True, False, False, 30.0), OutRow(6, False, True, False, 5.0)]
    worlds = [{"name": f"b-{i}", "group": "b", "barn_world": i, "episodes": 1} for i in (0, 6)]
    bench = [{"world": f"b-{r.world}", "controller": "mine", "world_idx": r.world, "success": int(r.success),
              "collision": int(r.collided), "timeout": int(r.timeout), "barn_time_s": r.time_s} for r in rows]
    (section,) = barn_sections(worlds, ["mine"], bench)
    assert [p["world"] for p in section["controllers"][1]["per_world"]] == [0, 6]  # DWA's rows of the same worlds
    path = plot_metric(section, tmp_path / "plot.png")
    with Image.open(path) as image:
        assert image.format == "PNG" and image.width > 600 and image.height > 300
    path = plot_success_pair(section, "mine", DWA_NAME, tmp_path / "pair.png")
    with Image.open(path) as image:
        assert image.format == "PNG" and image.width > 600 and image.height > 300


def test_the_barn_tab_shows_each_dwa_runs_success_beside_barns_rows(tmp_path):
    """A ``dwa`` controller's entry carries its agreement with BARN's DWA rows; the BARN tab shows
    the per-world success plot of the two beside the agreement table, linked to the PNG written
    beside the page; a controller of another type gets no such plot."""
    from bulletnav.benchmark.report import _barn_panel

    rows = [OutRow(0, True, False, False, 30.0), OutRow(6, False, True, False, 5.0)]
    worlds = [{"name": f"b-{i}", "group": "b", "barn_world": i, "episodes": 1} for i in (0, 6)]
    bench = [{"world": f"b-{r.world}", "controller": c, "world_idx": r.world, "success": int(r.success),
              "collision": int(r.collided), "timeout": int(r.timeout), "barn_time_s": r.time_s}
             for r in rows for c in ("mine", "other")]
    (section,) = barn_sections(worlds, [{"name": "mine", "type": "dwa"}, {"name": "other", "type": "navigator"}], bench)
    assert "agreement" in section["controllers"][0] and "agreement" not in section["controllers"][1]
    pair = plot_success_pair(section, "mine", DWA_NAME, tmp_path / "barn_success_b_0.png")
    page = "\n".join(_barn_panel(0, section, bench, None, [pair]))
    assert "href='barn_success_b_0.png'" in page and "data:image/png;base64," in page
    assert "DWA here against DWA in Gazebo" in page


def test_barn_score_is_barns_score_with_the_2_t_opt_clip():
    from bulletnav.benchmark.metrics import METRICS, EpisodeTrace, episode_metrics
    from bulletnav.evaluation import EpisodeResult

    class View:
        pose, movers = (0.0, 0.0, 0.0), ()

    trace = EpisodeTrace(0.1, top_speed=0.5)
    view = View()
    for k in range(61):  # 6 s for a 1 m shortest path at 0.5 m/s: t_opt = 2 s, t = 3 t_opt (between the two clips)
        view.pose = (k / 60, 0.0, 0.0)
        trace.record(view, {})
    result = EpisodeResult(episode=1, seed=0, initial_distance=1.0, shortest_path=1.0, steps=60, reward=0.0,
                           final_distance=0.1, path_length=1.0, success=True, collision=False, spl=1.0, sim_time=6.0,
                           wall_time=0.0)
    row = episode_metrics(result, trace, accel=2.5)
    assert row["barn_score"] == pytest.approx(2.0 / 6.0)  # BARN's 2 t_opt clip leaves 6 s alone (4 t_opt gave 0.25)
    assert row["barn_score"] == metric.barn_metric(True, 6.0, 2.0)
    assert "clip(t, 2 t_opt, 8 t_opt)" in METRICS["barn_score"] and "bulletnav.barn.metric" in METRICS["barn_score"]
    assert not {"world_idx", "barn_time_s", "barn_metric"} & set(row)  # not a BARN episode: no BARN fields


# ------------------------------------------------------------------ a run
@pytest.mark.slow
def test_a_barn_run_scores_its_rows_as_barn_and_reports_them(tmp_path, capsys):
    """Two real BARN episodes (the straight policy on world 93, a success, and world 0, a
    collision): the rows carry BARN's clock and score, the group's figures are report_test.py's
    of those rows, the report shows DWA's note and links the plot it wrote. A second controller
    left out with ``controllers=`` has no rows (and no made-up figures) until a resumed run."""
    from bulletnav.benchmark.report import write_report
    from bulletnav.benchmark.runner import run_suite
    from bulletnav.errors import BulletnavError

    raw = {"name": "b", "episodes": 1, "seed": 11, "worlds": [{"env": "bulletnav/BARN-v0", "barn_worlds": [93, 0]}],
           "controllers": [{"name": "straight", "type": "policy", "class": f"{__name__}:Straight"},
                           {"name": "slow", "type": "policy", "class": f"{__name__}:Straight", "kwargs": {"speed": 0.5}}]}
    suite = parse_suite(raw, str(tmp_path / "b.yaml"), "0" * 64, trust_code=True)
    with pytest.raises(BulletnavError, match=r"--controllers: \['PPO'\] not in .*b.yaml; its controllers: \['straight', 'slow'\]"):
        run_suite(suite, tmp_path / "out", workers=1, controllers=["PPO"])
    results = run_suite(suite, tmp_path / "out", workers=1, controllers=["straight"])
    ok, hit = results["episodes"]
    assert results["barn"][0]["controllers"][1]["overall"]["line"] is None  # "slow" not run yet
    assert [r["controller"] for r in run_suite(suite, tmp_path / "out", workers=1, resume=True)["episodes"]] == \
        ["straight", "slow", "straight", "slow"]
    assert (ok["world_idx"], ok["success"], hit["world_idx"], hit["collision"]) == (93, 1, 0, 1)
    t_opt = data.load_world(93).t_opt  # run.py's start, as the env scores
    assert ok["barn_metric"] == metric.barn_metric(True, ok["barn_time_s"], t_opt) > 0 and hit["barn_metric"] == 0.0
    assert 0 < ok["barn_time_s"] < ok["time_s"]  # BARN's clock starts at the first 0.1 m
    (section,) = results["barn"]
    mine = section["controllers"][0]["overall"]
    report_t_opt = {i: metric.optimal_time(data.load_world(i).path_cells, metric.REPORT_START) for i in (0, 93)}
    assert mine["line"] == metric.summarise(out_rows([ok, hit]), report_t_opt).line()
    assert mine["success"]["mean"] == 0.5 and mine["collision"]["mean"] == 0.5
    assert section["dwa_worlds"] == [0]  # DWA ran on the test worlds only
    written = json.loads((tmp_path / "out" / "results.json").read_text())
    assert written["suite"]["worlds"][0]["barn_world"] == 93 and written["barn"][0]["worlds"] == [93, 0]
    page = write_report(written, tmp_path / "out" / "report.html").read_text()
    assert DWA_NOTE in page and "href='barn_metric_barn.png'" in page and (tmp_path / "out" / "barn_metric_barn.png").is_file()
    # the two t_opts are each labelled where their figure is shown: the rows' (run.py's start) and the tables' (report_test.py's)
    assert "report_test.py's start (-2, 3)" in section["metric"] and "run.py's start (-2.25, 3)" in section["metric"]
    assert html.escape(section["metric"]) in page
    from bulletnav.cli.benchmark import _print_barn

    _print_barn(section)
    assert f"BARN metric: {section['metric']}" in capsys.readouterr().out


def test_a_worker_keeps_at_most_max_cells_envs_open(monkeypatch):
    """A BARN suite has 300 cells; a worker closes its least recently used env beyond MAX_CELLS
    (16) instead of holding 300 PyBullet worlds."""
    from bulletnav.benchmark import runner

    made, closed = [], []

    class Env:
        def __init__(self, key):
            self.key = key
            made.append(key)

        def close(self):
            closed.append(self.key)

    monkeypatch.setattr(runner, "make_cell", lambda world, controller, root, trust: (Env((world.barn_world, controller.name)), None))
    cells = runner._Cells(load_suite("barn"), Path("."))
    for w in range(3):  # 3 worlds x 6 controllers: 18 cells
        for c in range(6):
            cells.get(w, c)
    assert runner.MAX_CELLS == 16 and len(cells.cells) == 16
    assert closed == [(0, "PID + A*"), (0, "PID + RRT")]  # the two first made, least recently used
    cells.get(0, 2)  # open: used again, not made again
    cells.get(0, 0)  # closed: made again, closing the least recently used (0, 3)
    assert made.count((0, "DWA (BARN's parameters)")) == 1 and made.count((0, "PID + A*")) == 2
    assert closed[-1] == (0, "DWA (BARN's parameters, biases per cell)")
    cells.close()
    assert len(closed) == 3 + 16
