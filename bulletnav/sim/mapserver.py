"""ROS ``map_server`` / Nav2 occupancy maps: a ``map.yaml`` with its PGM or PNG image, read into
cell values exactly as Nav2 reads them, merged into boxes, and written from bulletnav's maps.

Reading follows Nav2's ``nav2_map_server/src/map_io.cpp`` (``loadMapYaml``, ``loadMapFromFile``):
a pixel's ``shade`` is the mean of its red, green and blue values on [0, 1] (in trinary mode the
alpha value is averaged in as a fourth channel when the image has one); ``occ = shade`` when
``negate`` is set, else ``1 - shade``; then

- ``trinary``: ``occ > occupied_thresh`` is occupied (100), ``occ < free_thresh`` free (0),
  anything else unknown (-1);
- ``scale``: a pixel that is not fully opaque is unknown; then occupied and free as in trinary;
  between them ``rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100)``;
- ``raw``: ``round(shade * 255)`` when it lies in [0, 100] (``negate`` is not applied), else unknown.

Image row 0 is the top of the map: cell (x, y) of the grid is pixel (x, height - 1 - y), and
``origin`` (x, y, yaw) is the pose of the lower-left pixel's lower-left corner in the map frame.

Writing (:func:`write_map`) follows Nav2's ``map_saver`` in trinary mode: occupied 0, free 254,
unknown 205, ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav import files, limits
from bulletnav.errors import LayoutError, LimitError
from bulletnav.yamlfile import show

OCCUPIED, FREE, UNKNOWN = 100, 0, -1
"""Cell values of a ``nav_msgs/OccupancyGrid`` (scale and raw modes give 1-99 too)."""
MODES = ("trinary", "scale", "raw")
KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")
"""The keys Nav2's ``loadMapYaml`` reads (all but ``mode`` required, as there)."""
IMAGE_FORMATS = ("PNG", "PPM")
"""Pillow formats an ``image`` may have (PPM covers PGM and PBM)."""
SAVE_OCCUPIED, SAVE_FREE, SAVE_UNKNOWN = 0, 254, 205
"""Pixel values ``map_saver`` writes in trinary mode."""
SAVE_OCCUPIED_THRESH, SAVE_FREE_THRESH = 0.65, 0.196
"""Thresholds :func:`write_map` puts in the YAML (ROS's ``map_saver`` defaults)."""


@dataclass(frozen=True)
class MapMeta:
    """A map YAML's fields (Nav2's ``LoadParameters``)."""

    image: Path
    """The image file (relative paths resolved against the YAML's folder)."""
    resolution: float
    """Cell side (m)."""
    origin: tuple[float, float, float]
    """Pose (x m, y m, yaw rad) of the map's lower-left corner in the map frame."""
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str = "trinary"


