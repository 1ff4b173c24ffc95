"""World generators: seeded functions that draw a :class:`~bulletnav.sim.layout.Layout`.

``WORLDS`` maps a style name (``WorldConfig.style``, env kwarg ``layout_style``) to a
generator ``(rng, WorldConfig) -> Layout``; :func:`register_world` adds one. A generator
draws every random number from ``rng`` and returns a frozen layout (the env builds it).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bulletnav.config import WorldConfig
from bulletnav.sim.aisles import generate_aisles
from bulletnav.sim.layout import Layout, generate_warehouse

WorldGenerator = Callable[[np.random.Generator, WorldConfig], Layout]

WORLDS: dict[str, WorldGenerator] = {"scattered": generate_warehouse, "aisles": generate_aisles}
"""Style name -> generator. ``scattered``: racks, pallets, boxes and columns placed apart
at random (the article's warehouse, ``Warehouse-v0``). ``aisles``: parallel rack rows with
aisles, cross aisles, dead ends, clutter in the aisles and columns (``WorldConfig.aisles``,
``WarehouseAisles-v0``)."""


def register_world(style: str, generator: WorldGenerator) -> None:
    """Make ``generator`` available as ``layout_style=style``.

    Raises:
        ValueError: ``style`` is taken by another generator.
    """
    if WORLDS.get(style, generator) is not generator:
        raise ValueError(f"world style {style!r} is already registered")
    WORLDS[style] = generator


def world_generator(style: str) -> WorldGenerator:
    """The generator of ``style``.

    Raises:
        ValueError: unknown style (the message lists the registered ones).
    """
    try:
        return WORLDS[style]
    except KeyError:
        raise ValueError(f"unknown layout_style {style!r}; registered: {', '.join(sorted(WORLDS))}") from None
