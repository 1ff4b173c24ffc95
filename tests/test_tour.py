"""The exact mission tour against brute force over every order."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from bulletnav.planning.tour import tour


def _brute(dist, order):
    k = len(dist) - 1
    orders = [tuple(range(1, k + 1))] if order == "fixed" else itertools.permutations(range(1, k + 1))
    best = (math.inf, ())
    for seq in orders:
        length = sum(dist[a][b] for a, b in zip((0, *seq), seq))
        best = min(best, (length, tuple(seq)))
    return best


@pytest.mark.parametrize("k", range(1, 8))
def test_tour_matches_brute_force_on_random_matrices(k):
    rng = np.random.default_rng(k)
    for _ in range(20):
        pts = rng.uniform(-5, 5, (k + 1, 2))
        euclid = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
        asym = euclid * rng.uniform(1.0, 1.5, euclid.shape)  # detours: not metric, not symmetric
        for dist in (euclid, asym):
            for order in ("free", "fixed"):
                length, seq = tour(dist.tolist(), order)
                ref_length, _ = _brute(dist, order)
                assert length == pytest.approx(ref_length, rel=1e-12)
                assert sorted(seq) == list(range(1, k + 1))
                assert sum(dist[a][b] for a, b in zip((0, *seq), seq)) == pytest.approx(length, rel=1e-12)


def test_free_order_beats_the_given_order_where_they_differ():
    # start at 0; goals at 10, 1, 5 on a line: the given order zigzags, the best goes 1, 5, 10
    xs = [0.0, 10.0, 1.0, 5.0]
    dist = [[abs(a - b) for b in xs] for a in xs]
    assert tour(dist, "fixed") == (10.0 + 9.0 + 4.0, (1, 2, 3))
    assert tour(dist, "free") == (10.0, (2, 3, 1))


def test_tour_rejects_bad_input():
    with pytest.raises(ValueError, match="order"):
        tour([[0.0]], "shortest")
    with pytest.raises(ValueError, match="at most 8"):
        tour(np.zeros((10, 10)).tolist())
    with pytest.raises(ValueError, match="square"):
        tour([[0.0, 1.0], [1.0]])
