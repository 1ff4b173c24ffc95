"""Convert the BARN challenge's own files into bulletnav's compact BARN data (run once).

    git clone https://github.com/Daffan/the-barn-challenge /tmp/barn
    python scripts/convert_barn.py /tmp/barn --commit "$(git -C /tmp/barn rev-parse HEAD)"

Reads ``jackal_helper/worlds/BARN/world_N.world`` (N = 0-299) with the package's SDF reader
(:func:`bulletnav.sim.sdf.read_shapes`: every collision placed as Gazebo places it), each shape
checked to be a ``unit_cylinder`` of 0.075 m radius and 1 m length standing on the floor;
``jackal_helper/worlds/BARN/path_files/path_N.npy`` (``numpy.load(allow_pickle=False)``:
2-column integer arrays), ``res/dwa_out.txt`` and
``LICENSE``; writes ``bulletnav/assets/barn/barn.npz`` (format in :mod:`bulletnav.barn.data`),
``dwa_out.txt`` and ``LICENSE`` (both verbatim). The attribution README beside them is kept
by hand.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bulletnav import files
from bulletnav.barn.data import N_WORLDS
from bulletnav.barn.metric import CYLINDER_RADIUS_M
from bulletnav.errors import LayoutError
from bulletnav.sim.sdf import read_shapes

OUT = Path(__file__).resolve().parent.parent / "bulletnav" / "assets" / "barn"
RADIUS = CYLINDER_RADIUS_M  # m, every BARN cylinder
LENGTH = 1.0  # m


def _um(metres: float, where: str) -> int:
    """A metre value as integer micrometres, refusing one that is not a whole number of them (the
    world files write 6 decimals)."""
    um = metres * 1e6
    if abs(um - round(um)) > 1e-3:
        raise SystemExit(f"convert_barn: {where}: {metres!r} m is not a whole number of micrometres")
    return round(um)


def read_world(path: Path) -> np.ndarray:
    """The cylinder centres (n x 2, micrometres) of one BARN world file, in file order, as the
    package's SDF reader builds it (:func:`bulletnav.sim.sdf.read_shapes`: Gazebo's placement,
    the world's ``<state>`` applied), each checked to be an upright 0.075 m-radius, 1 m cylinder
    standing on the floor (its centre at z = 0, as BARN's are)."""
    try:
        shapes, _ground, _name = read_shapes(path)
    except LayoutError as exc:
        raise SystemExit(f"convert_barn: {exc}") from None
    centres = []
    for shape in shapes:
        who = f"{path.name}: model {shape.model!r}"
        if not shape.model.startswith("unit_cylinder_") or shape.kind != "cylinder":
            raise SystemExit(f"convert_barn: {who} is not a unit cylinder")
        radius, length = shape.size[0] / 2, shape.top - shape.bottom
        if (radius, length) != (RADIUS, LENGTH):
            raise SystemExit(f"convert_barn: {who} has radius {radius}, length {length}")
        if (shape.bottom, shape.top) != (-LENGTH / 2, LENGTH / 2):
            raise SystemExit(f"convert_barn: {who} is raised: from z = {shape.bottom} to {shape.top} m")
        centres.append((_um(shape.center[0], f"{who} x"), _um(shape.center[1], f"{who} y")))
    return np.asarray(centres, dtype=np.int32).reshape(-1, 2)


def read_path(path: Path) -> np.ndarray:
    """One reference path's grid cells (k x 2), loaded without unpickling."""
    cells = np.load(path, allow_pickle=False)
    if cells.ndim != 2 or cells.shape[1] != 2 or cells.dtype.kind not in "iu" or len(cells) == 0:
        raise SystemExit(f"convert_barn: {path.name}: not a k x 2 integer array: {cells.dtype} {cells.shape}")
    if cells.min() < np.iinfo(np.int16).min or cells.max() > np.iinfo(np.int16).max:
        raise SystemExit(f"convert_barn: {path.name}: cells outside int16")
    return cells.astype(np.int16)


def convert(barn: Path, commit: str, out: Path = OUT) -> dict[str, int]:
    """Convert the BARN checkout ``barn`` into ``out``; returns counts for the log line."""
    worlds = barn / "jackal_helper" / "worlds" / "BARN"
    cylinders = [read_world(worlds / f"world_{i}.world") for i in range(N_WORLDS)]
    paths = [read_path(worlds / "path_files" / f"path_{i}.npy") for i in range(N_WORLDS)]
    arrays = {
        "cylinders_um": np.concatenate(cylinders),
        "cylinder_offsets": np.cumsum([0] + [len(c) for c in cylinders]).astype(np.int32),
        "path_cells": np.concatenate(paths),
        "path_offsets": np.cumsum([0] + [len(p) for p in paths]).astype(np.int32),
        "source": np.array(f"github.com/Daffan/the-barn-challenge@{commit}"),
    }
    out.mkdir(parents=True, exist_ok=True)
    files.write_with(out / "barn.npz", lambda f: np.savez_compressed(f, **arrays))
    files.write_bytes(out / "dwa_out.txt", (barn / "res" / "dwa_out.txt").read_bytes())
    files.write_bytes(out / "LICENSE", (barn / "LICENSE").read_bytes())
    return {"cylinders": len(arrays["cylinders_um"]), "path_cells": len(arrays["path_cells"]),
            "bytes": (out / "barn.npz").stat().st_size}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("barn", type=Path, help="a checkout of github.com/Daffan/the-barn-challenge")
    parser.add_argument("--commit", required=True, help="the checkout's commit (recorded in barn.npz)")
    parser.add_argument("--out", type=Path, default=OUT, help="output folder (default: %(default)s)")
    args = parser.parse_args(argv)
    counts = convert(args.barn, args.commit, args.out)
    sys.stdout.write(f"convert_barn: {N_WORLDS} worlds, {counts['cylinders']} cylinders, "
                     f"{counts['path_cells']} path cells, barn.npz {counts['bytes']} bytes -> {args.out}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
