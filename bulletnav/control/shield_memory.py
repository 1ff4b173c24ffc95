"""What the lidar saw and no longer sees: the shield's memory of the sector behind a lidar that
does not see all the way round.

The Jackal's UST-10 sees 270 degrees; the 90 degrees behind it are blind. A shield that looks only
at the current scan finds that sector empty, and a rectangle turning in place (or backing up)
sweeps its rear corners through it. :class:`ScanMemory` keeps the scan's points, carried forward
by the pose it is given (the shield's dead reckoning: the gyroscope's heading, the wheels'
distance), for as long as they lie in the blind sector:

- every step it moves the remembered points (kept in the frame of the poses given) into the current body
  frame; those the lidar now sees again (a ray spacing or more inside its field of view) are
  dropped, for the current scan is the truth there, and so are those farther than ``radius`` from the body centre and those
  inside the robot's own outline (a point there cannot be an obstacle: the robot stands on it, so
  it is dead reckoning's drift or something that moved away);
- then it adds the current scan's points (the shield's filled surfaces) within ``radius``: the
  ones that leave the field of view before the next step stay remembered.

A lidar that sees all the way round has no blind sector, and the memory stays empty: the shield's
decisions are the same as without it.
"""

from __future__ import annotations

import math

import numpy as np

from bulletnav.geometry import RobotGeometry


def blind_sector(angles: np.ndarray) -> tuple[float, float] | None:
    """The lidar's field of view as (first, last) ray angle (rad) when it leaves a blind sector
    (the widest gap between neighbouring rays, the way round, is over twice the rays' spacing);
    None for a lidar that sees all the way round."""
    a = np.sort(np.mod(np.asarray(angles, dtype=np.float64), 2.0 * math.pi))
    if len(a) < 2:
        return None
    gaps = np.diff(np.concatenate([a, a[:1] + 2.0 * math.pi]))
    widest = int(np.argmax(gaps))
    spacing = float(np.median(gaps))
    if gaps[widest] <= 2.0 * spacing:
        return None
    first = float(a[(widest + 1) % len(a)])
    last = first + float(2.0 * math.pi - gaps[widest])
    return first, last


class ScanMemory:
    """The remembered points of a lidar's blind sector (see the module docstring).

    Args:
        geometry: the robot's geometry (its outline and the lidar's mount).
        angles: the lidar's ray angles (rad, body frame).
        radius: remember points within this distance of the body centre (m).
    """

    def __init__(self, geometry: RobotGeometry, angles: np.ndarray, radius: float) -> None:
        self.radius = float(radius)
        self.fov = blind_sector(angles)
        spacing = float(np.median(np.abs(np.diff(np.asarray(angles, dtype=np.float64))))) if len(angles) > 1 else 0.0
        # a point counts as seen again only a ray spacing inside the outer rays: between the outer
        # ray and the blind sector no ray looks, and a cylinder there is seen by none
        self._edge = -spacing
        self._lidar = (geometry.lidar_mount[0], geometry.lidar_mount[1])
        self._outline = np.array([(r.cx, r.cy, r.half_x, r.half_y) for r in geometry.rectangles])
        self._world = np.zeros((0, 2))
        self.active = self.fov is not None and self.radius > 0.0
        """False when the lidar sees all the way round (or ``radius`` is 0): nothing is remembered."""

    def reset(self) -> None:
        """Forget everything (a new episode)."""
        self._world = np.zeros((0, 2))

    def __len__(self) -> int:
        return len(self._world)

    def _in_view(self, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
        assert self.fov is not None
        first, last = self.fov
        bearing = np.mod(np.arctan2(by - self._lidar[1], bx - self._lidar[0]) - (first - self._edge), 2.0 * math.pi)
        return bearing <= (last - first) + 2.0 * self._edge

    def _on_robot(self, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
        on = np.zeros(bx.shape, dtype=bool)
        for cx, cy, hx, hy in self._outline:
            on |= (np.abs(bx - cx) <= hx) & (np.abs(by - cy) <= hy)
        return on

    def update(self, pose: tuple[float, float, float], seen: np.ndarray) -> np.ndarray:
        """The remembered points the lidar does not see now, in the body frame (N, 2), after
        which this step's points ``seen`` (body frame, (M, 2)) join the memory.

        Args:
            pose: the robot's pose (x, y, yaw) by dead reckoning (m, m, rad), in a frame fixed for the episode.
            seen: the current scan's points (the shield's filled surfaces), body frame.
        """
        if not self.active:
            return np.zeros((0, 2))
        x, y, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = self._world[:, 0] - x, self._world[:, 1] - y
        bx, by = c * dx + s * dy, -s * dx + c * dy
        keep = (bx * bx + by * by <= self.radius * self.radius) & ~self._in_view(bx, by) & ~self._on_robot(bx, by)
        hidden = np.stack([bx[keep], by[keep]], axis=1)
        seen = np.asarray(seen, dtype=np.float64).reshape(-1, 2)
        seen = seen[seen[:, 0] ** 2 + seen[:, 1] ** 2 <= self.radius * self.radius]
        body = np.concatenate([hidden, seen])
        self._world = np.stack([x + c * body[:, 0] - s * body[:, 1], y + s * body[:, 0] + c * body[:, 1]], axis=1)
        return hidden
