"""What ``--live`` costs a run: the same seeded ``navigate`` episodes (PID + A* on
``Warehouse-v0``, unpaced) without a stream, streaming with no client, and streaming to one
client subscribed to every topic, interleaved in rounds so that the machine's noise hits all
three alike; the ratios of their wall times (median over rounds) are the figures, beside the
ratios of the run's process CPU time (the server's threads included, the client's process not).

The client is a separate process (as Foxglove would be), speaking the Foxglove WebSocket
protocol through the ``websockets`` library: it subscribes to every channel the server
advertises and counts the frames and bytes it receives.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from typing import Any

import gymnasium as gym
import numpy as np

CLIENT = r"""
import json, signal, sys
from websockets.sync.client import connect
frames = nbytes = 0
subscribed = {}
def stop(*_):
    print(json.dumps({"frames": frames, "bytes": nbytes, "channels": len(subscribed)}), flush=True)
    sys.exit(0)
signal.signal(signal.SIGTERM, stop)
with connect(sys.argv[1], subprotocols=["foxglove.sdk.v1"], max_size=None, compression=None, proxy=None) as ws:
    while True:
        msg = ws.recv()
        if isinstance(msg, bytes):
            frames += 1
            nbytes += len(msg)
            continue
        op = json.loads(msg)
        if op.get("op") == "advertise":
            subs = []
            for ch in op["channels"]:
                if ch["id"] not in subscribed:
                    subscribed[ch["id"]] = len(subscribed) + 1
                    subs.append({"id": subscribed[ch["id"]], "channelId": ch["id"]})
            if subs:
                ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                print("subscribed", len(subscribed), flush=True)
"""
"""The benchmark's client: subscribes to everything, counts what arrives, prints the counts on SIGTERM."""


def _run_block(env: gym.Env, nav: Any, episodes: int, seed: int) -> tuple[float, float, int]:
    """``episodes`` navigate episodes from ``seed``: (wall s, CPU s of this process, steps)."""
    from bulletnav.evaluation import run_episodes

    w0, c0 = time.perf_counter(), time.process_time()
    results = run_episodes(env, nav, episodes, seed)
    return time.perf_counter() - w0, time.process_time() - c0, int(sum(r.steps for r in results))


def _start_client(url: str, live: Any, timeout_s: float = 120.0) -> subprocess.Popen:
    """The client process, once it has subscribed to every channel and the server has taken it in."""
    client = subprocess.Popen([sys.executable, "-c", CLIENT, url], stdout=subprocess.PIPE, text=True)
    end = time.monotonic() + timeout_s
    client.stdout.readline()  # "subscribed N": its first subscribe is sent
    while not all(live.watched(t) for t in live.topics):
        if time.monotonic() > end or client.poll() is not None:
            client.kill()
            raise RuntimeError("the benchmark's live client did not subscribe in time")
        time.sleep(0.01)
    return client


def bench_live(episodes: int = 4, rounds: int = 5, seed: int = 0, env_id: str = "bulletnav/Warehouse-v0") -> dict[str, Any]:
    """Time ``rounds`` x three variants of the same ``episodes`` seeded navigate episodes (see
    the module docstring); returns the per-round times, the median ratios and the client's counts."""
    from bulletnav.control.navigator import Navigator, NavigatorConfig
    from bulletnav.ros.live import LiveServer
    from bulletnav.ros.record import McapRecorder

    base = gym.make(env_id)
    quiet, watched = LiveServer("127.0.0.1:0", speed=0), LiveServer("127.0.0.1:0", speed=0)
    client = None
    try:
        nav = Navigator(base.unwrapped.scene, NavigatorConfig(planner="astar"))
        variants = {"no_stream": base, "live_no_client": McapRecorder(base, None, live=quiet),
                    "live_one_client": McapRecorder(base, None, live=watched)}
        _run_block(variants["live_one_client"], nav, 1, seed)  # every channel advertised before the client joins
        _run_block(variants["live_no_client"], nav, 1, seed)
        client = _start_client(watched.url, watched)
        times: dict[str, list[float]] = {k: [] for k in variants}
        cpu: dict[str, list[float]] = {k: [] for k in variants}
        steps = {}
        for r in range(rounds):
            order = list(variants) if r % 2 == 0 else list(reversed(variants))
            for name in order:
                wall, c, n = _run_block(variants[name], nav, episodes, seed)
                times[name].append(wall)
                cpu[name].append(c)
                steps[name] = n
        client.terminate()
        counts = json.loads(client.communicate(timeout=60)[0].strip().splitlines()[-1])
        client = None
    finally:
        if client is not None:
            client.kill()
        quiet.close()
        watched.close()
        base.close()
    ratio = {name: float(np.median(np.asarray(times[name]) / np.asarray(times["no_stream"]))) for name in variants}
    cpu_ratio = {name: float(np.median(np.asarray(cpu[name]) / np.asarray(cpu["no_stream"]))) for name in variants}
    return {"benchmark": "live", "env_id": env_id, "episodes": episodes, "rounds": rounds, "seed": seed,
            "steps_per_round": steps, "wall_s": times, "cpu_s": cpu,
            "steps_per_s_median": {k: float(np.median([steps[k] / t for t in v])) for k, v in times.items()},
            "ratio_live_no_client": ratio["live_no_client"], "ratio_live_one_client": ratio["live_one_client"],
            "cpu_ratio_live_no_client": cpu_ratio["live_no_client"], "cpu_ratio_live_one_client": cpu_ratio["live_one_client"],
            "target_no_client": 1.05, "meets_target": ratio["live_no_client"] <= 1.05, "client": counts}


__all__ = ["bench_live"]
