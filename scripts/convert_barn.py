"""Convert the BARN challenge's own files into bulletnav's compact BARN data (run once).

    git clone https://github.com/Daffan/the-barn-challenge /tmp/barn
    python scripts/convert_barn.py /tmp/barn --commit "$(git -C /tmp/barn rev-parse HEAD)"

Reads ``jackal_helper/worlds/BARN/world_N.world`` (N = 0-299: every ``unit_cylinder`` model's
``<pose>``, checked to be a static 0.075 m-radius, 1 m cylinder, and checked against the same
model in the world's ``<state>``), ``jackal_helper/worlds/BARN/path_files/path_N.npy``
(``numpy.load(allow_pickle=False)``: 2-column integer arrays), ``res/dwa_out.txt`` and
``LICENSE``; writes ``bulletnav/assets/barn/barn.npz`` (format in :mod:`bulletnav.barn.data`),
``dwa_out.txt`` and ``LICENSE`` (both verbatim). The attribution README beside them is kept
by hand.
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from bulletnav import files

OUT = Path(__file__).resolve().parent.parent / "bulletnav" / "assets" / "barn"
N_WORLDS = 300
RADIUS = 0.075  # m, every BARN cylinder
LENGTH = 1.0  # m


def _um(text: str, where: str) -> int:
    """A metre value from the world file as integer micrometres, refusing one that is not exact."""
    um = float(text) * 1e6
    if abs(um - round(um)) > 1e-3:
        raise SystemExit(f"convert_barn: {where}: {text} m is not a whole number of micrometres")
    return round(um)


def _poses(models) -> dict[str, tuple[float, ...]]:
    return {m.get("name"): tuple(float(v) for v in m.find("pose").text.split()) for m in models
            if m.get("name", "").startswith("unit_cylinder_")} if models is not None else {}


def read_world(path: Path) -> np.ndarray:
    """The cylinder centres (n x 2, micrometres) of one BARN world file."""
    return read_world_text(path.read_bytes(), path.name)


def read_world_text(text: bytes, name: str) -> np.ndarray:
    """The cylinder centres (n x 2, micrometres) of a BARN world file's text; ``name`` names it in errors."""
    world = ET.fromstring(text).find("world")
    centres = []
    for model in world.findall("model"):
        model_name = model.get("name")
        if model_name == "ground_plane":
            continue
        cyl = model.find("link/collision/geometry/cylinder")
        if not model_name.startswith("unit_cylinder_") or cyl is None or model.findtext("static") != "1":
            raise SystemExit(f"convert_barn: {name}: model {model_name!r} is not a static unit cylinder")
        radius, length = float(cyl.findtext("radius")), float(cyl.findtext("length"))
        if (radius, length) != (RADIUS, LENGTH):
            raise SystemExit(f"convert_barn: {name}: model {model_name!r} has radius {radius}, length {length}")
        pose = model.findtext("pose").split()
        if any(float(v) != 0.0 for v in pose[2:]):
            raise SystemExit(f"convert_barn: {name}: model {model_name!r} is raised or rotated: {pose}")
        centres.append((_um(pose[0], f"{name} {model_name} x"), _um(pose[1], f"{name} {model_name} y")))
    state = world.find("state")
    declared = _poses(world.findall("model"))
    stated = _poses(state.findall("model") if state is not None else None)
    if stated and stated != declared:
        raise SystemExit(f"convert_barn: {name}: the <state> poses differ from the models' poses")
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
