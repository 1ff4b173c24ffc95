"""Safety shield (issue 18, in progress): analytic cases on synthetic scans, and the wrapper."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

import bulletnav  # noqa: F401
from bulletnav.control.shield import Shield, ShieldWrapper
from bulletnav.geometry import robot_geometry
from bulletnav.sensors.lidar import ray_angles

ANGLES = ray_angles(36, 360.0)
GEOMETRY = robot_geometry()
OX = GEOMETRY.lidar_offset


def _shield() -> Shield:
    return Shield(GEOMETRY, ANGLES, 5.0, 1 / 24, 0.5, 1.5)


def _wall_ahead(distance: float) -> np.ndarray:
    """Ranges to a wall x = distance (body frame) across the robot's path."""
    c = np.cos(ANGLES)
    with np.errstate(divide="ignore"):
        r = np.where(c > 1e-6, (distance - OX) / c, 5.0)
    return np.minimum(r, 5.0)


def _box(cx: float, cy: float, half: float, n: int = 400) -> np.ndarray:
    """Ranges to a square box centred at (cx, cy) (body frame), ray-cast analytically."""
    r = np.full(len(ANGLES), 5.0)
    for k, a in enumerate(ANGLES):
        d = np.array([math.cos(a), math.sin(a)])
        o = np.array([OX, 0.0])
        lo, hi = -math.inf, math.inf
        for axis, c in ((0, cx), (1, cy)):
            if abs(d[axis]) < 1e-12:
                if abs(o[axis] - c) > half:
                    lo, hi = math.inf, -math.inf
                continue
            t1, t2 = (c - half - o[axis]) / d[axis], (c + half - o[axis]) / d[axis]
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
        if lo <= hi and hi > 0:
            r[k] = min(r[k], max(lo, 0.0))
    return r


def test_a_wall_inside_the_stopping_sweep_stops_a_forward_command_and_one_just_beyond_does_not():
    """At 0.5 m/s the sweep is one control period at full speed plus the braking distance:
    0.5 / 24 + 0.5^2 / (2 x 1.5) = 0.104 m past the front face (0.15 m) and its 0.04 m margin."""
    reach = 0.15 + 0.04 + 0.5 / 24 + 0.5**2 / (2 * 1.5)
    shield = _shield()
    near = shield.filter(0.5, 0.0, 0.5, _wall_ahead(reach - 0.01))
    far = shield.filter(0.5, 0.0, 0.5, _wall_ahead(reach + 0.01))
    assert near.intervened and near.v == 0.0 and near.safe
    assert not far.intervened
    close = shield.filter(0.5, 0.0, 0.5, _wall_ahead(0.2))  # a wall 5 cm ahead: nothing forward is safe
    assert close.intervened and close.v == 0.0


def test_the_same_command_passes_unchanged_with_the_wall_3_m_away():
    d = _shield().filter(0.5, 0.0, 0.5, _wall_ahead(3.0))
    assert not d.intervened and (d.v, d.w) == (0.5, 0.0) and d.change == 0.0


def test_a_turn_that_sweeps_a_box_corner_is_vetoed_and_one_that_clears_it_is_not():
    ranges = _box(0.32, 0.27, 0.1)  # a box ahead-left: its near corner (0.22, 0.17) is beside the path
    shield = _shield()
    assert not shield.filter(0.5, 0.0, 0.5, ranges).intervened  # straight on passes it
    left = shield.filter(0.5, 1.5, 0.5, ranges)
    right = shield.filter(0.5, -1.5, 0.5, ranges)
    assert left.intervened and left.w < 1.5 and left.change > 0
    assert not right.intervened


def test_the_wrapper_reports_its_decision_and_passes_actions_bit_for_bit_when_clear():
    plain = gym.make("bulletnav/Warehouse-v0", world="bulletnav/assets/worlds/empty.yaml")
    shielded = ShieldWrapper(gym.make("bulletnav/Warehouse-v0", world="bulletnav/assets/worlds/empty.yaml"))
    options = {"start": [0.0, 0.0, 0.0], "goal": [3.0, 3.0]}
    plain.reset(seed=0, options=options)
    _, info = shielded.reset(seed=0, options=options)
    assert info["shield"]["intervened"] is False
    for _ in range(20):
        a, _, _, _, _ = plain.step(np.array([0.3, 0.2]))
        b, _, _, _, info = shielded.step(np.array([0.3, 0.2]))
        assert not info["shield"]["intervened"]
        np.testing.assert_array_equal(a, b)
    plain.close()
    shielded.close()
