"""BARN's worlds and reference paths as shipped: checked against BARN's own files.

tests/data/barn/ holds three of BARN's world files and path files verbatim; the cylinder poses
are read here with a regex of the test's own (independent of the converter's XML parser)."""

from __future__ import annotations

import gzip
import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

from bulletnav.barn import data, metric
from bulletnav.errors import LayoutError

DATA = Path(__file__).resolve().parent / "data" / "barn"
ROOT = Path(__file__).resolve().parent.parent
FIXTURE_WORLDS = (0, 1, 299)

# a cylinder model's name, its <static> line, then its <pose>: x y z roll pitch yaw
POSE = re.compile(r"<model name='unit_cylinder_(\d+)'>\s*<static>1</static>\s*<pose frame=''>([-\d.]+) ([-\d.]+) ")


def _text_centres(i: int) -> np.ndarray:
    """World ``i``'s cylinder centres (m) read from the world file's text, in file order."""
    text = gzip.decompress((DATA / f"world_{i}.world.gz").read_bytes()).decode()
    found = POSE.findall(text)
    assert [int(n) for n, _, _ in found] == list(range(len(found)))  # unit_cylinder_0, 1, ... once each
    return np.array([[float(x), float(y)] for _, x, y in found])


def _converter():
    spec = importlib.util.spec_from_file_location("convert_barn", ROOT / "scripts" / "convert_barn.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _world_file(i: int, tmp_path: Path, text: str | None = None) -> Path:
    """BARN world ``i``'s file (or ``text`` in its place) unpacked into ``tmp_path``."""
    path = tmp_path / f"world_{i}.world"
    path.write_text(text if text is not None else gzip.decompress((DATA / f"world_{i}.world.gz").read_bytes()).decode())
    return path


@pytest.mark.parametrize("i", FIXTURE_WORLDS)
def test_shipped_worlds_match_the_world_files_text(i, tmp_path):
    expected = _text_centres(i)
    world = data.load_world(i)
    assert world.index == i and world.cylinders.shape == expected.shape
    np.testing.assert_allclose(world.cylinders, expected, rtol=0, atol=1e-9)
    # the converter's reading of the same file (through the package's SDF reader) gives the same micrometres
    um = _converter().read_world(_world_file(i, tmp_path))
    np.testing.assert_array_equal(um, np.round(expected * 1e6).astype(np.int64))
    # the reference path is BARN's .npy, cell for cell
    np.testing.assert_array_equal(world.path_cells, np.load(DATA / f"path_{i}.npy", allow_pickle=False))


def test_counts_path_endpoints_and_cylinder_size():
    # counts from a regex scan of all 300 BARN world files and path files, made once by hand
    worlds = [data.load_world(i) for i in range(300)]
    counts = [len(w.cylinders) for w in worlds]
    assert (sum(counts), min(counts), max(counts), counts[0], counts[1]) == (78925, 181, 365, 209, 237)
    assert sum(len(w.path_cells) for w in worlds) == 10185
    # path_0.npy: 43 cells from (26, 0) to (18, 29); every path runs from grid row 0 to row 29
    assert len(worlds[0].path_cells) == 43
    assert worlds[0].path_cells[0].tolist() == [26, 0] and worlds[0].path_cells[-1].tolist() == [18, 29]
    assert {int(w.path_cells[0, 1]) for w in worlds} == {0} and {int(w.path_cells[-1, 1]) for w in worlds} == {29}
    # every centre lies on BARN's 0.15 m lattice: x = -0.075 - 0.15 c (c 0-29), y = 0.075 + 0.15 r (r 0-63)
    xy = np.concatenate([w.cylinders for w in worlds])
    c, r = (-xy[:, 0] - 0.075) / 0.15, (xy[:, 1] - 0.075) / 0.15
    np.testing.assert_allclose(c, np.round(c), atol=1e-9)
    np.testing.assert_allclose(r, np.round(r), atol=1e-9)
    assert (c.min(), c.max(), r.min(), r.max()) == pytest.approx((0, 29, 0, 63))
    assert metric.CYLINDER_RADIUS_M == 0.075 and metric.CELL_M == 0.15
    assert data.source().endswith("@bf5a226f6088ec96bf0d2dbee3253a8ea6119b83")
    assert data.DATA_FILE.stat().st_size < 1_000_000


def test_reference_paths_avoid_the_cylinders():
    # BARN's cell-to-metre conversion puts no reference-path cell on a cylinder in any world
    # (a mirrored or shifted conversion would: 979 cells for x mirrored)
    for i in range(300):
        world = data.load_world(i)
        path = metric.path_cells_to_metres(world.path_cells)
        gap = np.hypot(*(path[:, None, :] - world.cylinders[None, :, :]).transpose(2, 0, 1)).min()
        assert gap > 0.1, (i, gap)


def test_path_cells_convert_to_metres_as_barn_does():
    # run.py lines 19-27 by hand: x = 0.15 px - 0.075 - 4.5, y = 0.15 py + 0.075 + 5
    np.testing.assert_allclose(metric.path_cells_to_metres(np.array([[0, 0], [30, 0], [26, 29]])),
                               [[-4.575, 5.075], [-0.075, 5.075], [-0.675, 9.425]], atol=1e-12)


def test_bad_world_index_is_named():
    for bad in (300, -1, 1.5, True, "3"):
        with pytest.raises(LayoutError, match=re.escape(repr(bad))):
            data.load_world(bad)
    assert data.load_world(np.int64(299)).index == 299


def test_converter_refuses_what_it_cannot_convert(tmp_path):
    convert = _converter()
    text = gzip.decompress((DATA / "world_0.world.gz").read_bytes()).decode()
    with pytest.raises(SystemExit, match="unit_cylinder_0.*radius 0.1"):
        convert.read_world(_world_file(0, tmp_path, text.replace("<radius>0.075000</radius>", "<radius>0.1</radius>", 1)))
    with pytest.raises(SystemExit, match="unit_cylinder_0.*raised"):
        convert.read_world(_world_file(0, tmp_path, text.replace("0.075000 0.000000 0.000000", "0.075000 0.300000 0.000000")))
    with pytest.raises(SystemExit, match="world_0.world.*mesh"):
        convert.read_world(_world_file(0, tmp_path, text.replace("<cylinder>", "<mesh>").replace("</cylinder>", "</mesh>")))
    # the world's <state> places a model as Gazebo does (the converter checked it against the
    # model's own pose when it had a parser of its own): a cylinder moved there is converted there
    state = text.index("<state")
    moved = text[:state] + text[state:].replace("-0.075000 0.075000 0.000000", "-0.075000 0.090000 0.000000", 2)
    assert convert.read_world(_world_file(0, tmp_path, moved))[0].tolist() == [-75000, 90000]
    bad = tmp_path / "path_7.npy"
    np.save(bad, np.zeros((3, 3)))
    with pytest.raises(SystemExit, match="path_7.npy"):
        convert.read_path(bad)
