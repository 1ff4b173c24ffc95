"""Configuration of the multi-robot fleet: how many robots, how long, stations and penalties."""

from __future__ import annotations

import math
from dataclasses import dataclass

from bulletnav import limits
from bulletnav.errors import ConfigError, LimitError

MAX_ROBOTS = 16
"""Most robots one fleet holds by default: the limit ``fleet_robots`` (:mod:`bulletnav.limits`;
``BULLETNAV_MAX_FLEET_ROBOTS`` raises it up to :data:`ROBOT_BITS`)."""

ROBOT_BITS = 26
"""Most robots the collision filter can tell apart, whatever the limit says: robot ``i`` takes
bit ``5 + i`` of PyBullet's 32-bit filter group (:data:`bulletnav.fleet.lidar.FIRST_ROBOT_BIT`)."""

DOCK_WALLS = ("auto", "south", "north", "west", "east")
"""Where the drop stations (the dock) may lie: along one wall (south is -y, west is -x), or
``"auto"``: the wall with the most free room along it."""


@dataclass(frozen=True)
class FleetConfig:
    """The fleet's own settings (the per-robot world, sensors and reward are an
    :class:`~bulletnav.config.EnvConfig`, as for the single-robot envs)."""

    num_robots: int = 4
    """Robots in the warehouse, 1 to the limit ``fleet_robots`` (16; :mod:`bulletnav.limits`);
    agents ``robot_0`` ... ``robot_{N-1}``."""
    duration_s: float = 180.0
    """Simulated length of an episode (s), at most the limit ``fleet_duration`` (3600); every
    robot is truncated when it ends, none earlier."""
    collision_penalty_s: float = 5.0
    """After a collision a robot stands still this long (s): its actions are ignored."""
    min_clearance: float = 0.3
    """Least gap (m) between two robots' footprint discs where the robots are placed."""
    station_spacing: float = 1.0
    """Distance (m) between neighbouring stations along a rack face or the dock wall."""
    station_offset: float = 0.55
    """Distance (m) from a rack face (pick) or the dock wall (drop) to its stations."""
    dock_wall: str = "auto"
    """The wall the drop stations line (one of :data:`DOCK_WALLS`)."""
    pick_stations: tuple[tuple[float, float], ...] | None = None
    """Pick stations given explicitly (x, y m), instead of derived from the racks."""
    drop_stations: tuple[tuple[float, float], ...] | None = None
    """Drop stations given explicitly (x, y m), instead of derived from the dock wall."""

    def __post_init__(self) -> None:
        n = self.num_robots
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= ROBOT_BITS:
            raise ConfigError(f"fleet num_robots must be an integer from 1 to {limits.current().fleet_robots}, got {n!r}")
        _check("fleet_robots", n, "fleet num_robots")
        for name in ("duration_s", "station_spacing", "station_offset"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f"fleet {name} must be a positive number, got {value!r}")
        _check("fleet_duration", self.duration_s, "fleet duration_s")
        for name in ("collision_penalty_s", "min_clearance"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"fleet {name} must be a number >= 0, got {value!r}")
        if self.dock_wall not in DOCK_WALLS:
            raise ConfigError(f"fleet dock_wall must be one of {', '.join(DOCK_WALLS)}, got {self.dock_wall!r}")
        for name in ("pick_stations", "drop_stations"):
            points = getattr(self, name)
            if points is None:
                continue
            if len(points) == 0:
                raise ConfigError(f"fleet {name} must name at least one (x, y) point, got an empty list")
            for i, pt in enumerate(points):
                if len(pt) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in pt):
                    raise ConfigError(f"fleet {name}[{i}] must be 2 finite numbers (x, y), got {pt!r}")


def _check(name: str, value: float, what: str) -> None:
    """:func:`bulletnav.limits.check` as a :class:`ConfigError` (the message still names the variable)."""
    try:
        limits.check(name, value, what)
    except LimitError as exc:
        raise ConfigError(str(exc)) from None
