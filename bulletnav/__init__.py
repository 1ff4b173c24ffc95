"""bulletnav: PyBullet warehouse navigation with classical and learned controllers.

Importing the package registers ``bulletnav/Warehouse-v0`` and ``bulletnav/WarehouseAisles-v0``
with Gymnasium.
"""

import gymnasium as gym

__version__ = "0.1.0"

ENV_ID = "bulletnav/Warehouse-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="bulletnav.envs.warehouse:WarehouseEnv", max_episode_steps=1000)

AISLES_ENV_ID = "bulletnav/WarehouseAisles-v0"
AISLES_KWARGS = {
    "layout_style": "aisles",
    "world_size": (20.0, 16.0),
    "min_goal_distance": 3.0,
    "max_goal_distance": 10.0,
    "min_detour": 1.5,
    "blocked_by": ("rack",),
    "detour_share": 0.8,
    "collision_terminates": True,
}
"""``WarehouseAisles-v0``: procedural aisle warehouses (static), starts and goals where planning matters."""

if AISLES_ENV_ID not in gym.registry:
    gym.register(id=AISLES_ENV_ID, entry_point="bulletnav.envs.warehouse:WarehouseEnv", max_episode_steps=2400,
                 kwargs=AISLES_KWARGS)
