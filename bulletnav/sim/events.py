"""Obstacles that appear and vanish mid-episode: scripted by a layout's ``events:`` list or
drawn at a configurable rate.

Rules, for every event: nothing appears within ``keep_clear`` (1.5 m) of the robot or of a
goal, on a mover's route, on another obstacle, or where it would disconnect the robot from
any goal on the map inflated by the robot's footprint radius (checked before placing, by
connected components of the free cells). A scripted ``add`` that breaks a rule waits until
it no longer does; a drawn one tries a few other places and is dropped if none fits.
``remove`` hides an obstacle (a layout obstacle or an added one) by its ``label``. Bodies
come from a pool made with the world (parked under the floor while unused); hidden layout
obstacles come back at the next reset. Every event that happens is reported in ``info``.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
from scipy import ndimage

from bulletnav.sim.layout import Layout
from bulletnav.sim.movers import PARK_Z
from bulletnav.sim.specs import EventSpec, ForkliftSpec, MoverSpec, Obstacle
from bulletnav.sim.world import COLOURS, STATIC_GROUP, STATIC_MASK, static_body

PALLET = Obstacle("box", (0.0, 0.0), size=(1.2, 0.8, 1.0), label="pallet")
"""What a drawn event adds: a loaded pallet, 1.2 x 0.8 x 1.0 m."""


class Events:
    """The events of one scene: a body pool made with the world and the episode's schedule."""

    def __init__(self, cid: int, resolution: float = 0.1, keep_clear: float = 1.5) -> None:
        self.cid = cid
        self.resolution = resolution
        self.keep_clear = keep_clear
        self.scripted_bodies: list[int] = []
        self.pallet_bodies: list[int] = []
        self.body_ids: frozenset[int] = frozenset()
        self.created = 0
        self._layout: Layout | None = None
        self._obstacle_bodies: list[int] = []
        self._reset_state()

    def _reset_state(self) -> None:
        self.present: dict[int, Obstacle] = {}  # body -> obstacle, for added ones
        self.hidden: set[int] = set()  # layout obstacle indices removed this episode
        self.log: list[dict] = []
        self._pending: list[tuple[int, EventSpec]] = []
        self._free_pallets: list[int] = list(self.pallet_bodies)
        self._rate_per_s = 0.0
        self._next_draw = math.inf
        self._rng = np.random.default_rng(0)

    def build(self, layout: Layout, obstacle_bodies: list[int], pallets: int, labels: dict[int, str]) -> None:
        """Create the pool in a freshly built world: one body per scripted ``add`` of the
        layout and ``pallets`` bodies for drawn events."""
        self._layout = layout
        self._obstacle_bodies = list(obstacle_bodies)
        self.scripted_bodies = [self._body(e.add, labels) for e in layout.events if e.add is not None]
        self.pallet_bodies = [self._body(PALLET, labels) for _ in range(pallets)]
        self.body_ids = frozenset((*self.scripted_bodies, *self.pallet_bodies))
        self._reset_state()

    def _body(self, o: Obstacle, labels: dict[int, str]) -> int:
        cid = self.cid
        dims = (o.size[0] / 2, o.size[1] / 2, o.size[2] / 2) if o.kind == "box" else (o.radius, o.height)
        body = static_body(cid, o.kind, dims, COLOURS.get(o.label, COLOURS["box"]), (0.0, 0.0, PARK_Z))
        p.setCollisionFilterGroupMask(body, -1, STATIC_GROUP, STATIC_MASK, physicsClientId=cid)
        labels[body] = o.label or "event"
        self.created += 1
        return body

    # ------------------------------------------------------------------ episodes
    def start(self, rng: np.random.Generator | None, rate_per_min: float, inflated: np.ndarray) -> None:
        """Begin an episode: park every pool body, bring back hidden layout obstacles,
        schedule the layout's events, and draw events at ``rate_per_min`` from ``rng``.
        ``inflated`` is the static map inflated by the robot's radius (cells of ``resolution``)."""
        layout = self._layout
        for i in self.hidden:
            o = layout.obstacles[i]
            self._put(self._obstacle_bodies[i], o)
        for k, body in enumerate(self.pool_bodies()):
            self._park(body, 2.0 * k)
        self._reset_state()
        scripted = iter(self.scripted_bodies)
        self._pending = [(next(scripted) if e.add is not None else -1, e) for e in layout.events]
        self._rate_per_s = rate_per_min / 60.0
        if rng is not None:
            self._rng = np.random.default_rng(int(rng.integers(0, 2**63 - 1)))
        # a Poisson process: exponential waits between drawn events
        self._next_draw = self._rng.exponential(1.0 / self._rate_per_s) if self._rate_per_s > 0 else math.inf
        self._inflated = inflated

    def pool_bodies(self) -> list[int]:
        return [*self.scripted_bodies, *self.pallet_bodies]

    def step(self, time_s: float, dt: float, robot_xy: tuple[float, float], goals: tuple[tuple[float, float], ...],
             robot_radius: float, movers: list) -> list[dict]:
        """Fire what is due at ``time_s``; returns this step's events (also kept in :attr:`log`).
        ``movers``: the active movers (their specs' routes are kept clear)."""
        if not self._pending and time_s < self._next_draw:
            return []
        fired: list[dict] = []
        still = []
        for body, spec in self._pending:
            if spec.at > time_s:
                still.append((body, spec))
                continue
            if spec.add is not None:
                if self._fits(spec.add, robot_xy, goals, robot_radius, movers):
                    self._put(body, spec.add)
                    self.present[body] = spec.add
                    fired.append(self._record(time_s, "add", spec.add, "scripted"))
                else:
                    still.append((body, spec))  # waits until it fits
            else:
                fired.extend(self._remove(spec.remove, time_s, "scripted"))
        self._pending = still
        if time_s >= self._next_draw:
            self._next_draw = time_s + self._rng.exponential(1.0 / self._rate_per_s)
            drawn = [b for b in self.present if b in self.pallet_bodies]
            if drawn and (not self._free_pallets or self._rng.random() < 0.5):
                body = drawn[int(self._rng.integers(len(drawn)))]
                o = self.present.pop(body)
                self._park(body)
                self._free_pallets.append(body)
                fired.append(self._record(time_s, "remove", o, "drawn"))
            elif self._free_pallets:
                o = self._draw_pallet(robot_xy, goals, robot_radius, movers)
                if o is not None:
                    body = self._free_pallets.pop()
                    self._put(body, o)
                    self.present[body] = o
                    fired.append(self._record(time_s, "add", o, "drawn"))
        self.log.extend(fired)
        return fired

    # ------------------------------------------------------------------ helpers
    def _record(self, t: float, action: str, o: Obstacle, source: str) -> dict:
        return {"time_s": round(t, 6), "action": action, "label": o.label, "center": list(o.center),
                "size": list(o.size) if o.kind == "box" else [2 * o.radius, 2 * o.radius, o.height], "source": source}

    def _remove(self, label: str | None, t: float, source: str) -> list[dict]:
        out = []
        for body, o in list(self.present.items()):
            if o.label == label:
                self._park(body)
                del self.present[body]
                if body in self.pallet_bodies:
                    self._free_pallets.append(body)
                out.append(self._record(t, "remove", o, source))
        for i, o in enumerate(self._layout.obstacles):
            if o.label == label and i not in self.hidden:
                self._park(self._obstacle_bodies[i])
                self.hidden.add(i)
                out.append(self._record(t, "remove", o, source))
        return out

    def _put(self, body: int, o: Obstacle) -> None:
        half = 0.5 * o.yaw
        p.resetBasePositionAndOrientation(body, [o.center[0], o.center[1], o.top / 2],
                                          [0.0, 0.0, math.sin(half), math.cos(half)], physicsClientId=self.cid)

    def _park(self, body: int, x: float = 0.0) -> None:
        """Hide ``body`` under the floor (at ``x`` m along, keeping parked bodies apart)."""
        p.resetBasePositionAndOrientation(body, [x, 0.0, PARK_Z], [0, 0, 0, 1], physicsClientId=self.cid)

    def _draw_pallet(self, robot_xy, goals, robot_radius, movers, tries: int = 20) -> Obstacle | None:
        bx0, by0, bx1, by1 = self._layout.bounds
        r = PALLET.bounding_radius()
        for _ in range(tries):
            x, y = self._rng.uniform(bx0 + r, bx1 - r), self._rng.uniform(by0 + r, by1 - r)
            yaw = float(self._rng.choice([0.0, math.pi / 2]))
            o = Obstacle("box", (float(x), float(y)), size=PALLET.size, yaw=yaw, label="pallet")
            if self._fits(o, robot_xy, goals, robot_radius, movers):
                return o
        return None

    def _fits(self, o: Obstacle, robot_xy, goals, robot_radius: float, movers: list) -> bool:
        """The placement rules of the module docstring."""
        keep = self.keep_clear
        for xy in (robot_xy, *goals):
            if float(o.distance(np.array(xy[0]), np.array(xy[1]))) < keep:
                return False
        layout = self._layout
        if float(np.min(layout.clearance(*_footprint_points(o)))) <= 0.05:
            return False
        for other in self.present.values():
            if float(np.min(other.distance(*_footprint_points(o)))) <= 0.05:
                return False
        for mover in movers:
            spec: MoverSpec = mover.spec
            path = spec.route if isinstance(spec, ForkliftSpec) else spec.waypoints
            margin = (spec.size[1] / 2 if isinstance(spec, ForkliftSpec) else spec.radius) + 0.15
            px, py = _polyline_points(path)
            if float(np.min(o.distance(px, py))) < margin:
                return False
        return self._connected(o, robot_xy, goals, robot_radius)

    def _connected(self, o: Obstacle, robot_xy, goals, robot_radius: float) -> bool:
        occ = self._inflated.copy()
        for other in (*self.present.values(), o):
            self._mark(occ, other, robot_radius)
        labels, _ = ndimage.label(~occ)
        here = labels[self._cell(robot_xy)]
        return here != 0 and all(labels[self._cell(g)] == here for g in goals)

    def _cell(self, xy) -> tuple[int, int]:
        x0, y0, _, _ = self._layout.bounds
        nx, ny = self._inflated.shape
        return (min(max(int((xy[0] - x0) / self.resolution), 0), nx - 1),
                min(max(int((xy[1] - y0) / self.resolution), 0), ny - 1))

    def _mark(self, occ: np.ndarray, o: Obstacle, inflate: float) -> None:
        res = self.resolution
        x0, y0, _, _ = self._layout.bounds
        r = o.bounding_radius() + inflate
        i0, i1 = self._cell((o.center[0] - r, 0))[0], self._cell((o.center[0] + r, 0))[0] + 1
        j0, j1 = self._cell((0, o.center[1] - r))[1], self._cell((0, o.center[1] + r))[1] + 1
        xs = x0 + res * (np.arange(i0, i1) + 0.5)
        ys = y0 + res * (np.arange(j0, j1) + 0.5)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        occ[i0:i1, j0:j1] |= o.distance(gx, gy) <= inflate


def _footprint_points(o: Obstacle) -> tuple[np.ndarray, np.ndarray]:
    """Points on and inside an obstacle's footprint (its corners, edge midpoints, centre)."""
    if o.kind == "cylinder":
        a = np.linspace(0, 2 * math.pi, 12, endpoint=False)
        return o.center[0] + o.radius * np.cos(a), o.center[1] + o.radius * np.sin(a)
    c, s = math.cos(o.yaw), math.sin(o.yaw)
    lx = np.array([1, 1, -1, -1, 1, -1, 0, 0, 0]) * o.size[0] / 2
    ly = np.array([1, -1, 1, -1, 0, 0, 1, -1, 0]) * o.size[1] / 2
    return o.center[0] + c * lx - s * ly, o.center[1] + s * lx + c * ly


def _polyline_points(path, step: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = [], []
    for (ax, ay), (bx, by) in zip(path, path[1:]):
        n = max(2, int(math.hypot(bx - ax, by - ay) / step) + 1)
        t = np.linspace(0.0, 1.0, n)
        xs.append(ax + (bx - ax) * t)
        ys.append(ay + (by - ay) * t)
    return np.concatenate(xs), np.concatenate(ys)
