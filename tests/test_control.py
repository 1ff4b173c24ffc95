"""PID controller and the classical navigator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bulletnav.control.pid import PID


def test_pid_drives_a_first_order_plant_to_the_setpoint():
    """Plant dx/dt = u; a PI controller must settle on the setpoint with no steady error."""
    pid = PID(kp=2.0, ki=0.5, out_min=-1.0, out_max=1.0, integral_limit=5.0)
    x, dt = 0.0, 0.01
    for _ in range(2000):
        x += pid.update(1.0 - x, dt) * dt
    assert x == pytest.approx(1.0, abs=1e-3)


def test_pid_output_is_clamped_and_integral_does_not_wind_up():
    pid = PID(kp=1.0, ki=1.0, out_min=-0.5, out_max=0.5, integral_limit=100.0)
    for _ in range(1000):  # large persistent error: output saturated the whole time
        assert pid.update(10.0, 0.01) == 0.5
    assert pid.integral == 0.0  # conditional integration kept it from winding up
    # when the error reverses, the output follows at once instead of unwinding for seconds
    assert pid.update(-1.0, 0.01) < 0


def test_pid_integral_limit_derivative_and_reset():
    pid = PID(kp=0.0, ki=1.0, integral_limit=0.3)
    for _ in range(100):
        pid.update(1.0, 0.1)
    assert pid.integral == pytest.approx(0.3)
    pid.reset()
    assert pid.integral == 0.0
    d = PID(kp=0.0, kd=1.0)
    assert d.update(1.0, 0.1) == 0.0  # no derivative kick on the first update
    assert d.update(2.0, 0.1) == pytest.approx(10.0)
    with pytest.raises(ValueError, match="dt"):
        d.update(1.0, 0.0)


def test_lidar_map_matches_the_layout(make_scene, write_layout, report):
    from bulletnav.planning.mapping import OCCUPIED, UNKNOWN, LidarMapper

    layout = write_layout({
        "size": [8.0, 6.0],
        "obstacles": [
            {"type": "box", "center": [2.0, 1.0], "size": [1.2, 0.8, 1.0], "yaw": 0.3},
            {"type": "box", "center": [-2.0, -1.5], "size": [2.0, 0.6, 2.0]},
            {"type": "cylinder", "center": [0.5, -1.8], "radius": 0.25, "height": 2.0},
            {"type": "cylinder", "center": [-1.5, 1.5], "radius": 0.2, "height": 2.0},
        ],
    })
    scene = make_scene()
    scene.use_layout(layout)
    mapper = LidarMapper((-4.0, -3.0, 4.0, 3.0), 0.2)
    lidar = scene.sensors.lidar
    # A sweep as the robot would collect it: five stops, turning in place at each (36 rays
    # every 10 deg, so 6 headings 1.7 deg apart fill in between rays).
    for x, y in [(0.0, 0.0), (-1.0, 0.5), (1.0, -0.5), (3.0, -1.5), (-3.0, 0.5)]:
        for k in range(6):
            scene.place_robot((x, y, k * math.radians(10) / 6), np.random.default_rng(0))
            mapper.integrate(scene.robot.planar_pose(), lidar.angles, lidar.read(), lidar.config.max_range,
                             sensor_offset=0.1)
    state = mapper.state()
    # Truth: the obstacle intersects the cell (centre within half a cell diagonal). The ring of
    # cells along the walls is left out: the wall faces lie exactly on the grid's edge.
    truth = layout.occupancy(0.2, inflate=0.2 * math.sqrt(2) / 2)
    interior = np.zeros_like(truth)
    interior[1:-1, 1:-1] = True
    known = (state != UNKNOWN) & interior
    agreement = float(np.mean((state[known] == OCCUPIED) == truth[known]))
    occ = (state == OCCUPIED) & interior
    precision = float(truth[occ].mean())
    report("known interior cells", f"{int(known.sum())} of {int(interior.sum())}")
    report("cell agreement on known cells", f"{agreement:.3f}")
    report("occupied-cell precision", f"{precision:.3f}")
    assert known.mean() > 0.5
    assert agreement > 0.95
    assert precision > 0.9
    # every obstacle shows up: mapped cells within one cell of each footprint
    xs, ys = layout.grid_axes(0.2)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    for i, obstacle in enumerate(layout.obstacles):
        near = obstacle.distance(gx, gy) <= 0.2 * math.sqrt(2)
        assert occ[near].sum() >= 3, f"obstacle {i} barely mapped"
