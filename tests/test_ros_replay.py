"""``bulletnav replay``: a recording drawn from the file alone gives the live video's frames
(map, trajectory, plan, lidar hits, movers, strip), the path plot and one frame; files that are
no bulletnav recording are refused."""

from __future__ import annotations

import json

import imageio.v3 as iio
import numpy as np
import pytest

from bulletnav.cli import main
from bulletnav.errors import BulletnavError
from bulletnav.ros.replay import read_recording
from bulletnav.viz.video import MAP_PX, STRIP_Y


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Two PID + A* episodes of the dynamic warehouse, their live video and their recording."""
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.control.navigator import Navigator
    from bulletnav.evaluation import run_episodes
    from bulletnav.ros.record import McapRecorder
    from bulletnav.viz.video import EpisodeRecorder

    d = tmp_path_factory.mktemp("replay")
    env = gym.make("bulletnav/WarehouseDynamic-v0", max_episode_steps=200)
    nav = Navigator(env.unwrapped.scene)
    rec = McapRecorder(env, d / "run.mcap", plan=lambda: nav.path)
    with EpisodeRecorder(d / "live.mp4") as video:
        run_episodes(rec, nav, 2, 11, on_reset=lambda e, i: video.on_reset(e, i, path=nav.path),
                     on_step=lambda e, i: video.on_step(e, i, path=nav.path))
    rec.close()
    return d


@pytest.mark.slow
def test_replay_draws_the_live_frames(recorded, capsys):
    d = recorded
    capsys.readouterr()
    assert main(["replay", str(d / "run.mcap"), "--video", str(d / "replay.mp4"), "--plot", str(d / "paths.png"),
                 "--frame", str(d / "frame.png"), "--frame-at", "6.25", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["episodes"] == 2 and summary["steps"] == [200, 200]
    live = list(iio.imiter(d / "live.mp4"))
    again = list(iio.imiter(d / "replay.mp4"))
    assert len(again) == len(live) == summary["frames"] == 402  # a reset frame and 200 steps, twice
    for k in (0, 1, 100, 200, 201, 350, 401):
        a, b = live[k].astype(np.int16), again[k].astype(np.int16)
        # the map panel and the status strip (the camera panel is not replayed): the same picture,
        # up to the video encoder's noise
        assert np.abs(a[:STRIP_Y, :MAP_PX] - b[:STRIP_Y, :MAP_PX]).mean() < 1.5, k
        assert np.abs(a[STRIP_Y:] - b[STRIP_Y:]).mean() < 1.5, k
    # --frame-at is simulated seconds: 6.25 s at 24 control steps a second is step 150, the video's
    # frame 150 (frame 0 is the reset)
    assert (summary["frame_step"], summary["frame_time_s"]) == (150, 6.25)
    frame = iio.imread(d / "frame.png")
    assert frame.shape == live[0].shape
    # the PNG is the frame as composed, the video's the encoder's copy of it (2.8 of 255 apart here): nearer
    # to the video's frame 150 than to the frames 10 steps either side
    near = [np.abs(frame[:STRIP_Y, :MAP_PX].astype(np.int16) - again[k][:STRIP_Y, :MAP_PX]).mean() for k in (140, 150, 160)]
    assert near[1] < 4.0 and near[1] < min(near[0], near[2]), near
    assert (d / "paths.png").stat().st_size > 0


@pytest.mark.slow
def test_recording_holds_what_replay_needs(recorded):
    episodes = read_recording(recorded / "run.mcap")
    assert len(episodes) == 2
    for ep in episodes:
        assert len(ep["steps"]) == 200 and ep["layout"]["obstacles"]
        assert ep["meta"]["end_reason"] == "timeout"
        assert ep["mover_routes"] and all(len(r) >= 2 for r in ep["mover_routes"])
        assert any(st["movers"] for st in ep["steps"])
    # the file itself through mcap's reader (no bulletnav code, no message decoding): by hand,
    # 200 control steps of 1/24 s per episode, one /clock, /scan and /reward message each,
    # stamped 1e9 / 24 ns apart within an episode
    from mcap.reader import make_reader

    with open(recorded / "run.mcap", "rb") as f:
        reader = make_reader(f)
        stamps: dict[str, list[int]] = {"/clock": [], "/scan": [], "/reward": []}
        for _, channel, message in reader.iter_messages(topics=list(stamps)):
            stamps[channel.topic].append(message.log_time)
    for topic, times in stamps.items():
        assert len(times) == 2 * 200, topic
    clock = sorted(stamps["/clock"])
    for k in (0, 1):
        steps = np.diff(clock[200 * k:200 * (k + 1)])
        assert np.abs(steps - 1e9 / 24).max() <= 1.0, (k, steps.min(), steps.max())
    assert clock[200] > clock[199]  # the second episode follows the first


def test_replay_refuses_what_is_no_recording(tmp_path, capsys):
    with pytest.raises(BulletnavError, match="no such recording"):
        read_recording(tmp_path / "missing.mcap")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 64)
    with pytest.raises(BulletnavError, match="junk.mcap"):
        read_recording(junk)
    assert main(["replay", str(junk), "--plot", str(tmp_path / "p.png")]) == 2
    assert "junk.mcap" in capsys.readouterr().err
    assert not (tmp_path / "p.png").exists()


@pytest.mark.slow
def test_foxglove_layout_and_panel(recorded, tmp_path, capsys):
    """The shipped Foxglove layout names only topics a recording has, and ``--panel`` draws its
    3D panel's content from the messages."""

    from bulletnav.ros.live import LAYOUT
    from bulletnav.ros.record import TOPIC_TYPES

    layout = json.loads(LAYOUT.read_text())
    topics = set(layout["configById"]["3D!bulletnav"]["topics"])
    paths = {p["value"].split(".")[0] for cfg in layout["configById"].values() for p in cfg.get("paths", [])}
    assert topics | paths <= set(TOPIC_TYPES)
    # ... and the recording has them: its channels as mcap's own reader lists them
    from mcap.reader import make_reader

    with open(recorded / "run.mcap", "rb") as f:
        recorded_topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    shield_only = {"/shield/interventions"}  # recorded behind a shield (this episode has none)
    assert (topics | paths) - shield_only <= recorded_topics, (topics | paths) - shield_only - recorded_topics
    assert {"/cmd_vel", "/odom", "/goal_distance", "/shield/interventions"} <= paths  # the plots: speeds, to goal, shield
    assert layout["configById"]["3D!bulletnav"]["followTf"] == "base_link"
    out = tmp_path / "panel.png"
    assert main(["replay", str(recorded / "run.mcap"), "--panel", str(out), "--panel-at", "4", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["panel"]["step"] == 96 and out.stat().st_size > 10_000


@pytest.mark.slow
def test_replay_frame_has_no_depth_bar_and_frame_at_is_checked(recorded, tmp_path, capsys):
    """No camera is recorded: the replayed frame's legend has no depth colour bar (the live one,
    with its camera, has); a --frame-at after the first episode's end (200 steps of 1/24 s:
    8.33 s) is refused before anything is drawn."""
    d = recorded
    live = next(iter(iio.imiter(d / "live.mp4"))).astype(int)
    assert main(["replay", str(d / "run.mcap"), "--frame", str(tmp_path / "frame.png"), "--frame-at", "6.25"]) == 0
    frame = iio.imread(tmp_path / "frame.png").astype(int)  # its own frame: the live-frames test may not run (slow)
    bar = (slice(370, 460), slice(812, 828))  # where the live legend's depth bar runs (x: legend + 12 .. + 28 px)
    assert live[bar].std(axis=(0, 1)).max() > 40  # the turbo scale: many colours
    assert frame[bar].std(axis=(0, 1)).max() < 3  # the background only
    out = tmp_path / "late.png"
    assert main(["replay", str(d / "run.mcap"), "--frame", str(out), "--frame-at", "9"]) == 2
    err = capsys.readouterr().err
    assert "a frame at 9 s is outside the first episode (0 to 8.33 s, 200 steps)" in err and not out.exists()
