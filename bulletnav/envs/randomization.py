"""Domain randomization: robot, floor, sensor and world parameters drawn afresh every episode.

Declared as a mapping from parameter to distribution, in a hyperparameter file's ``randomize:``
block or as the env kwarg ``randomize``::

    randomize:
      floor_friction: [0.2, 1.0]                  # uniform on [low, high]
      mass_scale: {loguniform: [0.8, 1.5]}        # log-uniform
      action_latency: [0, 2]                      # integers: uniform on {0, 1, 2}
      lidar_noise_std: {normal: [0.02, 0.01], clip: [0.0, 0.08]}
      imu_accel_bias: [-0.1, 0.1]                 # each axis on its own
      num_obstacles: {choice: [20, 31, 40]}

Parameters (:data:`PARAMETERS`): every :class:`~bulletnav.config.ShiftConfig` field (floor and
wheel friction, mass, motor force, the odometry model's wheel radius and wheelbase, action
latency, lidar noise and dropout, IMU noise and biases, depth noise, mover speeds), and the world
parameters ``num_obstacles`` (scattered warehouses) and ``clutter_per_metre`` (aisle warehouses),
which take effect when a layout is drawn (every ``layouts_every`` resets).

Draws come from the env's own randomization stream, seeded from the reset seed apart from the
stream that draws layouts, starts and goals: with world parameters left alone, a randomized env
and a nominal one run the same episodes. ``info["dr"]`` reports this episode's values.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from bulletnav.config import ShiftConfig, WorldConfig

WORLD_PARAMETERS = {"num_obstacles": int, "clutter_per_metre": float}
"""World parameters: drawn when a layout is generated."""
_VECTOR = {"imu_accel_bias", "imu_gyro_bias"}
PARAMETERS: dict[str, type] = {
    **{f.name: (int if f.name == "action_latency" else float) for f in fields(ShiftConfig)}, **WORLD_PARAMETERS,
}
"""Every parameter ``randomize`` accepts, with its type."""
STREAM = 0xD0_5EED
"""Mixed into the reset seed for the randomization stream."""


@dataclass(frozen=True)
class Distribution:
    """One parameter's distribution: ``kind`` is ``uniform``, ``loguniform``, ``normal`` or
    ``choice``; ``args`` its (low, high), (mean, std) or choices; ``clip`` optional bounds."""

    name: str
    kind: str
    args: tuple[Any, ...]
    clip: tuple[float, float] | None = None
    integer: bool = False

    def sample(self, rng: np.random.Generator) -> Any:
        """One draw (three, one per axis, for a bias vector)."""
        if self.name in _VECTOR:
            return tuple(self._one(rng) for _ in range(3))
        return self._one(rng)

    def _one(self, rng: np.random.Generator) -> Any:
        if self.kind == "choice":
            return self.args[int(rng.integers(len(self.args)))]
        a, b = self.args
        if self.kind == "uniform":
            value = int(rng.integers(a, b + 1)) if self.integer else float(rng.uniform(a, b))
        elif self.kind == "loguniform":
            value = float(math.exp(rng.uniform(math.log(a), math.log(b))))
        else:
            value = float(rng.normal(a, b))
        if self.clip is not None:
            value = min(max(value, self.clip[0]), self.clip[1])
            value = int(round(value)) if self.integer else value
        return value

    def bounds(self) -> tuple[float, float]:
        """The smallest and largest value a draw can take."""
        if self.kind == "choice":
            return min(self.args), max(self.args)
        if self.kind == "normal":
            return self.clip if self.clip is not None else (-math.inf, math.inf)
        lo, hi = self.args
        if self.clip is not None:
            lo, hi = max(lo, self.clip[0]), min(hi, self.clip[1])
        return lo, hi


def parse_randomize(spec: Mapping[str, Any] | None, where: str = "randomize") -> tuple[Distribution, ...]:
    """Distributions from a ``randomize`` mapping (see the module docstring).

    Raises:
        ValueError: an unknown parameter (the message lists the known ones), or a distribution
            that is malformed or leaves the parameter's valid range, naming ``where`` and the entry.
    """
    if not spec:
        return ()
    if not isinstance(spec, Mapping):
        raise ValueError(f"{where} must be a mapping of parameter -> distribution, got {spec!r}")
    out = []
    for name, raw in spec.items():
        if name not in PARAMETERS:
            raise ValueError(f"{where}: unknown parameter {name!r}; known: {', '.join(sorted(PARAMETERS))}")
        out.append(_parse_one(str(name), raw, f"{where}.{name}"))
    dists = tuple(out)
    _check_ranges(dists, where)
    return dists


def _numbers(value: Any, n: int | None, where: str) -> tuple[float, ...]:
    try:
        items = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: expected {n or 'some'} numbers, got {value!r}") from None
    if (n is not None and len(items) != n) or not items or not all(math.isfinite(v) for v in items):
        raise ValueError(f"{where}: expected {n or 'some'} finite numbers, got {value!r}")
    return items


def _parse_one(name: str, raw: Any, where: str) -> Distribution:
    integer = PARAMETERS[name] is int
    clip = None
    if isinstance(raw, Mapping):
        raw = dict(raw)
        if "clip" in raw:
            clip = _numbers(raw.pop("clip"), 2, f"{where}.clip")
        if len(raw) != 1 or next(iter(raw)) not in ("uniform", "loguniform", "normal", "choice"):
            raise ValueError(f"{where}: give one of uniform, loguniform, normal, choice (and optionally clip), got {raw!r}")
        kind, args = next(iter(raw.items()))
    elif isinstance(raw, (list, tuple)):
        kind, args = "uniform", raw
    elif isinstance(raw, (int, float)) and not isinstance(raw, bool):
        kind, args = "choice", [raw]  # a fixed value
    else:
        raise ValueError(f"{where}: expected [low, high], a fixed number or a mapping, got {raw!r}")
    if kind == "choice":
        values = _numbers(args, None, where)
        if integer and any(v != int(v) for v in values):
            raise ValueError(f"{where}: {name} takes whole numbers, got {list(args)!r}")
        return Distribution(name, kind, tuple(int(v) if integer else v for v in values), clip, integer)
    a, b = _numbers(args, 2, where)
    if kind in ("uniform", "loguniform") and not a <= b:
        raise ValueError(f"{where}: need low <= high, got [{a}, {b}]")
    if kind == "loguniform" and a <= 0:
        raise ValueError(f"{where}: loguniform needs low > 0, got {a}")
    if kind == "normal" and b < 0:
        raise ValueError(f"{where}: normal needs std >= 0, got {b}")
    if integer and kind == "uniform":
        if a != int(a) or b != int(b):
            raise ValueError(f"{where}: {name} takes whole numbers, got [{a}, {b}]")
        a, b = int(a), int(b)
    elif integer:
        raise ValueError(f"{where}: {name} takes whole numbers: give [low, high] or choice")
    return Distribution(name, kind, (a, b), clip, integer)


def _check_ranges(dists: tuple[Distribution, ...], where: str) -> None:
    """Both ends of every distribution must make a valid shift or world."""
    for d in dists:
        lo, hi = d.bounds()
        for end in (lo, hi):
            if d.name in WORLD_PARAMETERS:
                if not (math.isfinite(end) and end >= 0):
                    raise ValueError(f"{where}.{d.name}: values must be finite and >= 0, the range reaches {end}")
                continue
            if not math.isfinite(end):
                raise ValueError(f"{where}.{d.name}: give a normal distribution a clip range")
            value = (end,) * 3 if d.name in _VECTOR else end
            try:
                ShiftConfig(**{d.name: value})
            except ValueError as exc:
                raise ValueError(f"{where}.{d.name}: the range reaches {end}: {exc}") from None


def draw(dists: tuple[Distribution, ...], rng: np.random.Generator, base: ShiftConfig) -> tuple[ShiftConfig, dict[str, Any]]:
    """This episode's shift: ``base`` with the drawn shift parameters, and the drawn values
    (world parameters are left to :func:`draw_world`)."""
    values = {d.name: d.sample(rng) for d in dists if d.name not in WORLD_PARAMETERS}
    return (replace(base, **values) if values else base), values


def draw_world(dists: tuple[Distribution, ...], rng: np.random.Generator, world: WorldConfig
               ) -> tuple[WorldConfig, dict[str, Any]]:
    """The world config for the next layout with the drawn world parameters, and those values."""
    values = {d.name: d.sample(rng) for d in dists if d.name in WORLD_PARAMETERS}
    if "num_obstacles" in values:
        world = replace(world, num_obstacles=int(values["num_obstacles"]))
    if "clutter_per_metre" in values:
        world = replace(world, aisles=replace(world.aisles, clutter_per_metre=float(values["clutter_per_metre"])))
    return world, values
