"""The fleet comparison: every entry on the same episodes, any worker count, resumable."""

from __future__ import annotations

import json
from dataclasses import asdict

import pytest

from bulletnav.errors import BulletnavError, ConfigError
from bulletnav.fleet.compare import Entry, build_comparison, parse_entries, plan_chunks, run_comparison

ENV = {"duration_s": 4.0, "dynamic": True}


def _check_cells_from_rows(results, duration_s: float) -> None:
    """Each row's throughput by its formula (errands per simulated hour), and each cell
    recomputed here from its rows: errands and collisions summed, throughput averaged, its
    standard error by the statistics module (sample standard deviation / sqrt(n)), the
    smallest separation the minimum."""
    import math
    import statistics

    for row in results["episodes"]:
        assert row["throughput_per_hour"] == pytest.approx(row["errands"] * 3600.0 / duration_s, rel=1e-12)
        assert row["seed"] == results["settings"]["seed"] + row["episode"]
    for cell in results["cells"]:
        mine = [r for r in results["episodes"] if r["robots"] == cell["robots"] and r["entry"] == cell["entry"]]
        assert cell["episodes"] == len(mine)
        assert cell["errands"] == sum(r["errands"] for r in mine)
        assert cell["collisions_robot_robot"] == sum(r["collisions_robot_robot"] for r in mine)
        tput = [r["throughput_per_hour"] for r in mine]
        assert cell["throughput_per_hour"] == pytest.approx(statistics.fmean(tput), rel=1e-12)
        assert cell["throughput_se"] == pytest.approx(statistics.stdev(tput) / math.sqrt(len(tput)), rel=1e-9, abs=1e-12)
        assert cell["min_separation_m"] == pytest.approx(min(r["min_separation_m"] for r in mine), rel=1e-12)


def _rows(results):
    """Rows without their wall times, as JSON text (NaN equals NaN there)."""
    return [json.dumps({k: v for k, v in r.items() if k != "wall_s"}) for r in results["episodes"]]


def test_parse_entries_names_and_errors():
    entries = parse_entries(["independent", "policy=models/ppo_dynamic.zip"], "both")
    assert [e.label for e in entries] == ["independent", "independent + shield", "ppo_dynamic", "ppo_dynamic + shield"]
    assert entries[3] == Entry("ppo_dynamic + shield", "policy", "models/ppo_dynamic.zip", True)
    with pytest.raises(ConfigError, match="policy=PATH"):
        parse_entries(["policy"])
    with pytest.raises(ConfigError, match="only the policy"):
        parse_entries(["coordinated=x.zip"])
    with pytest.raises(ConfigError, match="must be one of"):
        parse_entries(["greedy"])
    with pytest.raises(ConfigError, match="twice"):
        parse_entries(["independent", "independent"])
    with pytest.raises(ConfigError, match="--shield"):
        parse_entries(["independent"], "sometimes")


@pytest.mark.slow
def test_every_entry_meets_the_same_episodes_and_workers_do_not_change_rows(tmp_path):
    entries = parse_entries(["independent", "coordinated", "policy=models/ppo_dynamic.zip"], "off")
    one = run_comparison(tmp_path / "one", entries, robots=(2,), episodes=2, seed=31, env_kwargs=ENV, workers=1)
    two = run_comparison(tmp_path / "two", entries, robots=(2,), episodes=2, seed=31, env_kwargs=ENV, workers=2)
    assert _rows(one) == _rows(two)
    for k in range(2):  # the policy's env (floor-plan guidance, normalised actions) holds the same episode
        prints = {r["fingerprint"] for r in one["episodes"] if r["episode"] == k}
        assert len(prints) == 1
    assert [c["entry"] for c in one["cells"]] == ["independent", "coordinated", "ppo_dynamic"]
    assert all(c["episodes"] == 2 for c in one["cells"])
    md = (tmp_path / "one" / "comparison.md").read_text()
    assert "## 2 robots" in md and "| coordinated |" in md
    saved = json.loads((tmp_path / "one" / "comparison.json").read_text())
    assert saved["settings"]["seed"] == 31 and len(saved["episodes"]) == 6
    _check_cells_from_rows(one, ENV["duration_s"])


