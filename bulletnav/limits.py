"""Resource limits: the largest worlds, sensors, episodes and sweeps bulletnav agrees to build.

Every limit is checked where the value enters (env keyword arguments and configs, layout
files, sweep files, benchmark suites, mission goals, bag maps, saved models' sidecars, fleet
configs), before anything is built: a typo such as ``lidar_rays=10000000`` or a 10 km floor
fails at once with a message, instead of exhausting memory or running for hours. The
defaults sit far above anything the shipped worlds, suites, sweeps and tests use. Each can
be raised by an environment variable, read at every check::

    BULLETNAV_MAX_LIDAR_RAYS=100000 bulletnav navigate ...

The variable of field ``x`` is ``BULLETNAV_MAX_X`` (:func:`env_var`); docs/limits.md has the table.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from dataclasses import dataclass, fields
from pathlib import Path

from bulletnav.errors import LimitError


@dataclass(frozen=True)
class Limits:
    """The limits (defaults; :func:`current` applies the environment variables)."""

    world_size: float = 200.0
    """Floor extent along each axis (m). The placement raster (5 cm) and the sampler's grid
    (0.1 m) grow with the area: 200 m is 16 M raster cells; the shipped worlds are <= 20 m."""
    obstacles: int = 1000
    """Static obstacles of a layout (procedural ``num_obstacles`` or a YAML ``obstacles:`` list).
    Each is a PyBullet body and is rasterised every reset; the shipped worlds have <= 40."""
    movers: int = 64
    """Moving obstacles in one episode (forklifts + workers, YAML ``dynamic:`` or drawn).
    Each is moved every control step; the shipped envs have <= 10."""
    events: int = 1000
    """Obstacle events of a layout (YAML ``events:`` list) and pallets in the event pool
    (``event_pallets``); each event may add a body. The shipped worlds have <= 4."""
    event_rate: float = 600.0
    """Drawn pallet events per simulated minute (``pallet_events_per_min``); 600 is one every
    2.4 control steps at 24 Hz. The shipped envs draw 2."""
    lidar_rays: int = 4096
    """Rays per lidar scan (``lidar_rays``): cast every control step and part of the
    observation; the shipped envs use 36, the tests <= 360."""
    camera_width: int = 4096
    """Camera image width (pixels); the shipped camera is 320."""
    camera_height: int = 4096
    """Camera image height (pixels); the shipped camera is 240."""
    camera_pixels: int = 8_388_608
    """Camera pixels per frame (width x height; 2^23, e.g. 4096 x 2048): TinyRenderer renders
    on the CPU, and the RGB, depth and segmentation buffers grow with it."""
    episode_steps: int = 100_000
    """Control steps of one episode (Gymnasium's ``max_episode_steps``, a mission's
    ``steps_per_goal`` x ``goals``); 100,000 is 69 simulated minutes at 24 Hz. The shipped
    envs use <= 9,600."""
    goals: int = 8
    """Goals of a mission (``goals``, a layout's ``goals:``, ``reset(options={"goals": ...})``).
    The exact free-order tour (Held-Karp) takes K^2 2^K steps: 2,048 for 8, 419 M for 20."""
    sweep_trials: int = 10_000
    """Trials of a sweep file (grid configurations x seeds); each is a training run. The
    shipped sweeps have <= 20."""
    suite_episodes: int = 100_000
    """Episodes per world of a benchmark suite (``episodes``, a world's ``episodes``); the
    shipped suites run <= 200."""
    suite_worlds: int = 64
    """Worlds of a benchmark suite (``worlds:`` entries); the shipped suites have <= 4."""
    suite_controllers: int = 64
    """Controllers of a benchmark suite (``controllers:`` entries); the shipped suites have <= 6."""
    suite_total: int = 1_000_000
    """Episodes of a whole benchmark suite (per-world episodes x controllers, summed over the
    worlds); the standard suite runs 4,800."""
    map_extent: float = 1000.0
    """Side of the grid ``bulletnav map`` builds from a bag, along each axis (m): the poses'
    span grown by the lidar's reach. Also any :class:`~bulletnav.planning.mapping.LidarMapper`."""
    map_cells: int = 16_777_216
    """Cells of a lidar map (2^24; 4 bytes of log-odds each, 64 MB): extent / resolution,
    squared. The navigator's map of a 200 m floor at 0.05 m has 16 M. Also the pixels of a
    map_server map's image given as a world (checked before the image is decoded)."""
    net_width: int = 4096
    """Units of one hidden layer of a saved model's network (the sidecar's ``net_arch``),
    built before its weights are read; the shipped models use 64-256."""
    net_layers: int = 16
    """Hidden layers of one network of a saved model (``net_arch``); the shipped models use 2-3."""
    n_steps: int = 1_048_576
    """A saved model's ``n_steps`` (PPO/A2C rollout steps per env: the rollout buffer is
    allocated when the model is built); the shipped models use <= 2,048."""
    batch_size: int = 1_048_576
    """A saved model's ``batch_size`` (samples per gradient step)."""
    buffer_size: int = 5_000_000
    """A saved model's ``buffer_size`` (SAC/TD3's replay memory, allocated when an SB3 zip is
    loaded or training goes on); SB3's default is 1,000,000, the shipped SAC file's 300,000."""
    n_envs: int = 256
    """A saved model's ``n_envs`` (parallel training envs)."""
    fleet_robots: int = 16
    """Robots of one fleet (``num_robots``): each is a body and a lidar cast every step. The
    collision filter has bits for 26 at most, whatever the variable says."""
    fleet_duration: float = 3600.0
    """Simulated length of a fleet episode (``duration_s``, s): its trace stores every robot at
    every control step (86,400 steps at 24 Hz); the shipped runs use <= 600."""


_UNITS = {"world_size": "m", "event_rate": "events/min", "camera_width": "pixels", "camera_height": "pixels",
          "camera_pixels": "pixels", "episode_steps": "control steps", "suite_episodes": "episodes",
          "suite_total": "episodes", "map_extent": "m", "map_cells": "cells", "net_width": "units",
          "n_steps": "steps", "batch_size": "samples", "buffer_size": "transitions", "fleet_duration": "s"}


def env_var(name: str) -> str:
    """The environment variable that raises limit ``name`` (``BULLETNAV_MAX_<NAME>``)."""
    return f"BULLETNAV_MAX_{name.upper()}"


def unit(name: str) -> str:
    """The unit of limit ``name`` (``count`` for plain counts)."""
    return _UNITS.get(name, "count")


def current() -> Limits:
    """The limits in force: each default replaced by its environment variable when set.

    Raises:
        LimitError: a variable that is not a positive number (an integer for counts).
    """
    values = {}
    for f in fields(Limits):
        raw = os.environ.get(env_var(f.name))
        if raw is None or not raw.strip():
            continue
        try:
            value = int(raw) if f.type == "int" else float(raw)
        except ValueError:
            value = None
        if value is None or not math.isfinite(value) or value <= 0:
            kind = "a positive integer" if f.type == "int" else "a positive number"
            raise LimitError(f"{env_var(f.name)}={raw!r} must be {kind}")
        values[f.name] = value
    return Limits(**values)


def check(name: str, value: float, what: str) -> None:
    """Refuse ``value`` when it exceeds limit ``name``.

    Args:
        name: a :class:`Limits` field.
        value: the size or count asked for.
        what: the field as the user wrote it, for the message (``"lidar num_rays"``).

    Raises:
        LimitError: ``"<what> = <value> exceeds the limit <limit> (raise it with BULLETNAV_MAX_<NAME>)"``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return  # not a number: the caller's own validation names the type
    limit = getattr(current(), name)
    if value > limit:
        raise LimitError(f"{what} = {value} exceeds the limit {limit} (raise it with {env_var(name)})")


# ----------------------------------------------------------------------------- names that become folders
SLUG = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
"""A name a file gives to its output folder (a suite's or a sweep's ``name``): a letter or
digit, then up to 63 letters, digits, ``.``, ``_`` or ``-``, and never ``..``."""

SLUG_RULE = "a letter or digit, then up to 63 letters, digits, '.', '_' or '-', without '..'"
""":data:`SLUG` in words, for messages."""


def is_slug(name: object) -> bool:
    """True when ``name`` may name an output folder (:data:`SLUG`)."""
    return isinstance(name, str) and SLUG.match(name) is not None and ".." not in name


def inside(base: str | Path, *parts: str) -> Path:
    """``base / parts``, refused unless it resolves (links followed) inside ``base``.

    Raises:
        ValueError: the joined path leaves ``base`` (the message names both).
    """
    path = Path(base).joinpath(*parts)
    if not path.resolve().is_relative_to(Path(base).resolve()):
        raise ValueError(f"{path} resolves to {path.resolve()}, outside {Path(base).resolve()}")
    return path
