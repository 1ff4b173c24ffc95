"""Aisle warehouses (``layout_style="aisles"``): parallel rack rows, aisles, cross aisles, dead ends.

The layout follows how pallet-racking warehouses are drawn (rack engineers' layouts, and the
"traditional" and "cross-aisle" layouts of order-picking studies): long rows of racks,
single ones against the side walls and back-to-back double rows between aisles, cut by one
or more straight cross aisles; at each end wall the rows stop short of it (an open end
aisle), run into it, or run into a rack row along it. Building columns stand at row ends.

Built in a local frame where the rows run along ``u`` and stack along ``v``, then mapped
onto the floor (rows along x or y)::

    end wall   cross aisle   end wall
    |=====...===| |======|      <- rack row (u-extent: a block, v-extent: its depth)
    |   aisle   |o|      P      <- aisle segment; P = pallet stack closing one mouth, o = column
    |=====...===| |======|
    |##|  b   |   |  ##  |      <- a double row: two racks back to back; b/#: boxes, pallets

Every aisle segment (an aisle between two rows, or a row and a side wall, within one block
of rows) has two mouths, one at each end of its block. A mouth is closed when its block
runs into an end wall or an end rack row, or by a pallet stack across the aisle; at most
one mouth of a segment is ever closed, so every segment is reachable, some only from one
side (dead ends), and the layout always has at least one dead end. Pallets and boxes stand
against rack faces (and walls) inside segments, always leaving ``min_passage`` free across
the aisle. Every random number comes from ``rng``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bulletnav.config import AislesConfig, WorldConfig
from bulletnav.errors import LayoutError
from bulletnav.sim.layout import Layout
from bulletnav.sim.specs import Obstacle

OPEN, WALL, RACK = 0, 1, 2
"""How the rows meet an end wall: an open end aisle, rows running into the wall, rows running
into a rack row along the wall."""

_TRIES = 200
"""Redraws of the end treatments and of the rows across before a floor is declared too small."""


@dataclass
class _Item:
    """A local-frame footprint: a rectangle [u0, u1] x [v0, v1], or a rotated square (``yaw``)
    whose bounding rectangle that is."""

    u0: float
    u1: float
    v0: float
    v1: float
    height: float
    label: str
    yaw: float = 0.0
    side: float = 0.0
    """Side of a rotated square (0: the rectangle itself)."""
    kind: str = "box"


@dataclass
class _Segment:
    """One aisle within one block of rows: free floor [u0, u1] x [v0, v1] between two solid faces."""

    u0: float
    u1: float
    v0: float
    v1: float
    closed: list[bool] = field(default_factory=lambda: [False, False])
    """Mouth at u0, mouth at u1."""
    blocked: list[tuple[float, float]] = field(default_factory=list)
    """u-intervals taken by pallet stacks (no clutter there)."""
    clutter: list[tuple[float, float, float, int]] = field(default_factory=list)
    """(u0, u1, depth across the aisle, face 0 at v0 / 1 at v1) of each pallet or box in it."""

    @property
    def width(self) -> float:
        return self.v1 - self.v0


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def _split(rng: np.random.Generator, total: float, lo: float, hi: float) -> list[float]:
    """Random lengths in [lo, hi] that sum to ``total`` (``total >= lo`` and ``hi >= 2 lo``)."""
    n_min, n_max = max(1, math.ceil(total / hi - 1e-9)), max(1, math.floor(total / lo + 1e-9))
    n = int(rng.integers(n_min, max(n_min, n_max) + 1))
    lengths = []
    rest = total
    for i in range(n - 1):
        left = n - i - 1
        a, b = max(lo, rest - left * hi), min(hi, rest - left * lo)
        piece = float(rng.uniform(a, b)) if b > a else a
        lengths.append(piece)
        rest -= piece
    lengths.append(rest)
    return lengths


def _ends(rng: np.random.Generator, a: AislesConfig, lu: float) -> tuple[list[int], list[float], list[float], int]:
    """End treatments, end depths (end aisle width or end rack depth, 0 for a wall), the cross
    aisle widths and the number of blocks along the rows."""
    weights = np.asarray(a.end_weights, dtype=float)
    weights = weights / weights.sum()
    lo_len = a.rack_length[0]
    for _ in range(_TRIES):
        kinds = [int(rng.choice(3, p=weights)) for _ in range(2)]
        depths = [_uniform(rng, a.cross_aisle_width) if k == OPEN else _uniform(rng, a.rack_depth) if k == RACK else 0.0
                  for k in kinds]
        room = lu - sum(depths)
        k_max = 0
        while k_max < a.max_cross_aisles and (k_max + 2) * lo_len + (k_max + 1) * a.cross_aisle_width[0] <= room:
            k_max += 1
        if k_max == 0:
            continue
        k = int(rng.integers(1, k_max + 1))
        widest = min(a.cross_aisle_width[1], (room - (k + 1) * lo_len) / k)
        cross = [float(rng.uniform(a.cross_aisle_width[0], widest)) for _ in range(k)]
        return kinds, depths, cross, k + 1
    raise LayoutError(f"aisle warehouse: a {lu:.1f} m long floor is too short for two blocks of racks at least "
                      f"{lo_len} m long and a cross aisle; use a larger world_size")


def _rows_across(rng: np.random.Generator, a: AislesConfig, lv: float) -> tuple[list[list[float]], list[float], bool, bool]:
    """Rows across the floor: each row's rack depths (one, or two back to back), the aisle
    widths between them (in order from the low side wall), and whether the first and last
    rows stand against the side walls."""
    (d_lo, d_hi), (w_lo, w_hi) = a.rack_depth, a.aisle_width
    for _ in range(_TRIES):
        wall_lo, wall_hi = bool(rng.random() < a.wall_row_prob), bool(rng.random() < a.wall_row_prob)
        rows: list[list[float]] = [[float(rng.uniform(d_lo, d_hi))]] if wall_lo else []
        widths: list[float] = []
        used = sum(map(sum, rows))
        closing = w_hi + (d_hi if wall_hi else 0.0)  # room the far side may need at most
        while True:
            w = float(rng.uniform(w_lo, w_hi))
            n = 2 if rng.random() < a.double_row_prob else 1
            row = [float(x) for x in rng.uniform(d_lo, d_hi, n)]
            if used + w + sum(row) + closing > lv:
                break
            widths.append(w)
            rows.append(row)
            used += w + sum(row)
        widths.append(float(rng.uniform(w_lo, w_hi)))
        if wall_hi:
            rows.append([float(rng.uniform(d_lo, d_hi))])
        total = lv - sum(map(sum, rows))
        scale = total / sum(widths)
        scaled = [w * scale for w in widths]
        if len(rows) >= 2 and min(scaled) >= w_lo - 1e-9 and max(scaled) <= w_hi + 1e-9:
            return rows, scaled, wall_lo, wall_hi
    raise LayoutError(f"aisle warehouse: could not fit rows and aisles {a.aisle_width} m wide across a {lv:.1f} m "
                      "wide floor; change world_size or the aisle and rack ranges")


def generate_aisles(rng: np.random.Generator, config: WorldConfig = WorldConfig()) -> Layout:
    """A seeded aisle warehouse drawn with ``config.aisles`` on a ``config.size`` floor (see the module doc).

    Raises:
        LayoutError: the floor is too small for two blocks of racks and a cross aisle, or for
            two rows with aisles between them.
    """
    a = config.aisles
    along_x = _along_x(rng, config)
    lu, lv = (config.size[0], config.size[1]) if along_x else (config.size[1], config.size[0])
    items: list[_Item] = []
    ends, blocks = _blocks_along(rng, a, lu, lv, items)
    row_spans, aisles = _rows_across_blocks(rng, a, lv, blocks, items)
    segments = _aisle_segments(rng, a, aisles, blocks, ends, items)
    for seg in segments:  # pallets and boxes against the faces of each segment
        n = int(rng.poisson(a.clutter_per_metre * (seg.u1 - seg.u0)))
        for _ in range(n):
            _place_clutter(rng, a, seg, items)
    _place_columns(rng, a, row_spans, blocks, ends, items)
    obstacles = tuple(_to_world(it, along_x) for it in items)
    return Layout(config.size, obstacles, config.wall_height, name="aisles", source="procedural aisles")


def _along_x(rng: np.random.Generator, config: WorldConfig) -> bool:
    """Whether the rows run along x (``row_axis``; "random" draws only between axes that have
    room for two blocks of racks and a cross aisle along them)."""
    a = config.aisles
    if a.row_axis == "random":
        fits = [length >= 2 * a.rack_length[0] + a.cross_aisle_width[0] for length in config.size]
        return bool(rng.random() < 0.5) if all(fits) else fits[0]
    return a.row_axis == "x"


def _blocks_along(rng: np.random.Generator, a: AislesConfig, lu: float, lv: float,
                  items: list[_Item]) -> tuple[list[int], list[tuple[float, float]]]:
    """Along the rows (length ``lu``, m): the two end treatments (a rack row along an end wall
    added to ``items``), and the blocks of racks between the cross aisles, ``(u0, u1)`` each."""
    hu, hv = lu / 2, lv / 2
    ends, end_depths, cross, n_blocks = _ends(rng, a, lu)
    room = lu - sum(end_depths) - sum(cross)
    extra = room - n_blocks * a.rack_length[0]
    lengths = [a.rack_length[0] + float(x) * extra for x in rng.dirichlet(np.ones(n_blocks))]
    blocks = []
    u = -hu + end_depths[0]
    for i, length in enumerate(lengths):
        blocks.append((u, u + length))
        u += length + (cross[i] if i < len(cross) else 0.0)
    for e, (kind, depth) in enumerate(zip(ends, end_depths)):
        if kind == RACK:  # a rack row along the end wall, split into racks of the allowed lengths
            u0, u1 = (-hu, -hu + depth) if e == 0 else (hu - depth, hu)
            v = -hv
            for length in _split(rng, lv, *a.rack_length):
                items.append(_Item(u0, u1, v, v + length, a.rack_height, "rack"))
                v += length
    return ends, blocks


def _rows_across_blocks(rng: np.random.Generator, a: AislesConfig, lv: float, blocks: list[tuple[float, float]],
                        items: list[_Item]) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """Across the rows (width ``lv``, m): the rows of racks in every block (added to ``items``)
    and the aisles between them; returns the rows' and the aisles' ``(v0, v1)`` spans."""
    rows, widths, wall_lo, wall_hi = _rows_across(rng, a, lv)
    row_spans: list[tuple[float, float]] = []
    aisles: list[tuple[float, float]] = []
    v = -lv / 2
    if not wall_lo:
        aisles.append((v, v + widths[0]))
        v += widths[0]
    w_iter = iter(widths[0 if wall_lo else 1:])
    for i, row in enumerate(rows):
        row_spans.append((v, v + sum(row)))
        for b0, b1 in blocks:
            r0 = v
            for depth in row:  # each rack of a double row split along the block independently
                u = b0
                for length in _split(rng, b1 - b0, *a.rack_length):
                    items.append(_Item(u, u + length, r0, r0 + depth, a.rack_height, "rack"))
                    u += length
                r0 += depth
        v += sum(row)
        if i < len(rows) - 1 or not wall_hi:
            w = next(w_iter)
            aisles.append((v, v + w))
            v += w
    return row_spans, aisles


def _aisle_segments(rng: np.random.Generator, a: AislesConfig, aisles: list[tuple[float, float]],
                    blocks: list[tuple[float, float]], ends: list[int], items: list[_Item]) -> list[_Segment]:
    """The aisle segments (one per aisle and block) and their mouths, closed at a closed end;
    dead ends made with pallet stacks (``pallet_stack_prob``, and at least one)."""
    segments: list[_Segment] = []
    for v0, v1 in aisles:
        for i, (b0, b1) in enumerate(blocks):
            seg = _Segment(b0, b1, v0, v1)
            seg.closed[0] = i == 0 and ends[0] != OPEN
            seg.closed[1] = i == len(blocks) - 1 and ends[1] != OPEN
            segments.append(seg)
    for seg in segments:
        if not any(seg.closed) and rng.random() < a.pallet_stack_prob:
            _close_with_pallets(rng, seg, int(rng.integers(2)), items)
    if not any(any(s.closed) for s in segments):
        seg = segments[int(rng.integers(len(segments)))]
        _close_with_pallets(rng, seg, int(rng.integers(2)), items)
    return segments


def _place_columns(rng: np.random.Generator, a: AislesConfig, row_spans: list[tuple[float, float]],
                   blocks: list[tuple[float, float]], ends: list[int], items: list[_Item]) -> None:
    """Building columns at row ends facing a cross aisle or an open end aisle (``columns``)."""
    sites = []
    for r in range(len(row_spans)):
        for c in range(len(blocks) + 1):  # corridor c lies before block c (0: the low end, last: the high end)
            if c == 0 and ends[0] != OPEN or c == len(blocks) and ends[1] != OPEN:
                continue
            sites.append((r, c))
    n_columns = min(int(rng.integers(a.columns[0], a.columns[1] + 1)), len(sites))
    for k in rng.permutation(len(sites))[:n_columns]:
        r, c = sites[int(k)]
        v0, v1 = row_spans[r]
        radius = float(rng.uniform(0.15, min(0.25, (v1 - v0) / 2)))
        if c == 0:
            side = 1
        elif c == len(blocks):
            side = 0
        else:
            side = int(rng.integers(2))  # the end of the block before (0) or after (1) the corridor
        u = blocks[c - 1][1] + radius if side == 0 else blocks[c][0] - radius
        vc = (v0 + v1) / 2
        items.append(_Item(u - radius, u + radius, vc - radius, vc + radius, 3.0, "column", kind="cylinder"))


def _close_with_pallets(rng: np.random.Generator, seg: _Segment, mouth: int, items: list[_Item]) -> None:
    """A pallet stack across the whole aisle at one mouth: side-by-side pallets at most 1.2 m wide."""
    depth = float(rng.choice([0.8, 1.0, 1.2]))
    u0, u1 = (seg.u0, seg.u0 + depth) if mouth == 0 else (seg.u1 - depth, seg.u1)
    n = math.ceil(seg.width / 1.2 - 1e-9)
    step = seg.width / n
    for i in range(n):
        items.append(_Item(u0, u1, seg.v0 + i * step, seg.v0 + (i + 1) * step, float(rng.uniform(1.0, 1.8)), "pallet"))
    seg.closed[mouth] = True
    seg.blocked.append((u0, u1))


def _place_clutter(rng: np.random.Generator, a: AislesConfig, seg: _Segment, items: list[_Item]) -> None:
    """One pallet or box against a face of ``seg``, if a spot keeps ``min_passage`` free across."""
    if rng.random() < a.pallet_share:
        long_along = bool(rng.random() < 0.5)
        along, across = (1.2, 0.8) if long_along else (0.8, 1.2)
        side, yaw, kind_h = 0.0, 0.0, float(rng.uniform(0.4, 1.2))
        label = "pallet"
        offset = float(rng.uniform(0.0, 0.05))
    else:
        side = float(rng.uniform(0.3, 0.7))
        yaw = float(rng.uniform(-math.pi, math.pi))
        along = across = side * (abs(math.cos(yaw)) + abs(math.sin(yaw)))  # bounding square of the rotated box
        kind_h = float(rng.uniform(0.3, 0.8))
        label = "box"
        offset = float(rng.uniform(0.0, 0.1))
    face = int(rng.integers(2))
    depth = offset + across
    u0 = float(rng.uniform(seg.u0, seg.u1 - along)) if seg.u1 - seg.u0 > along else None
    if u0 is None or seg.width - depth < a.min_passage:
        return
    u1 = u0 + along
    for b0, b1 in seg.blocked:
        if u0 < b1 + a.min_passage and u1 > b0 - a.min_passage:
            return
    for c0, c1, c_depth, c_face in seg.clutter:
        if c_face == face and u0 < c1 + 0.1 and u1 > c0 - 0.1:
            return
        if c_face != face and u0 < c1 + a.min_passage and u1 > c0 - a.min_passage and seg.width - depth - c_depth < a.min_passage:
            return
    seg.clutter.append((u0, u1, depth, face))
    v0 = seg.v0 + offset if face == 0 else seg.v1 - offset - across
    items.append(_Item(u0, u1, v0, v0 + across, kind_h, label, yaw=yaw, side=side))


def _to_world(it: _Item, along_x: bool) -> Obstacle:
    """Map a local footprint onto the floor: (u, v) -> (x, y) with rows along x, (v, u) with rows along y."""
    uc, vc = (it.u0 + it.u1) / 2, (it.v0 + it.v1) / 2
    center = (uc, vc) if along_x else (vc, uc)
    if it.kind == "cylinder":
        return Obstacle("cylinder", center, radius=(it.u1 - it.u0) / 2, height=it.height, label=it.label)
    if it.side:  # rotated square: (u, v) -> (v, u) mirrors angles about the diagonal
        yaw = it.yaw if along_x else math.remainder(math.pi / 2 - it.yaw, 2 * math.pi)
        return Obstacle("box", center, size=(it.side, it.side, it.height), yaw=yaw, label=it.label)
    du, dv = it.u1 - it.u0, it.v1 - it.v0
    size = (du, dv, it.height) if along_x else (dv, du, it.height)
    return Obstacle("box", center, size=size, label=it.label)
