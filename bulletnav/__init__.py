"""bulletnav: PyBullet warehouse navigation with classical and learned controllers.

Importing the package registers ``bulletnav/Warehouse-v0``, ``bulletnav/WarehouseAisles-v0`` and
``bulletnav/WarehouseDynamic-v0`` with Gymnasium.
"""

import os

# MKL, torch's BLAS on x86-64, picks its kernels by CPU, and their float sums differ in the last
# bits. On an AVX-512 Intel machine the shipped policy's 30 reference episodes all came out
# different with MKL's own choice (AVX-512) and with its AVX2 kernels, and all identical with its
# AVX (or SSE4.2) ones, which the machines that recorded them must have used. So every machine
# takes the AVX kernels (on every x86-64 CPU since 2011); a user who sets MKL_ENABLE_INSTRUCTIONS
# keeps their choice. MKL reads it at its first call: importing torch before bulletnav is fine,
# a matrix product on the CPU before it is not (set the variable then).
os.environ.setdefault("MKL_ENABLE_INSTRUCTIONS", "AVX")

import gymnasium as gym  # noqa: E402


def _import_pybullet_quietly() -> None:
    """Import pybullet without its ``pybullet build time: ...`` line, which its C code prints
    when first imported (to stderr in pybullet 3.2.7, to stdout in some builds) and which would
    precede every command's output and every error message. Whatever else reaches file
    descriptors 1 and 2 meanwhile (another thread's output) comes out after the import
    (:func:`bulletnav.stdio.import_without_banner`). A process that imported pybullet before
    bulletnav has had its banner already; nothing is done then."""
    import sys

    from bulletnav.stdio import import_without_banner

    if "pybullet" not in sys.modules:
        import_without_banner("pybullet", (b"pybullet build time:",))


_import_pybullet_quietly()

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

DYNAMIC_ENV_ID = "bulletnav/WarehouseDynamic-v0"
DYNAMIC_KWARGS = {
    **AISLES_KWARGS,
    "forklifts": (2, 4),
    "workers": (2, 6),
    "pallet_events_per_min": 2.0,
}
"""``WarehouseDynamic-v0``: the aisle warehouses of ``WarehouseAisles-v0`` with 2-4 forklifts,
2-6 workers and pallets appearing and vanishing (2 events a minute on average)."""

if DYNAMIC_ENV_ID not in gym.registry:
    gym.register(id=DYNAMIC_ENV_ID, entry_point="bulletnav.envs.warehouse:WarehouseEnv", max_episode_steps=2400,
                 kwargs=DYNAMIC_KWARGS)

MISSION_ENV_ID = "bulletnav/WarehouseMission-v0"
MISSION_KWARGS = {**AISLES_KWARGS, "task_name": "mission", "goals": 3, "goal_order": "free"}
"""``WarehouseMission-v0``: aisle warehouses, 3 goals in any order (``bulletnav.tasks.mission``);
the task truncates after 1,200 steps per goal."""

if MISSION_ENV_ID not in gym.registry:
    gym.register(id=MISSION_ENV_ID, entry_point="bulletnav.envs.warehouse:WarehouseEnv", max_episode_steps=None,
                 kwargs=MISSION_KWARGS)

BARN_ENV_ID = "bulletnav/BARN-v0"
"""``BARN-v0``: the BARN challenge's 300 static worlds (``world_idx`` 0-299) with BARN's start, goal,
rules and score (``bulletnav.barn``); BARN's own 100 s clock ends an episode, not a step limit."""

if BARN_ENV_ID not in gym.registry:
    gym.register(id=BARN_ENV_ID, entry_point="bulletnav.barn.env:BarnEnv", max_episode_steps=None)
