"""bulletnav: PyBullet warehouse navigation with classical and learned controllers.

Importing the package registers ``bulletnav/Warehouse-v0`` with Gymnasium.
"""

import gymnasium as gym

__version__ = "0.1.0"

ENV_ID = "bulletnav/Warehouse-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="bulletnav.envs.warehouse:WarehouseEnv", max_episode_steps=1000)
