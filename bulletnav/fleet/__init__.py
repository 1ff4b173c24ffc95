"""Multi-robot fleet: N robots running pick-and-drop errands in one warehouse (PettingZoo).

``from bulletnav.fleet import fleet_v0``; ``fleet_v0.parallel_env(num_robots=4, ...)`` or
``fleet_v0.env(...)`` (AEC). See :class:`~bulletnav.fleet.env.FleetEnv` and ``docs/fleet.md``.
"""

from bulletnav.fleet import fleet_v0
from bulletnav.fleet.config import MAX_ROBOTS, FleetConfig
from bulletnav.fleet.env import FleetEnv
from bulletnav.fleet.stations import Errand, ErrandStream, Stations, find_stations

__all__ = ["MAX_ROBOTS", "Errand", "ErrandStream", "FleetConfig", "FleetEnv", "Stations", "find_stations", "fleet_v0"]
