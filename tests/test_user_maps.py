"""A user's own maps as worlds: a ROS map_server map (YAML + PGM) and a Gazebo SDF world, both
written by hand here (bytes and text, no bulletnav code), loaded with ``world=PATH`` and driven to
their goals by PID + A*.

References: Nav2's ``loadMapFromFile`` thresholds worked by hand on single pixels; the merged boxes
rasterised here (not by bulletnav) against the wall cells computed here from the pixel values; the
SDF poses composed by hand; every refusal a one-line error naming the file and the model or field.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from PIL import Image

import bulletnav  # noqa: F401  (registers the envs)
from bulletnav.cli import main
from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.errors import LayoutError
from bulletnav.evaluation import run_episodes
from bulletnav.sim.layout import load_layout
from bulletnav.sim.mapserver import cell_values, merge_boxes, read_meta

META = "resolution: 0.1\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"


def _pgm(path: Path, rows: np.ndarray) -> None:
    """A binary PGM written byte by byte (row 0 the top of the map)."""
    h, w = rows.shape
    path.write_bytes(b"P5\n%d %d\n255\n" % (w, h) + rows.astype(np.uint8).tobytes())


# ----------------------------------------------------------------------------- map_server thresholds


def _cells(tmp_path: Path, pixels, mode: str = "trinary", negate: int = 0, image_mode: str = "L") -> list[int]:
    """The cell values bulletnav reads for one row of pixels written with Pillow."""
    name = "px.png"
    Image.fromarray(np.array([pixels], dtype=np.uint8), mode=image_mode).save(tmp_path / name)
    (tmp_path / "px.yaml").write_text(f"image: {name}\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: {negate}\n"
                                      f"occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: {mode}\n")
    from bulletnav.sim.mapserver import read_grid
    from bulletnav.yamlfile import read_yaml

    _, grid = read_grid(read_yaml(tmp_path / "px.yaml", "map", LayoutError), str(tmp_path / "px.yaml"))
    return grid[:, 0].tolist()


def test_thresholds_are_nav2s_on_hand_values(tmp_path):
    # trinary: occ = 1 - p/255; occupied when occ > 0.65, free when occ < 0.196, else unknown
    #   p=0: occ 1 -> 100; p=89: 166/255 = 0.65098 -> 100; p=90: 165/255 = 0.64706 -> -1;
    #   p=205: 50/255 = 0.19608 -> -1 (map_saver's unknown); p=206: 49/255 = 0.19216 -> 0; p=254 -> 0
    assert _cells(tmp_path, [0, 89, 90, 205, 206, 254]) == [100, 100, -1, -1, 0, 0]
    # negate: occ = p/255: p=254 -> 100, p=0 -> 0, p=50: 0.19608 -> -1
    assert _cells(tmp_path, [254, 0, 50], negate=1) == [100, 0, -1]
    # scale: p=128: occ = 127/255 = 0.498039; (0.498039 - 0.196) / 0.454 * 100 = 66.53 -> 67;
    #   p=100: occ = 0.607843 -> 90.71 -> 91; thresholds as in trinary
    assert _cells(tmp_path, [128, 100, 0, 254], mode="scale") == [67, 91, 100, 0]
    # raw: round(p) itself when 0..100 (negate not applied), else unknown
    assert _cells(tmp_path, [37, 100, 101, 150, 0], mode="raw") == [37, 100, -1, -1, 0]
    assert _cells(tmp_path, [37, 150], mode="raw", negate=1) == [37, -1]
    # colour: shade is the mean of R, G, B: (255, 0, 0) -> 1/3 -> occ 0.667 -> 100; (255, 255, 0) -> occ 0.333 -> -1
    rgb = np.array([[[255, 0, 0], [255, 255, 0], [255, 255, 255]]], dtype=np.uint8)
    Image.fromarray(rgb, "RGB").save(tmp_path / "rgb.png")
    meta = read_meta({"image": "rgb.png", "resolution": 0.1, "origin": [0, 0, 0], "negate": 0, "occupied_thresh": 0.65,
                      "free_thresh": 0.196}, str(tmp_path / "m.yaml"))
    assert cell_values(rgb / 255.0, None, meta).tolist() == [[100, -1, 0]]
    # trinary with alpha: alpha joins the mean. grey 254 with alpha 0: (3 * 254 + 0) / 4 / 255 = 0.747 -> occ 0.253 -> -1
    la = np.array([[254 / 255, 254 / 255, 254 / 255]]).reshape(1, 1, 3)
    assert cell_values(la, np.array([[0.0]]), meta).tolist() == [[-1]]
    assert cell_values(la, np.array([[1.0]]), meta).tolist() == [[0]]
    # scale: a pixel that is not opaque is unknown whatever its shade
    scale = read_meta({**{"image": "x.png", "resolution": 0.1, "origin": [0, 0, 0], "negate": 0},
                       "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "scale"}, str(tmp_path / "m.yaml"))
    assert cell_values(np.zeros((1, 2, 3)), np.array([[0.5, 1.0]]), scale).tolist() == [[-1, 100]]


def test_image_rows_run_from_the_top(tmp_path):
    # a 3 x 2 image: its bottom-left pixel is cell (0, 0)
    _pgm(tmp_path / "rows.pgm", np.array([[254, 254, 0], [0, 254, 254]]))
    (tmp_path / "rows.yaml").write_text("image: rows.pgm\norigin: [0, 0, 0]\n" + META)
    from bulletnav.sim.mapserver import read_grid
    from bulletnav.yamlfile import read_yaml

    _, grid = read_grid(read_yaml(tmp_path / "rows.yaml", "map", LayoutError), str(tmp_path / "rows.yaml"))
    assert grid.tolist() == [[100, 0], [0, 0], [0, 100]]  # grid[ix][iy]


# ----------------------------------------------------------------------------- box merging


def _raster(boxes, shape) -> np.ndarray:
    """How many boxes cover each cell (written here, not bulletnav's)."""
    count = np.zeros(shape, dtype=int)
    for i0, j0, i1, j1 in boxes:
        assert 0 <= i0 < i1 <= shape[0] and 0 <= j0 < j1 <= shape[1]
        count[i0:i1, j0:j1] += 1
    return count


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_merged_boxes_cover_exactly_the_occupied_cells(seed):
    rng = np.random.default_rng(seed)
    grid = rng.random((57, 43)) < 0.3
    grid[5:40, 10:14] = True  # a thick wall and a block among the noise
    grid[20:25, 0:43] = True
    boxes = merge_boxes(grid)
    count = _raster(boxes, grid.shape)
    assert np.array_equal(count, grid.astype(int))  # every occupied cell once, no free cell
    assert len(boxes) < int(grid.sum())


def test_walls_merge_into_few_boxes():
    # the border of a 100 x 80 grid and a wall 3 cells thick from the bottom row: 5 boxes (one per cell row: 80)
    grid = np.zeros((100, 80), dtype=bool)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = True
    grid[48:51, 0:55] = True
    boxes = merge_boxes(grid)
    assert np.array_equal(_raster(boxes, grid.shape), grid.astype(int))
    assert len(boxes) == 5  # rows: bottom and top rows, the left and right columns between them, the wall


# ----------------------------------------------------------------------------- a hand-made map, driven

ORIGIN = (3.0, -2.0, 0.5)  # the map's lower-left corner in the map frame, turned 0.5 rad
W, H, RES = 100, 70, 0.1  # 10 x 7 m


def _site_pixels() -> np.ndarray:
    """The site as pixel rows (row 0 the top): 0 occupied, 254 free, 205 unknown."""
    cells = np.full((W, H), 254, dtype=np.uint8)  # [ix, iy]
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 0  # the outer walls
    cells[48:52, 0:45] = 0  # a wall from the bottom to y = 4.5 m: the robot goes round it
    cells[70:85, 50:69] = 205  # an unexplored corner
    return cells.T[::-1]


def _map_point(lx: float, ly: float) -> tuple[float, float]:
    """A point given from the map's lower-left corner (m) in the map frame (origin's yaw turns it)."""
    c, s = math.cos(ORIGIN[2]), math.sin(ORIGIN[2])
    return ORIGIN[0] + c * lx - s * ly, ORIGIN[1] + s * lx + c * ly


@pytest.fixture()
def site(tmp_path) -> Path:
    _pgm(tmp_path / "site.pgm", _site_pixels())
    start, goal = _map_point(2.0, 1.5), _map_point(8.0, 1.5)
    (tmp_path / "site.yaml").write_text(
        f"image: site.pgm\nmode: trinary\norigin: [{ORIGIN[0]}, {ORIGIN[1]}, {ORIGIN[2]}]\n" + META +
        f"start: [{start[0]!r}, {start[1]!r}, {ORIGIN[2] + 0.3!r}]\ngoal: [{goal[0]!r}, {goal[1]!r}]\n")
    return tmp_path / "site.yaml"


def _site_yaml(tmp_path: Path, origin: tuple[float, float, float]) -> Path:
    """The site's map with ``origin``, start and goal given in the map's frame."""
    _pgm(tmp_path / "flat.pgm", _site_pixels())
    (tmp_path / "flat.yaml").write_text(
        f"image: flat.pgm\nmode: trinary\norigin: [{origin[0]!r}, {origin[1]!r}, {origin[2]!r}]\n" + META +
        f"start: [{origin[0] + 2.0!r}, {origin[1] + 1.5!r}, 0.3]\ngoal: [{origin[0] + 8.0!r}, {origin[1] + 1.5!r}]\n")
    return tmp_path / "flat.yaml"


def test_a_map_lives_in_its_own_frame_its_boxes_on_its_wall_cells(tmp_path):
    """An unturned map far off the origin (as a SLAM run saves one): the floor's corner is the
    YAML's origin to the bit, start and goal are where the YAML puts them, and the boxes cover
    exactly the wall cells (occupied and unknown pixels), rasterised here at the cells' centres
    in the map's coordinates."""
    origin = (-53.7, 12.3, 0.0)
    layout = load_layout(_site_yaml(tmp_path, origin))
    assert layout.corner == (-53.7, 12.3) and layout.size == pytest.approx((W * RES, H * RES))
    assert layout.bounds[:2] == (-53.7, 12.3) and layout.bounds[2:] == pytest.approx((-43.7, 19.3))
    assert layout.start == (-53.7 + 2.0, 12.3 + 1.5, 0.3) and layout.goal == (-53.7 + 8.0, 12.3 + 1.5)
    walls = (_site_pixels()[::-1].T != 254)
    xs = -53.7 + RES * (np.arange(W) + 0.5)
    ys = 12.3 + RES * (np.arange(H) + 0.5)
    covered = np.zeros((W, H), dtype=int)
    for o in layout.obstacles:
        assert o.kind == "box" and o.yaw == 0.0 and o.size[2] == 2.0
        inside = (np.abs(xs[:, None] - o.center[0]) < o.size[0] / 2) & (np.abs(ys[None, :] - o.center[1]) < o.size[1] / 2)
        covered += inside
    assert np.array_equal(covered, walls.astype(int))
    assert np.array_equal(layout.occupancy(RES), walls)  # the layout's own grid: the map's cells, cell for cell
    assert len(layout.obstacles) == 6  # the border (4), the wall (1) and the unknown corner (1)
    # unknown: free keeps only the occupied cells
    path = tmp_path / "flat.yaml"
    path.write_text(path.read_text() + "unknown: free\n")
    free = load_layout(path)
    assert sum(o.size[0] * o.size[1] for o in free.obstacles) == pytest.approx(
        RES * RES * int((_site_pixels() == 0).sum()))


def test_a_turned_map_is_resampled_in_the_map_frame(site):
    """The site's origin (3, -2) is turned by 0.5 rad: the floor is the rectangle that bounds the
    turned image (its corners worked by hand), start and goal stay where the YAML gives them, the
    centre of every wall pixel (map frame, by the origin's rotation) is inside a wall and a point
    two cells clear of every wall pixel is free; outside the image is wall."""
    layout = load_layout(site)
    corners = [_map_point(lx, ly) for lx in (0.0, W * RES) for ly in (0.0, H * RES)]
    x0, y0 = min(c[0] for c in corners), min(c[1] for c in corners)
    x1, y1 = max(c[0] for c in corners), max(c[1] for c in corners)
    assert layout.corner == pytest.approx((x0, y0), abs=1e-9)
    assert layout.size == pytest.approx((math.ceil((x1 - x0) / RES - 1e-9) * RES, math.ceil((y1 - y0) / RES - 1e-9) * RES))
    assert layout.start[:2] == pytest.approx(_map_point(2.0, 1.5)) and layout.start[2] == pytest.approx(ORIGIN[2] + 0.3)
    assert layout.goal == pytest.approx(_map_point(8.0, 1.5))
    cells = _site_pixels()[::-1].T  # [ix, iy]
    walls = cells != 254
    from scipy import ndimage

    clear = ndimage.distance_transform_edt(~walls) >= 2.5  # two cells and more from any wall pixel
    for ix, iy in np.argwhere(walls):  # the wall, the borders, the unknown corner
        px, py = _map_point((ix + 0.5) * RES, (iy + 0.5) * RES)
        assert float(layout.clearance(np.array(px), np.array(py))) <= 0.0, (ix, iy)
    rng = np.random.default_rng(0)
    free = np.argwhere(clear)
    for ix, iy in free[rng.choice(len(free), 200, replace=False)]:
        px, py = _map_point((ix + 0.5) * RES, (iy + 0.5) * RES)
        assert float(layout.clearance(np.array(px), np.array(py))) > 0.0, (ix, iy)
    # beyond the image's edge (map frame) but inside the bounding floor: wall
    px, py = _map_point(-0.3, 3.5)
    assert layout.on_floor(px, py) and float(layout.clearance(np.array(px), np.array(py))) <= 0.0


def test_hand_made_map_driven_by_pid_astar(site):
    env = gym.make("bulletnav/Warehouse-v0", world=str(site))
    try:
        goals = []
        results = run_episodes(env, Navigator(env.unwrapped.scene, NavigatorConfig(planner="astar")), 1, seed=7,
                               on_reset=lambda e, info: goals.append(info["goal"]))
    finally:
        env.close()
    assert results[0].success and not results[0].collision
    assert tuple(goals[0]) == pytest.approx(_map_point(8.0, 1.5))  # the goal the YAML gives, in its frame
    # round the wall (x = 4.8-5.2 m from the corner, up to y = 4.5 m): far longer than the straight 6 m
    assert results[0].shortest_path > 8.0


# ----------------------------------------------------------------------------- a hand-written Gazebo world

WORLD = """<?xml version="1.0" ?>
<sdf version="1.9">
  <world name="hand_site">
    <include><uri>model://ground_plane</uri></include>
    <include><uri>model://sun</uri></include>
    <model name="walls">
      <static>true</static>
      <pose>10 20 0 0 0 0</pose>
      <link name="outer">
        <collision name="south"><pose>0 -3.5 1 0 0 0</pose><geometry><box><size>10 0.2 2</size></box></geometry></collision>
        <collision name="north"><pose>0 3.5 1 0 0 0</pose><geometry><box><size>10 0.2 2</size></box></geometry></collision>
        <collision name="west"><pose>-5 0 1 0 0 1.570796326795</pose><geometry><box><size>7 0.2 2</size></box></geometry></collision>
        <collision name="east"><pose degrees="true">5 0 1 0 0 90</pose><geometry><box><size>7 0.2 2</size></box></geometry></collision>
        <visual name="look"><geometry><mesh><uri>walls.dae</uri></mesh></geometry></visual>
      </link>
      <link name="divider">
        <pose>0 -1 0 0 0 0</pose>
        <collision name="c"><pose>0 0 0.75 0 0 0</pose><geometry><box><size>0.3 5 1.5</size></box></geometry></collision>
      </link>
    </model>
    <model name="pillar">
      <static>true</static>
      <pose relative_to="walls">-2.5 2 0 0 0 0</pose>
      <link name="l"><collision name="c"><pose>0 0 1.5 0 0 0</pose>
        <geometry><cylinder><radius>0.25</radius><length>3</length></cylinder></geometry></collision></link>
    </model>
    <model name="crate">
      <pose>13 21 0.3 1.5707963267948966 0 0.4</pose>
      <link name="l"><collision name="c"><geometry><box><size>0.8 0.6 0.5</size></box></geometry></collision></link>
    </model>
  </world>
</sdf>
"""


def test_sdf_poses_compose(tmp_path):
    path = tmp_path / "hand.world"
    path.write_text(WORLD)
    layout = load_layout(path)
    # the shapes' extent: x 4.9..15.1 (the west/east walls 0.2 thick), y 16.4..23.6; grown 1 m each side
    assert layout.size == pytest.approx((10.2 + 2, 7.2 + 2))
    assert layout.corner == pytest.approx((4.9 - 1.0, 16.4 - 1.0))  # the world's own frame
    by = {(o.label, round(o.center[0], 6), round(o.center[1], 6)): o for o in layout.obstacles}
    assert len(layout.obstacles) == 7
    west, east = by[("walls", 5.0, 20.0)], by[("walls", 15.0, 20.0)]  # 1.570796326795 rad and 90 degrees
    assert east.yaw == pytest.approx(math.pi / 2) and west.yaw == pytest.approx(math.pi / 2)
    assert west.size == pytest.approx((7, 0.2, 2))
    divider = by[("walls", 10.0, 19.0)]
    assert divider.size == pytest.approx((0.3, 5, 1.5)) and divider.yaw == pytest.approx(0.0)
    pillar = by[("pillar", 7.5, 22.0)]  # relative_to="walls": (10 - 2.5, 20 + 2)
    assert pillar.kind == "cylinder" and pillar.radius == 0.25 and pillar.height == pytest.approx(3.0)
    # roll 90 deg turns the crate's y axis (0.6) upright: footprint 0.8 x 0.5, top at 0.3 + 0.3, heading 0.4
    crate = by[("crate", 13.0, 21.0)]
    assert crate.size == pytest.approx((0.8, 0.5, 0.6)) and crate.yaw == pytest.approx(0.4)


def test_sdf_state_is_applied_as_gazebo_loads_it(tmp_path):
    # a world saved from Gazebo: <state> poses (world frame) replace the models' own, <insertions> are
    # built, <deletions> are not; SDF 1.6's <pose frame=''> is the parent frame
    box = SHAPE.format("<box><size>1 2 1</size></box>")
    cyl = "<link name='l'><pose frame=''>0 0 0.5 0 0 0</pose><collision name='c'><geometry><cylinder><radius>0.2</radius>" \
          "<length>1</length></cylinder></geometry></collision></link>"
    path = _world(tmp_path, f"<model name='moved'><pose frame=''>0 0 0.5 0 0 0</pose>{box}</model>"
                            f"<model name='gone'><pose>9 9 0.5 0 0 0</pose>{box}</model>"
                            "<state world_name='w'><model name='moved'><pose frame=''>4 1 0.5 0 0 0.3</pose>"
                            "<link name='l'><pose frame=''>4 1 0.5 0 0 0.3</pose></link></model>"
                            f"<insertions><model name='added'><pose>1 3 0 0 0 0</pose>{cyl}</model></insertions>"
                            "<deletions><name>gone</name></deletions></state>")
    layout = load_layout(path)
    placed = {o.label: (o.center, o.yaw) for o in layout.obstacles}
    assert sorted(placed) == ["added", "moved"]
    assert placed["moved"][0] == pytest.approx((4.0, 1.0)) and placed["moved"][1] == pytest.approx(0.3)
    assert placed["added"][0] == pytest.approx((1.0, 3.0))


def test_hand_written_world_driven_by_pid_astar(tmp_path):
    (tmp_path / "hand.world").write_text(WORLD)
    (tmp_path / "run.yaml").write_text("map: hand.world\nstart: [7.0, 18.0, 0.0]\ngoal: [12.5, 18.0]\nmargin: 0.5\n")
    layout = load_layout(tmp_path / "run.yaml")
    assert layout.start == (7.0, 18.0, 0.0) and layout.goal == (12.5, 18.0)  # the world's frame, as given
    env = gym.make("bulletnav/Warehouse-v0", world=str(tmp_path / "run.yaml"))
    try:
        results = run_episodes(env, Navigator(env.unwrapped.scene, NavigatorConfig(planner="astar")), 1, seed=3)
    finally:
        env.close()
    # the divider (x = 10, y 16.5..21.5 in the world) stands between: the path goes round its north end
    assert results[0].success and not results[0].collision
    assert results[0].shortest_path > 8.0


def test_fleet_runs_in_a_hand_made_map_with_stations_in_its_frame(site, tmp_path):
    """``fleet --world`` takes a user's map: stations given in the map's frame (as start and goal are)
    stay where they are given (the world is in the map's frame); a Gazebo world, which has no racks
    and no place for stations, is refused naming what to add."""
    from bulletnav.errors import ConfigError
    from bulletnav.fleet import fleet_v0

    pick, drop = _map_point(2.0, 5.5), _map_point(8.0, 1.5)  # left of the wall, top; right of it, bottom
    (tmp_path / "fleet.yaml").write_text(f"map: site.yaml\nstations:\n  pick: [[{pick[0]!r}, {pick[1]!r}]]\n"
                                         f"  drop: [[{drop[0]!r}, {drop[1]!r}]]\n")
    env = fleet_v0.parallel_env(num_robots=2, world=str(tmp_path / "fleet.yaml"), duration_s=2.0)
    try:
        obs, infos = env.reset(seed=4)
        stations = env.unwrapped.stations
        assert list(stations.pick) == [pytest.approx(pick)] and list(stations.drop) == [pytest.approx(drop)]
        for _ in range(5):
            obs, _, _, _, infos = env.step({a: np.zeros(2, dtype=np.float32) for a in env.agents})
        assert len(obs) == 2
    finally:
        env.close()
    (tmp_path / "hand.world").write_text(WORLD)
    with pytest.raises(ConfigError, match="hand.world has no pick stations.*name them"):
        fleet_v0.parallel_env(num_robots=2, world=str(tmp_path / "hand.world")).reset(seed=0)


# ----------------------------------------------------------------------------- refusals, one line each


def _refused(path: Path, *needles: str) -> str:
    with pytest.raises(LayoutError) as err:
        load_layout(path)
    message = str(err.value)
    assert "\n" not in message and str(path).split(" ")[0] in message
    for needle in needles:
        assert needle in message, message
    return message


SHAPE = "<link name='l'><collision name='c'><geometry>{}</geometry></collision></link>"


def _world(tmp_path: Path, body: str, name: str = "w.world") -> Path:
    path = tmp_path / name
    path.write_text(f"<?xml version='1.0'?><sdf version='1.9'><world name='w'>{body}</world></sdf>")
    return path


def test_sdf_refusals_name_the_file_and_model(tmp_path):
    box = "<box><size>1 1 1</size></box>"
    _refused(_world(tmp_path, f"<model name='robot_arm'>{SHAPE.format('<mesh><uri>arm.stl</uri></mesh>')}</model>"),
             "model 'robot_arm'", "<mesh>")
    _refused(_world(tmp_path, "<include><uri>model://warehouse_shelf</uri><name>shelf_3</name></include>"),
             "include 'shelf_3'", "model://warehouse_shelf")
    _refused(_world(tmp_path, f"<model name='ball'>{SHAPE.format('<sphere><radius>1</radius></sphere>')}</model>"),
             "model 'ball'", "<sphere>")
    _refused(_world(tmp_path, f"<model name='ramp'><pose>0 0 0 0.3 0 0</pose>{SHAPE.format(box)}</model>"),
             "model 'ramp'", "tilted")
    plane = "<plane><normal>1 0 0</normal><size>5 5</size></plane>"
    _refused(_world(tmp_path, f"<model name='wallplane'>{SHAPE.format(plane)}</model>"), "model 'wallplane'", "plane")
    _refused(_world(tmp_path, f"<model name='outer'><model name='inner'>{SHAPE.format('<mesh/>')}</model></model>"),
             "model 'outer::inner'")
    _refused(_world(tmp_path, f"<model name='m'><pose relative_to='nowhere'>0 0 0 0 0 0</pose>{SHAPE.format(box)}</model>"),
             "model 'm'", "'nowhere'")
    _refused(_world(tmp_path, "<model name='flat'><static>true</static></model>"), "no box or cylinder")
    doctype = tmp_path / "dt.world"
    doctype.write_text("<?xml version='1.0'?><!DOCTYPE sdf [<!ENTITY big 'xxxxxxxx'>]><sdf><world name='w'>"
                       "<model name='m'><link name='l'/></model></world></sdf>")
    _refused(doctype, "DOCTYPE", "never expands entities")
    # the same in UTF-16 (a byte search for "<!ENTITY" does not see it): refused, not expanded into the name
    utf16 = tmp_path / "utf16.world"
    utf16.write_bytes("<?xml version='1.0' encoding='UTF-16'?><!DOCTYPE sdf [<!ENTITY n 'expanded'>]><sdf>"
                      "<world name='&n;'><model name='m'><link name='l'/></model></world></sdf>".encode("utf-16"))
    _refused(utf16, "<!DOCTYPE> declaration at line 1", "never expands entities")
    utf16le = tmp_path / "utf16le.world"  # no byte-order mark, the entity declared after a comment
    utf16le.write_bytes("<!-- x --><!DOCTYPE sdf [<!ENTITY n 'expanded'>]><sdf><world name='&n;'/></sdf>".encode("utf-16-le"))
    _refused(utf16le, "DOCTYPE")
    entity = tmp_path / "ent.sdf"  # an entity declaration outside a DTD is not XML at all
    entity.write_text("<sdf><!ENTITY x 'y'><world name='w'/></sdf>")
    _refused(entity, "not well-formed XML")
    sjis = tmp_path / "sjis.world"  # a multi-byte encoding Expat cannot read: one line, not a ValueError's traceback
    sjis.write_bytes(b"<?xml version='1.0' encoding='shift_jis'?><sdf><world name='w'/></sdf>")
    _refused(sjis, "an encoding bulletnav cannot read", "save it as UTF-8")
    deep = tmp_path / "deep.world"  # 3,000 nested models: one line, not a RecursionError
    deep.write_text("<sdf><world name='w'>" + "<model name='m'>" * 3000 + "</model>" * 3000 + "</world></sdf>")
    _refused(deep, "elements nested more than 100 deep")
    broken = tmp_path / "broken.world"
    broken.write_text("<sdf><world name='w'><model name='m'></world></sdf>")
    _refused(broken, "not well-formed XML")


def test_map_server_refusals_name_the_file_and_field(tmp_path):
    _pgm(tmp_path / "m.pgm", np.full((40, 40), 254))
    cases = {
        "resolution: 0\n": ("field 'resolution'", "0"),
        "resolution: -0.1\n": ("field 'resolution'", "-0.1"),
        "resolution: abc\n": ("field 'resolution'", "abc"),
    }
    base = "origin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    for i, (line, needles) in enumerate(cases.items()):
        path = tmp_path / f"bad{i}.yaml"
        path.write_text("image: m.pgm\n" + line + base)
        _refused(path, *needles)
    missing = tmp_path / "missing.yaml"
    missing.write_text("image: nothere.pgm\nresolution: 0.1\n" + base)
    _refused(missing, "field 'image'", "nothere.pgm", "does not exist")
    for text, needles in (("image: m.pgm\nresolution: 0.1\n" + base.replace("negate: 0", "negate: 2"), ("field 'negate'",)),
                          ("image: m.pgm\nresolution: 0.1\n" + base + "mode: fancy\n", ("field 'mode'", "fancy")),
                          ("image: m.pgm\nresolution: 0.1\n" + base.replace("origin: [0, 0, 0]", "origin: [0, 0]"),
                           ("field 'origin'",)),
                          ("image: m.pgm\nresolution: 0.1\n" + base + "unknown: maybe\n", ("field 'unknown'", "maybe")),
                          ("image: m.pgm\nresolution: 0.01\n" + base, ("over 2 m",)),
                          ("image: m.pgm\nresolution: 0.1\n" + base + "start: [0.05, 1, 0]\n", ("field 'start' [0.05, 1]", "wall")),
                          ("image: m.pgm\nresolution: 0.1\n" + base + "goal: [9, 1]\n", ("field 'goal' [9, 1]", "outside"))):
        path = tmp_path / "case.yaml"
        path.write_text(text)
        _pgm(tmp_path / "m.pgm", np.pad(np.full((38, 38), 254), 1))
        _refused(path, *needles)
    notimage = tmp_path / "junk.yaml"
    (tmp_path / "junk.pgm").write_bytes(b"not an image")
    notimage.write_text("image: junk.pgm\nresolution: 0.1\n" + base)
    _refused(notimage, "field 'image'", "junk.pgm", "not a readable")
    wrapper = tmp_path / "wrap.yaml"
    wrapper.write_text("map: gone.world\n")
    _refused(wrapper, "field 'map'", "gone.world")


def test_hostile_map_server_maps_are_refused_in_one_line_before_the_work_grows(tmp_path):
    """Each refused by name: an image outside the YAML's folder (absolute or climbing), with the
    same message whether the file exists or not; an origin or wall height past any site; a PGM
    whose header claims 10^10 pixels (the project's limit, before Pillow's bomb check); a 5 kB
    checkerboard PNG of 2048^2 cells, whose walls would merge into 2 M boxes (refused from its
    first row's runs, before any merge)."""
    base = "resolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    inner = tmp_path / "maps"
    inner.mkdir()
    _pgm(tmp_path / "outside.pgm", np.full((40, 40), 254))
    messages = []
    for image in (str(tmp_path / "outside.pgm"), "../outside.pgm", "../nothere.pgm", "/etc/passwd"):
        path = inner / "m.yaml"
        path.write_text(f"image: {image}\n" + base)
        messages.append(_refused(path, "field 'image' must name a file in the map YAML's folder or below it"))
    assert len({m.replace(m.split("got ")[-1], "") for m in messages}) == 1  # nothing says whether it exists
    _pgm(inner / "m.pgm", np.pad(np.full((38, 38), 254), 1))
    absolute = inner / "abs.yaml"  # ROS 1's map_saver -f /abs/stem writes the image's absolute path: inside, so fine
    absolute.write_text(f"image: {inner / 'm.pgm'}\n" + base)
    assert load_layout(absolute).size == pytest.approx((4.0, 4.0))
    for text, needles in (("image: m.pgm\n" + base.replace("origin: [0, 0, 0]", "origin: [1.0e+300, 0, 0]"),
                           ("field 'origin'", "within 1e+06 m")),
                          ("image: m.pgm\n" + base + "height: 1.0e+300\n", ("field 'height'", "at most 100 m"))):
        path = inner / "far.yaml"
        path.write_text(text)
        _refused(path, *needles)
    (inner / "bomb.pgm").write_bytes(b"P5\n100000 100000\n255\n" + bytes(64))
    bomb = inner / "bomb.yaml"
    bomb.write_text("image: bomb.pgm\n" + base)
    _refused(bomb, "image bomb.pgm pixels = 10000000000 exceeds the limit 16777216", "BULLETNAV_MAX_MAP_CELLS")
    from PIL import Image

    board = ((np.indices((2048, 2048)).sum(axis=0) % 2) * 254).astype(np.uint8)
    Image.fromarray(board).save(inner / "board.png", optimize=True)
    assert (inner / "board.png").stat().st_size < 20_000
    checker = inner / "board.yaml"
    checker.write_text("image: board.png\n" + base.replace("resolution: 0.1", "resolution: 0.01"))
    _refused(checker, "more than 1000 boxes", "BULLETNAV_MAX_OBSTACLES")


def test_a_map_yamls_typos_are_map_typos_and_an_image_or_model_as_a_world_says_what_belongs(tmp_path):
    """A YAML with ``image:`` is a map: a misspelt field is named as map_server's with the
    nearest (it fell through to the layout parser, which called every valid field unknown). The
    map's picture given as the world names the YAML beside it; a saved model names --model."""
    _pgm(tmp_path / "site.pgm", np.pad(np.full((38, 38), 254), 1))
    base = "origin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    typo = tmp_path / "site.yaml"
    typo.write_text("image: site.pgm\nresolutoin: 0.1\n" + base)
    _refused(typo, "unknown map field 'resolutoin' (did you mean 'resolution'?)")
    missing = tmp_path / "short.yaml"
    missing.write_text("image: site.pgm\n" + base)
    _refused(missing, "field 'resolution' is missing")
    _refused(tmp_path / "site.pgm", "site.pgm: an image, not a world: give the map's YAML (site.yaml beside it)")
    alone = tmp_path / "alone"
    alone.mkdir()
    Path(alone / "plan.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(32))
    _refused(alone / "plan.png", "an image, not a world", "the .yaml beside it that names plan.png")
    model = tmp_path / "policy.zip"
    model.write_bytes(b"PK\x03\x04" + bytes(30))
    _refused(model, "a zip archive (a saved model?), not a world: a model goes to --model")


def test_navigate_cli_refuses_a_mesh_world_in_one_line(tmp_path, capsys):
    path = _world(tmp_path, f"<model name='robot_arm'>{SHAPE.format('<mesh><uri>arm.stl</uri></mesh>')}</model>")
    assert main(["navigate", "--world", str(path), "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("bulletnav navigate: error:") and "robot_arm" in err and str(path) in err


# ----------------------------------------------------------------------------- fuzz: only a LayoutError escapes

MAP_DOC = {"image": "m.pgm", "resolution": 0.1, "origin": [0.0, 0.0, 0.0], "negate": 0, "occupied_thresh": 0.65,
           "free_thresh": 0.196, "mode": "trinary", "start": [1.0, 1.0, 0.0], "goal": [3.0, 3.0], "unknown": "free"}


def _only_layout_errors(path: Path) -> None:
    try:
        load_layout(path)
    except LayoutError as exc:
        assert str(path.name) in str(exc) and "\n" not in str(exc), str(exc)


@pytest.mark.slow  # as test_fuzz's file properties: make test runs it, make check leaves it out
def test_mutated_maps_and_worlds_load_or_fail_with_a_layout_error(tmp_path):
    """Mutated map YAMLs (fuzz_strategies' edits) beside a good PGM, and SDF text with bytes
    flipped, cut or repeated: each loads or fails with one LayoutError line naming the file."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    from fuzz_strategies import examples, mutated

    _pgm(tmp_path / "m.pgm", np.pad(np.full((38, 38), 254), 1))
    world = WORLD.encode()

    @settings(max_examples=examples(25), deadline=None, suppress_health_check=list(HealthCheck))
    @given(mutated(st.just(MAP_DOC)), st.lists(st.tuples(st.integers(0, len(world) - 1), st.integers(0, 255)), max_size=4),
           st.integers(0, len(world)))
    def check(doc, flips, cut):
        import yaml

        path = tmp_path / "map.yaml"
        path.write_text(yaml.safe_dump(doc))
        _only_layout_errors(path)
        data = bytearray(world[:cut] + world[cut // 2:])  # a cut and a repeat
        for i, b in flips:
            data[i % len(data)] = b
        path = tmp_path / "fuzz.world"
        path.write_bytes(bytes(data))
        _only_layout_errors(path)

    check()
