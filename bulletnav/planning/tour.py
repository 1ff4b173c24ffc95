"""Exact shortest tours through a few goals (K <= 8): the order a mission should take.

The input is a distance matrix over ``K + 1`` points, index 0 the start and 1..K the goals
(shortest path lengths on the map, so they need not be Euclidean or symmetric). ``fixed``
order visits the goals as given; ``free`` order finds the cheapest open path that starts at
0 and visits every goal once (no return), by dynamic programming over subsets (Held-Karp):
``cost[S][j]`` = cheapest way to start at 0, visit exactly the goals in ``S`` and stop at
``j``; ``K**2 2**K`` steps, 2,048 for K = 8.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from bulletnav import limits

MAX_GOALS = 8
"""Largest K the exact tour accepts by default (the ``goals`` limit of :mod:`bulletnav.limits`,
which ``BULLETNAV_MAX_GOALS`` raises)."""


def tour(dist: Sequence[Sequence[float]], order: str = "free") -> tuple[float, tuple[int, ...]]:
    """Length and goal order (indices 1..K) of the best tour from point 0 through every goal.

    Raises:
        ValueError: ``order`` is not ``fixed`` or ``free``, the matrix is not square, or K
            exceeds :data:`MAX_GOALS`.
    """
    n = len(dist)
    if any(len(row) != n for row in dist):
        raise ValueError(f"tour needs a square distance matrix, got rows of lengths {[len(r) for r in dist]}")
    k = n - 1
    if order not in ("fixed", "free"):
        raise ValueError(f"order must be 'fixed' or 'free', got {order!r}")
    most = max(MAX_GOALS, limits.current().goals)
    if k > most:
        raise ValueError(f"an exact tour takes at most {most} goals, got {k} (raise it with {limits.env_var('goals')})")
    if k <= 0:
        return 0.0, ()
    if order == "fixed":
        seq = tuple(range(1, n))
        return sum(dist[a][b] for a, b in zip((0, *seq), seq)), seq
    full = (1 << k) - 1
    inf = math.inf
    cost = [[inf] * n for _ in range(1 << k)]
    back = [[0] * n for _ in range(1 << k)]
    for j in range(1, n):
        cost[1 << (j - 1)][j] = dist[0][j]
    for subset in range(1, full + 1):
        for j in range(1, n):
            c = cost[subset][j]
            if c == inf or not subset & (1 << (j - 1)):
                continue
            for nxt in range(1, n):
                bit = 1 << (nxt - 1)
                if subset & bit:
                    continue
                total = c + dist[j][nxt]
                if total < cost[subset | bit][nxt]:
                    cost[subset | bit][nxt] = total
                    back[subset | bit][nxt] = j
    last = min(range(1, n), key=lambda j: cost[full][j])
    best = cost[full][last]
    seq = []
    subset, j = full, last
    while j:
        seq.append(j)
        subset, j = subset & ~(1 << (j - 1)), back[subset][j]
    return best, tuple(reversed(seq))


def tour_through(points: Sequence[tuple[float, float]], length: Callable[[tuple[float, float], tuple[float, float]], float],
                 order: str = "free") -> tuple[float, tuple[int, ...]]:
    """:func:`tour` over ``points`` (the start first, then the goals), with the path length
    between each pair from ``length(a, b)`` (assumed symmetric: computed once per pair)."""
    n = len(points)
    dist = [[0.0] * n for _ in range(n)]
    for i in range(n):
        for j in range(i + 1, n):
            dist[i][j] = dist[j][i] = length(points[i], points[j])
    return tour(dist, order)