def finite(value: float) -> bool:
    """``math.isfinite``, False for an int too large for a float (instead of OverflowError)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def _number(data: dict, key: str, where: str) -> float:
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not finite(value):
        raise LayoutError(f"{where}: field '{key}' must be a finite number, got {show(value)}")
    return float(value)


def read_meta(data: Any, where: str) -> MapMeta:
    """Validate a decoded map YAML (Nav2's required keys and their types).

    Raises:
        LayoutError: naming ``where`` (the file), the field and its value.
    """
    if not isinstance(data, dict):
        raise LayoutError(f"{where}: a map_server map YAML must be a mapping, got {type(data).__name__}")
    for key in KEYS[:-1]:
        if key not in data:
            raise LayoutError(f"{where}: field '{key}' is missing (a map_server map YAML needs {', '.join(KEYS[:-1])})")
    image = data["image"]
    if not isinstance(image, str) or not image.strip():
        raise LayoutError(f"{where}: field 'image' must name the map's image file, got {show(image)}")
    resolution = _number(data, "resolution", where)
    if resolution <= 0:
        raise LayoutError(f"{where}: field 'resolution' must be > 0 m per cell, got {show(data['resolution'])}")
    origin = data["origin"]
    if not isinstance(origin, list) or len(origin) != 3:
        raise LayoutError(f"{where}: field 'origin' must be [x, y, yaw], got {show(origin)}")
    xyz = tuple(_number({"origin": v}, "origin", where) for v in origin)
    negate = data["negate"]
    if negate not in (0, 1) or isinstance(negate, float):  # Nav2 reads an int, else a bool
        raise LayoutError(f"{where}: field 'negate' must be 0 or 1, got {show(negate)}")
    thresholds = {}
    for key in ("occupied_thresh", "free_thresh"):
        thresholds[key] = _number(data, key, where)
        if not 0.0 <= thresholds[key] <= 1.0:
            raise LayoutError(f"{where}: field '{key}' must be in [0, 1], got {show(data[key])}")
    mode = data.get("mode", "trinary")
    if mode not in MODES:
        raise LayoutError(f"{where}: field 'mode' must be one of {', '.join(MODES)}, got {show(mode)}")
    if mode == "scale" and thresholds["occupied_thresh"] <= thresholds["free_thresh"]:
        raise LayoutError(f"{where}: field 'free_thresh' ({thresholds['free_thresh']}) must be below 'occupied_thresh' "
                          f"({thresholds['occupied_thresh']}) in scale mode")
    path = Path(image) if Path(image).is_absolute() else Path(where).parent / image
    return MapMeta(path, resolution, xyz, bool(negate), thresholds["occupied_thresh"], thresholds["free_thresh"],
                   mode)  # type: ignore[arg-type]


def cell_values(rgb: np.ndarray, alpha: np.ndarray | None, meta: MapMeta) -> np.ndarray:
    """Nav2's cell value of every pixel (module docstring).

    Args:
        rgb: ``(H, W, 3)`` red, green, blue on [0, 1] (a grey image: the grey value three times).
        alpha: ``(H, W)`` opacity on [0, 1] (1 opaque), or None for an image without alpha.
        meta: thresholds, ``negate`` and ``mode``.

    Returns:
        ``(H, W)`` int8 in image order (row 0 the top): 100 occupied, 0 free, -1 unknown, 1-99 (scale, raw).
    """
    channels = [rgb[..., 0], rgb[..., 1], rgb[..., 2]]
    if meta.mode == "trinary" and alpha is not None:
        channels.append(alpha)
    shade = sum(channels) / len(channels)
    if meta.mode == "raw":
        level = np.floor(shade * 255.0 + 0.5)  # std::round: halves away from zero (all values >= 0)
        return np.where((level >= FREE) & (level <= OCCUPIED), level, UNKNOWN).astype(np.int8)
    occ = shade if meta.negate else 1.0 - shade
    out = np.full(occ.shape, UNKNOWN, dtype=np.int8)
    if meta.mode == "scale":
        span = meta.occupied_thresh - meta.free_thresh
        out = np.clip(np.rint((occ - meta.free_thresh) / span * 100.0), UNKNOWN, OCCUPIED).astype(np.int8)
    out[occ < meta.free_thresh] = FREE
    out[meta.occupied_thresh < occ] = OCCUPIED
    if meta.mode == "scale" and alpha is not None:
        out[alpha != 1.0] = UNKNOWN
    return out


def read_image(meta: MapMeta, where: str) -> tuple[np.ndarray, np.ndarray | None]:
    """The image's red, green, blue (and alpha, if it has one) on [0, 1], as :func:`cell_values` takes them.

    Raises:
        LayoutError: the image is missing, not PGM/PPM/PBM or PNG, or unreadable.
        LimitError: its pixels pass the limit ``map_cells`` (checked before it is decoded).
    """
    from PIL import Image, UnidentifiedImageError

    if not meta.image.is_file():
        raise LayoutError(f"{where}: field 'image' names {meta.image}, which does not exist")
    try:
        with Image.open(meta.image, formats=IMAGE_FORMATS) as img:
            width, height = img.size
            try:
                limits.check("map_cells", width * height, f"{where}: image {meta.image.name} pixels")
            except LimitError as exc:
                raise LayoutError(str(exc)) from None
            if width == 0 or height == 0:
                raise LayoutError(f"{where}: field 'image' names {meta.image}, an empty image")
            mode = img.mode
            if mode.startswith("I;16") or mode == "I":
                grey = np.asarray(img, dtype=np.float64) / 65535.0
                return np.repeat(grey[..., None], 3, axis=2), None
            if mode in ("P", "PA"):
                img = img.convert("RGBA" if mode == "PA" or "transparency" in img.info else "RGB")
            elif mode == "1":
                img = img.convert("L")
            elif mode not in ("L", "LA", "RGB", "RGBA"):
                img = img.convert("RGBA" if "A" in mode else "RGB")
            pixels = np.asarray(img, dtype=np.float64) / 255.0
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise LayoutError(f"{where}: field 'image' names {meta.image}, not a readable PGM or PNG image ({exc})") from None
    if pixels.ndim == 2:
        return np.repeat(pixels[..., None], 3, axis=2), None
    if pixels.shape[2] == 2:  # grey + alpha
        return np.repeat(pixels[..., :1], 3, axis=2), pixels[..., 1]
    return pixels[..., :3], (pixels[..., 3] if pixels.shape[2] == 4 else None)


def read_grid(data: Any, where: str) -> tuple[MapMeta, np.ndarray]:
    """A map YAML's metadata and its grid ``[ix, iy]`` of cell values (iy = 0 the bottom row).

    Raises:
        LayoutError: a field or the image is wrong (named in the message).
    """
    meta = read_meta(data, where)
    rgb, alpha = read_image(meta, where)
    return meta, np.ascontiguousarray(cell_values(rgb, alpha, meta)[::-1].T)


def merge_boxes(occupied: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Cover the True cells of ``occupied[ix, iy]`` exactly with few axis-aligned rectangles.

    Runs of True cells along one axis are merged with the identical runs of the next rows;
    this is done along x and along y, and the cover with fewer rectangles is kept. The
    rectangles do not overlap.

    Returns:
        ``(i0, j0, i1, j1)`` per rectangle: cells ``i0 <= ix < i1``, ``j0 <= iy < j1``.
    """
    by_rows = _merge_runs(occupied.T)  # runs along x, stacked along y
    by_cols = _merge_runs(occupied)  # runs along y, stacked along x
    if len(by_cols) < len(by_rows):
        return by_cols  # rows of occupied are ix: (i0, j0, i1, j1) already
    return [(i0, j0, i1, j1) for j0, i0, j1, i1 in by_rows]


def _merge_runs(grid: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Rectangles (r0, c0, r1, c1) over ``grid[r, c]``: runs along c in row r, merged down the rows."""
    rows, cols = grid.shape
    padded = np.zeros((rows, cols + 2), dtype=np.int8)
    padded[:, 1:-1] = grid
    step = np.diff(padded, axis=1)
    starts = np.argwhere(step == 1)  # (row, first column), row-major: rows in order, runs left to right
    ends = np.argwhere(step == -1)[:, 1]  # one past each run's last column, in the same order
    boxes: list[list[int]] = []
    open_runs: dict[tuple[int, int], int] = {}  # (c0, c1) -> index of the box that ended on the row before
    for (r, c0), c1 in zip(starts.tolist(), ends.tolist()):
        key = (c0, c1)
        k = open_runs.get(key)
        if k is not None and boxes[k][2] == r:
            boxes[k][2] = r + 1
        else:
            open_runs[key] = len(boxes)
            boxes.append([r, c0, r + 1, c1])
    return [tuple(b) for b in boxes]  # type: ignore[misc]


def write_map(stem: str | Path, state: np.ndarray, resolution: float, origin: tuple[float, float]) -> tuple[Path, Path]:
    """Write ``STEM.yaml`` and ``STEM.pgm`` as Nav2's ``map_saver`` does in trinary mode.

    Args:
        stem: the output path without suffix.
        state: ``[ix, iy]`` cells: > 0 occupied, 0 free, < 0 unknown (iy = 0 the bottom row).
        resolution: cell side (m).
        origin: (x, y) of the grid's lower-left corner (m); yaw 0.

    Returns:
        The YAML's and the PGM's paths (each written atomically).
    """
    stem = Path(stem)
    yaml_path, pgm_path = stem.with_name(stem.name + ".yaml"), stem.with_name(stem.name + ".pgm")
    pixels = np.where(state > 0, SAVE_OCCUPIED, np.where(state < 0, SAVE_UNKNOWN, SAVE_FREE)).astype(np.uint8)
    image = np.ascontiguousarray(pixels.T[::-1])  # row 0 the top (largest y)
    height, width = image.shape
    files.write_bytes(pgm_path, b"P5\n%d %d\n255\n" % (width, height) + image.tobytes())
    text = (f"image: {pgm_path.name}\nmode: trinary\nresolution: {float(resolution)!r}\n"
            f"origin: [{float(origin[0])!r}, {float(origin[1])!r}, 0.0]\nnegate: 0\n"
            f"occupied_thresh: {SAVE_OCCUPIED_THRESH}\nfree_thresh: {SAVE_FREE_THRESH}\n")
    files.write_text(yaml_path, text)
    return yaml_path, pgm_path


__all__ = ["MapMeta", "cell_values", "merge_boxes", "read_grid", "read_image", "read_meta", "write_map"]
