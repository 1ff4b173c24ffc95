"""Who may drive a ``--live-control`` stream, asked of a real browser (Debian's Chromium driven by
Playwright): a page of another site (``http://evil.example``, resolved to this machine by the
browser's own host rules, so its requests reach the server) opens a WebSocket to the stream and
publishes a goal; the browser sends that page's ``Origin`` itself, the gate refuses the handshake
and the robot's goal does not change. The same page served from ``http://127.0.0.1`` connects,
publishes the same goal, and the session takes it. The browser, not the test, writes the headers."""

from __future__ import annotations

import http.server
import threading

import gymnasium as gym
import pytest

import bulletnav  # noqa: F401
from browser import chromium
from hang import HANG_S

PAGE = """<!doctype html><title>page</title><script>
const ws = new WebSocket("%(url)s", ["foxglove.sdk.v1"]);
ws.binaryType = "arraybuffer";
window.result = null;
ws.onopen = () => {
  ws.send(JSON.stringify({op: "advertise", channels: [
    {id: 1, topic: "/goal_pose", encoding: "json", schemaName: "geometry_msgs/msg/PoseStamped"}]}));
  const goal = new TextEncoder().encode(JSON.stringify(
    {header: {frame_id: "map"}, pose: {position: {x: %(x)r, y: %(y)r, z: 0}}}));
  const frame = new Uint8Array(5 + goal.length);
  frame[0] = 1; new DataView(frame.buffer).setUint32(1, 1, true); frame.set(goal, 5);
  ws.send(frame);
  window.result = "sent";
};
ws.onclose = (event) => { if (window.result === null) window.result = "closed " + event.code; };
</script>"""


@pytest.fixture(scope="module")
def browser():
    yield from chromium("--host-resolver-rules=MAP evil.example 127.0.0.1")


def _serve(html: str) -> tuple[http.server.ThreadingHTTPServer, int]:
    class Page(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 (the handler's name in http.server)
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, server.server_address[1]


@pytest.mark.slow
def test_a_page_of_another_site_cannot_drive_a_loopback_page_can(browser, report):
    from bulletnav.control.navigator import Navigator
    from bulletnav.ros.live import LiveServer
    from bulletnav.ros.live_control import NO_STEP_LIMIT, TASK_NAME, LiveControl
    from bulletnav.ros.live_gate import OriginPolicy

    live = LiveServer("127.0.0.1:0", speed=0, control=OriginPolicy())
    env = gym.make("bulletnav/Warehouse-v0", task_name=TASK_NAME, max_episode_steps=NO_STEP_LIMIT, num_obstacles=0)
    session = LiveControl(env, Navigator(env.unwrapped.scene), live)
    server, port = _serve(PAGE % {"url": live.url, "x": 2.0, "y": 1.0})
    page = browser.new_page()
    try:
        session.reset(seed=0)
        start_goal = session.scene.goal
        page.goto(f"http://evil.example:{port}/", timeout=HANG_S * 1000)
        page.wait_for_function("window.result !== null", timeout=HANG_S * 1000)
        foreign = page.evaluate("window.result")
        for _ in range(48):
            session.step()
        assert foreign.startswith("closed") and f"http://evil.example:{port}" in live.gate.refused
        assert session.goals_taken == 0 and session.scene.goal == start_goal
        page.goto(f"http://127.0.0.1:{port}/", timeout=HANG_S * 1000)
        page.wait_for_function("window.result !== null", timeout=HANG_S * 1000)
        local = page.evaluate("window.result")
        for _ in range(2000):
            if session.goals_taken:
                break
            session.step()
        assert local == "sent" and session.goals_taken == 1 and session.scene.goal == (2.0, 1.0)
        report("browser", f"page of http://evil.example:{port}: WebSocket {foreign} (refused: {dict(live.gate.refused)}); "
                          f"page of http://127.0.0.1:{port}: goal {session.scene.goal} taken")
    finally:
        page.close()
        server.shutdown()
        session.close()
        live.close()
