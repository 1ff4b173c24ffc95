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
MAX_ORIGIN = 1.0e6
"""Largest distance (m) of a map's ``origin`` from its frame's origin, along x and y: 1,000 km,
past any site's map (a SLAM run's origin is tens or hundreds of metres off)."""
MAX_ORIGIN_YAW = 1.0e3
"""Largest ``origin`` yaw (rad), as a sanity bound (maps use -pi..pi)."""
ROWS_AT_ONCE = 256
"""Image rows turned into cell values at a time: the float64 arithmetic Nav2 does, on a bounded
slice, so a large image costs its own bytes and not 24 times them."""


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
    if max(abs(xyz[0]), abs(xyz[1])) > MAX_ORIGIN or abs(xyz[2]) > MAX_ORIGIN_YAW:
        raise LayoutError(f"{where}: field 'origin' must be within {MAX_ORIGIN:g} m of the map frame's origin and its "
                          f"yaw within {MAX_ORIGIN_YAW:g} rad, got {show(origin)}")
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
    path = _inside_folder(image, where)
    return MapMeta(path, resolution, xyz, bool(negate), thresholds["occupied_thresh"], thresholds["free_thresh"],
                   mode)  # type: ignore[arg-type]


def _inside_folder(image: str, where: str) -> Path:
    """The image a map YAML names, which must lie in the YAML's folder or below it: a path that
    leads elsewhere (absolute, climbing out with ``..``, or a link out) is refused with the same message
    whether or not the file exists, so a map file cannot read, nor tell whether there is, a
    file elsewhere on the reader's machine."""
    folder = Path(where).parent
    path = Path(image)
    try:  # an absolute path is fine where it points into the folder (ROS 1's map_saver -f /abs/stem writes one)
        inside = (folder / path).resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError, ValueError):  # a link loop, a NUL byte
        inside = False
    if not inside:
        raise LayoutError(f"{where}: field 'image' must name a file in the map YAML's folder or below it, "
                          f"got {show(image)}")
    return folder / path


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


def read_image(meta: MapMeta, where: str) -> tuple[np.ndarray, float]:
    """The image's pixels as stored (uint8; uint16 for a 16-bit grey image, int64 for a 32-bit one): ``(H, W)`` grey,
    or ``(H, W, C)`` with C = 2 (grey, alpha), 3 (RGB) or 4 (RGBA); and the value of full
    intensity (255 or 65535). :func:`read_grid` turns them into cell values a slice at a time.

    Raises:
        LayoutError: the image is missing, not PGM/PPM/PBM or PNG, or unreadable; its pixels pass
            the limit ``map_cells`` (checked from the header, before it is decoded, and before
            Pillow's own decompression-bomb check).
    """
    from PIL import Image, UnidentifiedImageError

    if not meta.image.is_file():
        raise LayoutError(f"{where}: field 'image' names {meta.image}, which does not exist")
    try:
        with _header_only(Image):
            img = Image.open(meta.image, formats=IMAGE_FORMATS)
        with img:
            width, height = img.size
            try:
                limits.check("map_cells", width * height, f"{where}: image {meta.image.name} pixels")
            except LimitError as exc:
                raise LayoutError(str(exc)) from None
            if width == 0 or height == 0:
                raise LayoutError(f"{where}: field 'image' names {meta.image}, an empty image")
            mode = img.mode
            if mode.startswith("I;16") or mode == "I":
                return np.asarray(img, dtype=np.uint16 if mode.startswith("I;16") else np.int64), 65535.0
            if mode in ("P", "PA"):
                img = img.convert("RGBA" if mode == "PA" or "transparency" in img.info else "RGB")
            elif mode == "1":
                img = img.convert("L")
            elif mode not in ("L", "LA", "RGB", "RGBA"):
                img = img.convert("RGBA" if "A" in mode else "RGB")
            return np.asarray(img, dtype=np.uint8), 255.0
    except LayoutError:  # the limit's own message, as it is
        raise
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
        raise LayoutError(f"{where}: field 'image' names {meta.image}, not a readable PGM or PNG image ({exc})") from None


