"""The widest passage through a world (``bulletnav.barn.passage``) against geometry worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from bulletnav.barn.passage import widest_passage

BOUNDS = (-2.0, 0.0, 2.0, 4.0)  # a 4 x 4 m room


def _row(xs) -> np.ndarray:
    return np.array([[x, 2.0] for x in xs])


@pytest.mark.parametrize("gap", [0.3, 0.45, 0.62])
def test_one_gap_in_a_row_of_touching_cylinders(gap):
    """A row of touching cylinders (radius 0.075 m, 0.15 m apart) across the room at y = 2 with one
    gap: the passage is the gap between the two cylinder surfaces beside it."""
    edge = gap / 2 + 0.075  # the centres beside the gap
    right = edge + 0.15 * np.arange(0, 20)
    right = right[right < 2.2]
    left = -right
    width = widest_passage(_row(np.concatenate([left, right])), (0.0, 0.5), (0.0, 3.5), BOUNDS)
    assert width == pytest.approx(gap, abs=0.02)


def test_closed_row_and_open_room():
    """No gap: nothing passes (0); no cylinders: the passage is limited by the room's own walls
    beside the start and goal, 2 x the nearer wall's distance."""
    closed = np.arange(-2.1, 2.2, 0.15)
    assert widest_passage(_row(closed), (0.0, 0.5), (0.0, 3.5), BOUNDS) == 0.0
    # start 0.5 m from the bottom wall: a disc wider than 1 m cannot stand there
    assert widest_passage(np.zeros((0, 2)), (0.0, 0.5), (0.0, 3.5), BOUNDS) == pytest.approx(1.0, abs=0.02)


def test_the_wider_of_two_ways_counts():
    """Two gaps, 0.3 m and 0.5 m: the widest passage takes the wider one."""
    xs = np.arange(-2.1, 2.2, 0.15)
    keep = (np.abs(xs - (-1.0)) > 0.15 + 0.075) & (np.abs(xs - 1.0) > 0.25 + 0.075)  # holes around x = -1 and x = 1
    row = _row(xs[keep])
    got = widest_passage(row, (0.0, 0.5), (0.0, 3.5), BOUNDS)
    # the hole around x = 1: the nearest kept centres' surfaces, computed from the kept centres themselves
    kept = xs[keep]
    right_hole = min(kept[kept > 1.0]) - max(kept[kept < 1.0]) - 0.15
    assert got == pytest.approx(right_hole, abs=0.02) and right_hole > 0.45