@pytest.mark.slow
def test_an_interrupted_run_resumes_to_the_same_rows(tmp_path):
    entries = parse_entries(["independent"], "both")
    full = run_comparison(tmp_path / "full", entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV)
    out = tmp_path / "cut"
    run_comparison(out, entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV)
    lines = (out / "episodes.jsonl").read_text().splitlines()
    (out / "episodes.jsonl").write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])  # a torn third row
    with pytest.raises(BulletnavError, match="--resume"):
        run_comparison(out, entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV)
    with pytest.raises(BulletnavError, match="other settings"):
        run_comparison(out, entries, robots=(2,), episodes=3, seed=8, env_kwargs=ENV, resume=True)
    resumed = run_comparison(out, entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV, resume=True)
    assert _rows(resumed) == _rows(full)
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 6
    # by hand: 2 entries x 3 episodes, seeds 7-9, each once; the summary recomputed from the rows
    assert sorted((r["entry"], r["episode"], r["seed"]) for r in resumed["episodes"]) == \
           [(label, k, 7 + k) for label in ("independent", "independent + shield") for k in range(3)]
    _check_cells_from_rows(resumed, ENV["duration_s"])
    # an entry added later runs alone; the earlier entries' rows are kept, not rerun
    more = run_comparison(out, entries + parse_entries(["coordinated"], "off"), robots=(2,), episodes=3, seed=7,
                          env_kwargs=ENV, resume=True)
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 9
    assert _rows(more)[:6] == _rows(full) and [c["entry"] for c in more["cells"]][-1] == "coordinated"
    # one label meaning another controller is refused
    with pytest.raises(BulletnavError, match="another controller"):
        run_comparison(out, [Entry("coordinated", "independent")], robots=(2,), episodes=3, seed=7, env_kwargs=ENV,
                       resume=True)


def test_rows_of_different_episodes_are_refused():
    settings = {"entries": [{"label": "a"}, {"label": "b"}], "robots": [2], "episodes": 1, "seed": 0, "env_kwargs": {}}
    row = {"robots": 2, "episode": 0, "seed": 0, "throughput_per_hour": 0.0}
    with pytest.raises(BulletnavError, match="different episodes"):
        build_comparison(settings, [{**row, "entry": "a", "fingerprint": "x"}, {**row, "entry": "b", "fingerprint": "y"}])


def test_bad_settings_name_the_argument(tmp_path):
    entries = parse_entries(["independent"], "off")
    with pytest.raises(ConfigError, match="robots"):
        run_comparison(tmp_path, entries, robots=(0,), episodes=1)
    with pytest.raises(ConfigError, match="episodes"):
        run_comparison(tmp_path, entries, robots=(2,), episodes=0)
    with pytest.raises(BulletnavError, match="model file not found"):
        run_comparison(tmp_path, parse_entries(["policy=models/none.zip"], "off"), robots=(2,), episodes=1)


def test_chunks_cover_every_entry_block_by_block():
    entries = parse_entries(["independent", "coordinated"], "off")
    chunks = plan_chunks(entries, (4, 8), 6, done={"8/coordinated/1"}, size=4)
    assert [(e.label, n, eps) for e, n, eps in chunks] == [
        ("independent", 8, [0, 1, 2, 3]), ("coordinated", 8, [0]), ("coordinated", 8, [2, 3]),
        ("independent", 4, [0, 1, 2, 3]), ("coordinated", 4, [0, 1, 2, 3]),
        ("independent", 8, [4, 5]), ("coordinated", 8, [4, 5]), ("independent", 4, [4, 5]), ("coordinated", 4, [4, 5])]


@pytest.mark.slow
def test_tables_of_a_stopped_run_cover_the_episodes_every_entry_has(tmp_path):
    """A run stopped early: ``run=False`` runs nothing and tabulates only the episodes that
    every entry has, each cell saying how many; the shielded entry's settings record its shield."""
    from bulletnav.fleet.compare import comparison_markdown
    from bulletnav.fleet.controllers import FLEET_SHIELD

    entries = parse_entries(["independent"], "both")
    with pytest.raises(BulletnavError, match="no episodes.jsonl"):
        run_comparison(tmp_path / "none", entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV, run=False)
    out = tmp_path / "cut"
    full = run_comparison(out, entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV)
    assert "not finished" not in comparison_markdown(full)
    settings = json.loads((out / "settings.json").read_text())
    assert [e.get("shield_config") for e in settings["entries"]] == [None, json.loads(json.dumps(asdict(FLEET_SHIELD)))]
    rows = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    kept = [r for r in rows if not (r["entry"] == "independent + shield" and r["episode"] == 2)]
    (out / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in kept))
    part = run_comparison(out, entries, robots=(2,), episodes=3, seed=7, env_kwargs=ENV, run=False)
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 5  # nothing ran
    assert [c["episodes"] for c in part["cells"]] == [2, 2]
    assert sorted({r["episode"] for r in part["episodes"]}) == [0, 1]
    assert _rows(part) == [r for r in _rows(full) if json.loads(r)["episode"] < 2]
    assert "not finished" in (out / "comparison.md").read_text()