class _header_only:
    """Within: Pillow's decompression-bomb check off, for ``Image.open`` (which reads only the
    header): the project's own limit (``map_cells``) is checked on the size before any pixel is
    decoded, and says which limit and how to raise it."""

    def __init__(self, image_module) -> None:
        self.image = image_module

    def __enter__(self) -> None:
        self.saved = self.image.MAX_IMAGE_PIXELS
        self.image.MAX_IMAGE_PIXELS = None

    def __exit__(self, *exc: object) -> None:
        self.image.MAX_IMAGE_PIXELS = self.saved


def _channels(pixels: np.ndarray, full: float) -> tuple[np.ndarray, np.ndarray | None]:
    """Stored pixels (a slice of rows) as :func:`cell_values` takes them: RGB and alpha on [0, 1]."""
    values = pixels.astype(np.float64) / full
    if values.ndim == 2:
        return np.repeat(values[..., None], 3, axis=2), None
    if values.shape[2] == 2:  # grey + alpha
        return np.repeat(values[..., :1], 3, axis=2), values[..., 1]
    return values[..., :3], (values[..., 3] if values.shape[2] == 4 else None)


def read_grid(data: Any, where: str) -> tuple[MapMeta, np.ndarray]:
    """A map YAML's metadata and its grid ``[ix, iy]`` of cell values (iy = 0 the bottom row),
    computed :data:`ROWS_AT_ONCE` image rows at a time (int8 cells; the float arithmetic on a
    slice only).

    Raises:
        LayoutError: a field or the image is wrong (named in the message).
    """
    meta = read_meta(data, where)
    pixels, full = read_image(meta, where)
    height, width = pixels.shape[:2]
    cells = np.empty((height, width), dtype=np.int8)
    for r0 in range(0, height, ROWS_AT_ONCE):
        rgb, alpha = _channels(pixels[r0:r0 + ROWS_AT_ONCE], full)
        cells[r0:r0 + ROWS_AT_ONCE] = cell_values(rgb, alpha, meta)
    return meta, np.ascontiguousarray(cells[::-1].T)


def merge_boxes(occupied: np.ndarray, most: int | None = None) -> list[tuple[int, int, int, int]] | None:
    """Cover the True cells of ``occupied[ix, iy]`` exactly with few axis-aligned rectangles.

    Runs of True cells along one axis are merged with the identical runs of the next rows;
    this is done along x and along y, and the cover with fewer rectangles is kept. The
    rectangles do not overlap.

    Args:
        most: give up (return None) once both covers need more rectangles than this: each
            merge stops at its ``most + 1``-th rectangle, and a grid one of whose rows (or
            columns) alone holds more runs than this is not merged that way at all (every
            run of a row is a rectangle of its own), so a hostile image costs the limit, not
            its cells.

    Returns:
        ``(i0, j0, i1, j1)`` per rectangle: cells ``i0 <= ix < i1``, ``j0 <= iy < j1``; None
        when both covers need more than ``most``.
    """
    by_rows = _merge_runs(occupied.T, most)  # runs along x, stacked along y
    by_cols = _merge_runs(occupied, most)  # runs along y, stacked along x
    if by_rows is None and by_cols is None:
        return None
    if by_rows is None or (by_cols is not None and len(by_cols) < len(by_rows)):
        return by_cols  # rows of occupied are ix: (i0, j0, i1, j1) already
    return [(i0, j0, i1, j1) for j0, i0, j1, i1 in by_rows]


def _merge_runs(grid: np.ndarray, most: int | None = None) -> list[tuple[int, int, int, int]] | None:
    """Rectangles (r0, c0, r1, c1) over ``grid[r, c]``: runs along c in row r, merged down the
    rows; None once there would be more than ``most``."""
    rows, cols = grid.shape
    padded = np.zeros((rows, cols + 2), dtype=np.int8)
    padded[:, 1:-1] = grid
    step = np.diff(padded, axis=1)
    if most is not None and int((step == 1).sum(axis=1).max(initial=0)) > most:
        return None  # one row's runs alone are more rectangles than allowed
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
            if most is not None and len(boxes) > most:
                return None
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
