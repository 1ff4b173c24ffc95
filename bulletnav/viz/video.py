"""Episode videos: one composed dashboard frame per recorded control step, as MP4 or GIF.

Frame layout (960 x 528 px, both divisible by 16 so H.264 needs no resizing)::

    +--------------------------+----------------+--------+
    | top-down map   480 x 480 | camera RGB     | legend |
    | (static layout cached,   | 320 x 240      | and    |
    |  trajectory, lidar hits, +----------------+ depth  |
    |  planned path, robot)    | depth 0-6 m    | scale  |
    |                          | 320 x 240      | 160 px |
    +--------------------------+----------------+--------+
    | text strip 960 x 48: episode, step, distance, return, outcome |
    +--------------------------------------------------------------+

The legend names every mark of the map and, when the scene has a camera, the depth colour
scale and the robot's own body (blue) and lidar (the red cylinder just ahead of the camera) that
its image shows; without a camera (a replayed recording) the camera panels read "camera
disabled" and the legend has no depth scale. Text is drawn word by word with spaces of
:data:`WORD_GAP_EM` (the bundled font's own are 2-3 px).

Frames are drawn with PIL and NumPy only (matplotlib is used once, for the depth colour
table). Recording only reads the robot's pose and its cached sensor readings, so an episode
with a recorder attached is bit-identical to one without.

Dynamic worlds (``scene.dynamic``): the camera panels show the movers already (they are
PyBullet bodies); the map adds each mover's route (thin, in its own shade: forklifts
yellow-amber, workers blue-violet), its footprint now (a rectangle with a heading tick
for a forklift, a disc for a worker; outlined white while it yields to the robot) and the
events so far (an added obstacle filled and outlined, a removed one crossed out). The
legend lists forklift, worker and event, and the strip's second line ends with the movers'
count and the latest event. Static worlds' frames are drawn exactly as before.

Multi-goal missions (``scene.goals`` holds two or more goals): the map draws every goal zone
with its number (1..K in the episode's goal order) beside it; a reached goal is filled and
ticked, the current target (``scene.goal``) ringed in :data:`TARGET`, the others hollow. What
was reached comes from ``info["reached"]`` at each step. The strip's second line reads
``goals 1/3`` and the current target, and the legend adds ``goal reached`` and ``current
target``. Single-goal episodes are drawn exactly as before.
"""

from __future__ import annotations

import logging
import math
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from bulletnav.files import discard, finish, temp_path
from bulletnav.sim.layout import WALL_THICKNESS, Layout
from bulletnav.sim.specs import Obstacle
from bulletnav.sim.world import COLOURS
from bulletnav.viz.mission import mission_goals, progress_text
from bulletnav.viz.movers import (
    EVENT_RGB,
    event_corners,
    event_text,
    forklift_corners,
    mover_colour,
    mover_colours,
    movers_summary,
)

log = logging.getLogger(__name__)

FRAME_SIZE = (960, 528)
"""Composed frame (width, height) in pixels."""
MAP_PX = 480
"""Side of the square top-down map panel (px)."""
CAMERA_PX = (320, 240)
"""Size of each camera panel (width, height) in pixels; other camera sizes are resized to it."""
SIDE_X = MAP_PX + CAMERA_PX[0]
"""Left edge of the legend column (px)."""
STRIP_Y = MAP_PX
"""Top edge of the text strip (px)."""
DEPTH_MAX = 6.0
"""Depth mapped to the far end of the colour scale (m); farther is clipped."""
MAP_MARGIN = 8
"""Blank border around the map drawing (px)."""
_SUPERSAMPLE = 2
"""The static map is drawn at this multiple and downsampled once: smooth edges for free."""

BACKGROUND = (22, 24, 28)
TEXT = (230, 232, 236)
DIM_TEXT = (150, 154, 162)
GOAL = (60, 220, 90)
TRAJECTORY = (0, 190, 255)
PATH = (240, 90, 240)
LIDAR = (255, 70, 60)
ROBOT = (255, 255, 255)
START = (255, 225, 70)
OUTCOME_COLOURS = {"success": GOAL, "collision": LIDAR, "timeout": (255, 160, 40)}
TARGET = (255, 245, 120)
"""Ring around a mission's current target."""
SHIELD = (255, 120, 20)
"""The robot's colour on a step where the safety shield replaced the command."""
OWN_BODY = (38, 89, 217)
"""The robot's own base as its camera sees it at the bottom of the image (``diff_drive.urdf``'s
``blue`` material, 0.15 0.35 0.85)."""
OWN_LIDAR = (217, 38, 38)
"""The robot's own lidar, the red cylinder in front of the camera (mounted 0.3 m ahead of it and
0.14 m lower; ``diff_drive.urdf``'s ``red`` material, 0.85 0.15 0.15)."""


def category_rgb(category: str) -> tuple[int, int, int]:
    """The 0-255 colour of an obstacle category (``rack``, ``floor``, ...; unknown ones as ``box``)."""
    r, g, b, _ = COLOURS.get(category, COLOURS["box"])
    return int(r * 255), int(g * 255), int(b * 255)


def box_corners(obstacle: Obstacle) -> np.ndarray:
    """(4, 2) world corners (m) of a box obstacle's footprint, counter-clockwise."""
    hx, hy = obstacle.size[0] / 2, obstacle.size[1] / 2
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    local = np.array([(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)])
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.asarray(obstacle.center)


def ui_font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    """Pillow's bundled font at ``size`` px (the fixed bitmap font where FreeType is missing)."""
    try:  # Pillow >= 10.1 with FreeType: the bundled scalable default font
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # older Pillow or no FreeType: the fixed bitmap font
        return ImageFont.load_default()


WORD_GAP_EM = 0.3
"""Width of a space in the frames' text, in font sizes. The bundled font's own space is 2-3 px at
11-13 px, so ``8 robots`` read ``8robots``; the frames draw text word by word with this gap."""


def _gap(font: Any) -> float:
    return max(float(getattr(font, "size", 11)) * WORD_GAP_EM, 3.0)


def text_length(text: str, font: Any) -> float:
    """Width (px) of ``text`` as :func:`draw_text` draws it (spaces :data:`WORD_GAP_EM` wide)."""
    draw = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    words = text.split(" ")
    return sum(draw.textlength(w, font=font) for w in words) + _gap(font) * (len(words) - 1)


def draw_text(draw: ImageDraw.ImageDraw, xy: tuple[float, float], text: str, font: Any,
              fill: tuple[int, int, int]) -> None:
    """``text`` at ``xy`` word by word, each space :data:`WORD_GAP_EM` of the font size wide."""
    x, y = xy
    gap = _gap(font)
    for word in text.split(" "):
        if word:
            draw.text((x, y), word, fill=fill, font=font)
            x += draw.textlength(word, font=font)
        x += gap


_DEPTH_LUT: np.ndarray | None = None


def depth_colours() -> np.ndarray:
    """(256, 3) uint8 colour table for depth: index 0 = 0 m (red, near) ... 255 = ``DEPTH_MAX`` (blue, far)."""
    global _DEPTH_LUT
    if _DEPTH_LUT is None:
        from matplotlib import colormaps  # once per process; frames only index the table

        _DEPTH_LUT = (colormaps["turbo"](np.linspace(1.0, 0.0, 256))[:, :3] * 255).round().astype(np.uint8)
    return _DEPTH_LUT


def colourize_depth(depth: np.ndarray, max_depth: float = DEPTH_MAX) -> np.ndarray:
    """(H, W, 3) uint8 image of a depth map (m), clipped to [0, ``max_depth``]."""
    index = np.clip(np.asarray(depth, dtype=np.float32) * (255.0 / max_depth), 0.0, 255.0).astype(np.uint8)
    return depth_colours()[index]


class MapView:
    """World (m) <-> map-panel pixel transform for one layout, and its static raster.

    The floor and its enclosing walls are fitted into a ``size`` x ``size`` pixel square,
    x to the right and y up.
    """

    def __init__(self, layout: Layout, size: int = MAP_PX, margin: int = MAP_MARGIN) -> None:
        self.layout = layout
        self.size = size
        hx, hy = layout.half_extents
        ex, ey = hx + WALL_THICKNESS, hy + WALL_THICKNESS
        self.scale = (size - 2 * margin) / (2 * max(ex, ey))
        """Pixels per metre."""

    def to_px(self, xy: Any, scale: float = 1.0) -> list[tuple[float, float]]:
        """Pixel coordinates of world points ``xy`` ((N, 2) or one (x, y)), optionally on a ``scale``-times canvas."""
        pts = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        c = self.size / 2 * scale
        s = self.scale * scale
        cx, cy = self.layout.centre  # the floor's centre is the picture's (a user's map: off the origin)
        return list(zip((c + s * (pts[:, 0] - cx)).tolist(), (c - s * (pts[:, 1] - cy)).tolist()))

    def metres(self, d: float, scale: float = 1.0) -> float:
        return d * self.scale * scale

    def render_static(self) -> Image.Image:
        """The layout without anything that moves: background, walls, floor, obstacles, 1 m grid."""
        k = _SUPERSAMPLE
        img = Image.new("RGB", (self.size * k, self.size * k), BACKGROUND)
        draw = ImageDraw.Draw(img)
        x0, y0, x1, y1 = self.layout.bounds
        t = WALL_THICKNESS
        draw.rectangle(self._rect(x0 - t, y0 - t, x1 + t, y1 + t, k), fill=category_rgb("wall"))
        draw.rectangle(self._rect(x0, y0, x1, y1, k), fill=category_rgb("floor"))
        grid = tuple(min(c + 14, 255) for c in category_rgb("floor"))
        for gx in range(math.ceil(x0), math.floor(x1) + 1):  # 1 m grid (whole metres of the world's frame): a scale
            draw.line(self.to_px([(gx, y0), (gx, y1)], k), fill=grid, width=1)
        for gy in range(math.ceil(y0), math.floor(y1) + 1):
            draw.line(self.to_px([(x0, gy), (x1, gy)], k), fill=grid, width=1)
        for o in self.layout.obstacles:
            colour = category_rgb(o.label if o.label in COLOURS else "box")
            edge = tuple(int(c * 0.6) for c in colour)
            if o.kind == "cylinder":
                (cx, cy), = self.to_px(o.center, k)
                r = self.metres(o.radius, k)
                draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=colour, outline=edge, width=k)
            else:
                draw.polygon(self.to_px(box_corners(o), k), fill=colour, outline=edge, width=k)
        return img.resize((self.size, self.size), Image.Resampling.LANCZOS)

    def _rect(self, x0: float, y0: float, x1: float, y1: float, k: float) -> tuple[float, float, float, float]:
        (ax, ay), (bx, by) = self.to_px([(x0, y1), (x1, y0)], k)
        return ax, ay, bx, by


def _outcome(env: Any, info: dict[str, Any], step: int) -> str | None:
    """'success', 'collision' or 'timeout' once the episode is over, else None."""
    if info.get("is_success"):
        return "success"
    if info.get("collision"):
        return "collision"
    spec = env.spec
    limit = getattr(spec, "max_episode_steps", None)
    if limit is not None and step >= limit:
        return "timeout"
    return None


def _reward(info: dict[str, Any]) -> float:
    """The step reward, rebuilt from the ``reward_<term>`` entries (the env's reward is their sum)."""
    return float(sum(v for k, v in info.items() if k.startswith("reward_")))


class VideoWriter:
    """Frames to an MP4 or GIF, written to a hidden file beside ``path`` and renamed onto it by
    :meth:`close`: a crash or an interrupted run never leaves half a video under the name, nor
    replaces an earlier one (:meth:`abort` drops the unfinished file).

    ``.mp4`` is H.264 (libx264, yuv420p) through imageio-ffmpeg, streamed to disk (frame sides
    must be multiples of 16); ``.gif`` goes through Pillow, which keeps all frames in memory
    until :meth:`close`.

    Args:
        path: output file, ``.mp4`` or ``.gif``.
        fps: playback frames per second.
        quality: H.264 quality 0-10 (imageio's scale).
    """

    def __init__(self, path: str | Path, fps: float = 24, quality: float = 5.0) -> None:
        import imageio.v2 as imageio  # the writers live here; import cost only when recording

        self.path = Path(path)
        self.frames_written = 0
        suffix = self.path.suffix.lower()
        if suffix not in (".mp4", ".gif"):
            raise ValueError(f"{self.path}: videos are written as .mp4 or .gif, not {suffix or 'no suffix'!r}")
        self._tmp = temp_path(self.path, suffix)  # imageio picks the format by the suffix
        try:
            if suffix == ".mp4":
                self._writer = imageio.get_writer(
                    self._tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=quality,
                    pixelformat="yuv420p", macro_block_size=16, ffmpeg_log_level="error",
                )
            else:  # Pillow stores durations in ms, rounded to GIF's 10 ms resolution
                self._writer = imageio.get_writer(self._tmp, mode="I", duration=1000.0 / fps, loop=0)
        except BaseException:
            discard(self._tmp)
            raise
        self.closed = False

    def append(self, frame: np.ndarray) -> None:
        """Add one (H, W, 3) uint8 frame."""
        if self.closed:
            raise RuntimeError(f"{self.path}: the video is closed")
        self._writer.append_data(frame)
        self.frames_written += 1

    def close(self) -> None:
        """Finish the file and rename it onto :attr:`path` (idempotent)."""
        if not self.closed:
            self.closed = True
            try:
                self._writer.close()
            except BaseException:
                discard(self._tmp)
                raise
            finish(self._tmp, self.path)  # removes the temp file if it fails

    def abort(self) -> None:
        """Delete the unfinished file; :attr:`path` is left as it was (idempotent)."""
        if not self.closed:
            self.closed = True
            try:
                self._writer.close()
            except Exception:  # an unfinished file is dropped whatever its writer says
                log.debug("closing the writer of an aborted video failed", exc_info=True)
            finally:
                discard(self._tmp)


class EpisodeRecorder:
    """Writes a composed frame every ``stride`` control steps of every episode into one file.

    Call :meth:`on_reset` after ``env.reset`` and :meth:`on_step` after every ``env.step``.
    Per episode of ``n`` steps the file gets ``1 + n // stride`` frames (the reset frame and
    steps ``stride, 2 stride, ...``), plus one for the final step when the episode ended
    (success, collision or time limit) on a step that is not a multiple of ``stride`` and
    ``final_frame`` is set, so that the outcome is always shown.

    ``.mp4`` is H.264 (libx264, yuv420p) through imageio-ffmpeg, streamed to disk; ``.gif``
    goes through Pillow, which keeps all frames in memory until :meth:`close` (use it for
    short clips or a larger stride).

    Args:
        path: output file, ``.mp4`` or ``.gif``.
        stride: record every this many control steps (>= 1).
        fps: playback frames per second.
        quality: H.264 quality 0-10 (imageio's scale; 5 is moderate: ~2-3 MB per minute of video here).
        final_frame: also write the last step of an episode that ended off the stride.
        shield: the episodes run behind the safety shield: the legend lists its colour, the
            robot is drawn in :data:`SHIELD` on every step where ``info["shield"]`` says it
            replaced the command, and the strip counts those steps.
    """

    def __init__(self, path: str | Path, stride: int = 1, fps: int = 24, quality: float = 5.0,
                 final_frame: bool = True, shield: bool = False) -> None:
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        self.path = Path(path)
        self.stride = int(stride)
        self.fps = fps
        self.final_frame = final_frame
        self.shield = shield
        self._vetoed = False
        self._vetoes = 0
        self.frame_size: tuple[int, int] = FRAME_SIZE
        """(width, height) of every frame (px)."""
        self.episodes = 0
        self.last_frame: np.ndarray | None = None
        """The most recent composed frame, (H, W, 3) uint8."""
        suffix = self.path.suffix.lower()
        if suffix not in (".mp4", ".gif"):
            raise ValueError(f"{self.path}: EpisodeRecorder writes .mp4 or .gif, not {suffix or 'no suffix'!r}")
        self._video = VideoWriter(self.path, fps=fps, quality=quality)
        self._font = ui_font(13)
        self._small = ui_font(11)
        self._maps: OrderedDict[Layout, tuple[MapView, Image.Image]] = OrderedDict()
        self._label = LabelCache(self._font, self._small, 64)  # per-episode lines would otherwise pile up
        self._bases: dict[tuple[bool, bool, bool], Image.Image] = {}  # (dynamic, mission, camera): drawn when first needed
        self._goals: tuple[tuple[float, float], ...] = ()
        self._reached: tuple[bool, ...] = ()
        self.mission_text = ""
        """A mission's progress in the strip, ``goals 1/3   target 2 (+2.00, +2.50)`` (empty otherwise)."""
        self._dynamic = False
        self._mover_rgb: list[tuple[int, int, int]] = []
        self._events_drawn = 0
        self._dynamic_text = ""
        self._episode_stamp: int | None = None
        self._episode_map: Image.Image | None = None
        self._view: MapView | None = None
        self._trajectory: list[tuple[float, float]] = []
        self._step = 0
        self._return = 0.0
        self._distance = math.nan
        self._outcome: str | None = None
        self._done_written = False

    # ------------------------------------------------------------------ hooks
    def on_reset(self, env: Any, info: dict[str, Any] | None = None,
                 path: Sequence[tuple[float, float]] | None = None) -> None:
        """Start an episode (call right after ``env.reset``; fits ``run_episodes``' ``on_reset``)
        and write its first frame, with ``path`` (a plan to draw) if given."""
        self._begin(env)
        self._mission_info(info)
        self._write(self.compose(env, path=path))

    def on_step(self, env: Any, info: dict[str, Any], path: Sequence[tuple[float, float]] | None = None) -> None:
        """Account for the step just taken (call after every ``env.step``); write a frame when due.

        ``path`` is the planned path to draw, e.g. ``navigator.path``. When :meth:`on_reset`
        was not called for a new episode, the episode is started here, without its reset frame.
        """
        scene = env.unwrapped.scene
        if scene.episode != self._episode_stamp:
            log.debug("episode started without on_reset: its reset frame is missing")
            self._begin(env)
        self._step = scene.steps
        x, y, _ = scene.pose
        self._trajectory.append((x, y))
        self._return += _reward(info)
        self._distance = float(info.get("distance_to_goal", self._distance))
        self._outcome = _outcome(env, info, self._step)
        veto = info.get("shield")
        self._vetoed = bool(veto and veto.get("intervened"))
        self._vetoes += self._vetoed
        if self._goals:
            self._mission_info(info)
        due = self._step % self.stride == 0
        final = self._outcome is not None and self.final_frame and not self._done_written
        if due or final:
            self._write(self.compose(env, path=path))
            self._done_written = self._outcome is not None

    @property
    def frames_written(self) -> int:
        """Frames in the file so far."""
        return self._video.frames_written

    def close(self) -> None:
        """Finish the file and rename it onto :attr:`path` (idempotent)."""
        if not self._video.closed:
            self._video.close()
            log.info("wrote %d frames (%d episodes) to %s", self.frames_written, self.episodes, self.path)

    def abort(self) -> None:
        """Stop recording and delete the unfinished file; :attr:`path` is left as it was (idempotent)."""
        self._video.abort()

    def __enter__(self) -> EpisodeRecorder:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        """Keep the file when the block ended normally, drop it when it raised."""
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # ------------------------------------------------------------------ frames
    def compose(self, env: Any, path: Sequence[tuple[float, float]] | None = None) -> np.ndarray:
        """The frame for the current state, (H, W, 3) uint8, without writing it."""
        scene = env.unwrapped.scene
        if self._episode_map is None or self._view is None or scene.episode != self._episode_stamp:
            self._begin(env)
        view = self._view
        self._step = scene.steps
        if self._dynamic:
            self._draw_new_events(scene, view)
        camera = scene.sensors.camera
        key = (self._dynamic, bool(self._goals), camera is not None)
        base = self._bases.get(key)
        if base is None:
            base = self._bases[key] = self._render_base(*key)
        frame = base.copy()
        frame.paste(self._map_frame(scene, view, path), (0, 0))
        if camera is not None:
            image = camera.read()  # cached per control step; no noise, no random draws
            rgb = Image.fromarray(image.rgb)
            depth = Image.fromarray(colourize_depth(image.depth))
            if rgb.size != CAMERA_PX:
                rgb = rgb.resize(CAMERA_PX, Image.Resampling.BILINEAR)
                depth = depth.resize(CAMERA_PX, Image.Resampling.NEAREST)
            frame.paste(rgb, (MAP_PX, 0))
            frame.paste(depth, (MAP_PX, CAMERA_PX[1]))
            frame.paste(self._label("camera RGB"), (MAP_PX + 2, 2))
            frame.paste(self._label(f"depth 0-{DEPTH_MAX:g} m (near red)"), (MAP_PX + 2, CAMERA_PX[1] + 2))
        else:
            frame.paste(self._label("camera disabled"), (MAP_PX + 2, 2))
        self._strip(frame, scene)
        out = np.asarray(frame, dtype=np.uint8)
        self.last_frame = out
        return out

    def _begin(self, env: Any) -> None:
        scene = env.unwrapped.scene
        self.episodes += 1
        self._episode_stamp = scene.episode
        self._view, static = self._static_map(scene.layout)
        # per-episode layer: the static map plus start and goal, copied for every frame
        img = static.copy()
        draw = ImageDraw.Draw(img)
        view = self._view
        self._goals = mission_goals(None, scene)
        self._reached = (False,) * len(self._goals)
        if not self._goals:  # a mission's goals change look as they are reached: drawn per frame
            (gx, gy), = view.to_px(scene.goal)
            r = view.metres(scene.goal_radius)
            draw.ellipse((gx - r, gy - r, gx + r, gy + r), fill=mix_colour(GOAL, category_rgb("floor"), 0.35), outline=GOAL, width=3)
            draw.ellipse((gx - 3, gy - 3, gx + 3, gy + 3), fill=GOAL)
        sx, sy, syaw = scene.start
        (px, py), = view.to_px((sx, sy))
        h = view.metres(0.15)
        draw.rectangle((px - h, py - h, px + h, py + h), outline=START, width=2)
        (tx, ty), = view.to_px((sx + 0.3 * math.cos(syaw), sy + 0.3 * math.sin(syaw)))
        draw.line((px, py, tx, ty), fill=START, width=2)
        self._episode_map = img
        self._dynamic = bool(scene.dynamic)
        self._events_drawn = 0
        if self._dynamic:
            movers = scene.movers
            self._mover_rgb = mover_colours(m.kind for m in movers)
            floor = category_rgb("floor")
            for m, rgb in zip(movers, self._mover_rgb):
                if len(m.path) >= 2:  # routes are fixed for the episode: drawn once into its layer
                    draw.line(view.to_px(m.path), fill=mix_colour(rgb, floor, 0.7), width=1)
            self._dynamic_text = f"movers: {movers_summary(m.kind for m in movers)}   last event: none"
        x, y, _ = scene.pose
        self._trajectory = [(x, y)]
        self._step = scene.steps
        self._return = 0.0
        self._distance = math.hypot(scene.goal[0] - x, scene.goal[1] - y)
        self._outcome = None
        self._done_written = False
        self._vetoed, self._vetoes = False, 0
        self.mission_text = self._progress(scene) if self._goals else ""

    def _mission_info(self, info: dict[str, Any] | None) -> None:
        """Take which goals are reached from ``info["reached"]`` (a mission's)."""
        if not self._goals or info is None:
            return
        reached = info.get("reached")
        if reached is not None and len(reached) == len(self._goals):
            self._reached = tuple(bool(r) for r in reached)

    def _progress(self, scene: Any) -> str:
        text = progress_text(sum(self._reached), len(self._goals))
        target = scene.goal
        if target is not None and not all(self._reached):
            gx, gy = target
            number = self._target_index(target)
            text += f"   target {number + 1 if number is not None else '?'} ({gx:+.2f}, {gy:+.2f})"
        return text

    def _target_index(self, target: Any) -> int | None:
        if target is None:
            return None
        tx, ty = float(target[0]), float(target[1])
        for i, (gx, gy) in enumerate(self._goals):
            if gx == tx and gy == ty and not self._reached[i]:
                return i
        return None

    def _draw_goals(self, img: Image.Image, scene: Any, view: MapView) -> None:
        """A mission's goal zones, numbered: reached filled and ticked, the target ringed, the rest hollow."""
        draw = ImageDraw.Draw(img)
        floor = category_rgb("floor")
        r = view.metres(scene.goal_radius)
        target = self._target_index(scene.goal)
        for i, ((gx, gy), reached) in enumerate(zip(view.to_px(self._goals), self._reached)):
            box = (gx - r, gy - r, gx + r, gy + r)
            if reached:
                draw.ellipse(box, fill=mix_colour(GOAL, floor, 0.8), outline=GOAL, width=2)
                k = max(r * 0.5, 4.0)  # a tick across the zone
                draw.line([(gx - k, gy), (gx - k * 0.3, gy + k * 0.7), (gx + k, gy - k * 0.8)], fill=BACKGROUND,
                          width=3, joint="curve")
            elif i == target:
                draw.ellipse(box, fill=mix_colour(GOAL, floor, 0.35), outline=GOAL, width=3)
                draw.ellipse((gx - r - 4, gy - r - 4, gx + r + 4, gy + r + 4), outline=TARGET, width=2)
                draw.ellipse((gx - 3, gy - 3, gx + 3, gy + 3), fill=GOAL)
            else:
                draw.ellipse(box, fill=mix_colour(GOAL, floor, 0.12), outline=mix_colour(GOAL, floor, 0.6), width=2)
                draw.ellipse((gx - 2, gy - 2, gx + 2, gy + 2), fill=mix_colour(GOAL, floor, 0.6))
            colour = TARGET if i == target else GOAL if reached else TEXT
            number = self._label(str(i + 1), colour, small=False)
            img.paste(number, (int(gx + r * 0.7 + 2), int(gy - r * 0.7 - number.height)))

    def _static_map(self, layout: Layout) -> tuple[MapView, Image.Image]:
        # procedural envs draw a new layout every reset: keep a few, not all of them
        if layout in self._maps:
            self._maps.move_to_end(layout)
            return self._maps[layout]
        view = MapView(layout)
        entry = (view, view.render_static())
        self._maps[layout] = entry
        while len(self._maps) > 8:
            self._maps.popitem(last=False)
        return entry

    def _map_frame(self, scene: Any, view: MapView, path: Sequence[tuple[float, float]] | None) -> Image.Image:
        img = self._episode_map.copy()
        if self._goals:
            self._draw_goals(img, scene, view)
        draw = ImageDraw.Draw(img)
        if path is not None and len(path) >= 2:
            draw.line(view.to_px(path), fill=PATH, width=2)
        if len(self._trajectory) >= 2:
            draw.line(view.to_px(self._trajectory), fill=TRAJECTORY, width=2, joint="curve")
        lidar = scene.sensors.lidar
        if lidar is not None:
            ranges = lidar.read()  # cached: the env read it this step
            hit = ranges < lidar.config.max_range - 1e-6
            if np.any(hit):
                for px, py in view.to_px(lidar.hit_points(ranges)[hit]):
                    draw.ellipse((px - 2, py - 2, px + 2, py + 2), fill=LIDAR)
        if self._dynamic:
            self._draw_movers(draw, scene, view)
        x, y, yaw = scene.pose
        (cx, cy), = view.to_px((x, y))
        r = view.metres(scene.geometry.radius)
        robot = SHIELD if self._vetoed else ROBOT
        draw.ellipse((cx - r, cy - r, cx + r, cy + r), outline=robot, width=2 if self._vetoed else 1)
        tri = [(x + 0.3 * math.cos(yaw), y + 0.3 * math.sin(yaw)),
               (x + 0.18 * math.cos(yaw + 2.4), y + 0.18 * math.sin(yaw + 2.4)),
               (x + 0.18 * math.cos(yaw - 2.4), y + 0.18 * math.sin(yaw - 2.4))]
        draw.polygon(view.to_px(tri), fill=robot, outline=BACKGROUND)
        return img

    def _strip(self, frame: Image.Image, scene: Any) -> None:
        dt = scene.control_dt
        line1 = (f"episode {self.episodes}   step {self._step:4d}   t {self._step * dt:6.2f} s   "
                 f"distance to goal {self._distance:5.2f} m   return {self._return:+8.2f}")
        if self.shield:
            line1 += f"   shield acted {self._vetoes} steps"
        draw_text(ImageDraw.Draw(frame), (10, STRIP_Y + 6), line1, self._font, TEXT)  # changes every frame
        name = scene.layout.name or "layout"
        sx, sy, _ = scene.start
        if self._goals:
            self.mission_text = self._progress(scene)
            line2 = f"{name}   start ({sx:+.2f}, {sy:+.2f})   {self.mission_text}"
        else:
            gx, gy = scene.goal
            line2 = f"{name}   start ({sx:+.2f}, {sy:+.2f})   goal ({gx:+.2f}, {gy:+.2f})"
        label2 = self._label(line2, DIM_TEXT)
        frame.paste(label2, (7, STRIP_Y + 24))
        outcome = self._outcome or "running"
        label = self._label(outcome.upper(), OUTCOME_COLOURS.get(outcome, DIM_TEXT), small=False)
        frame.paste(label, (FRAME_SIZE[0] - 12 - label.width, STRIP_Y + 12))
        if self._dynamic:  # movers and the latest event, cut short before the outcome label
            x = 7 + label2.width + 12
            dyn = self._label(self._dynamic_text, EVENT_RGB)
            room = FRAME_SIZE[0] - 12 - label.width - 10 - x
            if dyn.width > room > 0:
                dyn = dyn.crop((0, 0, room, dyn.height))
            if room > 0:
                frame.paste(dyn, (x, STRIP_Y + 24))

    def _draw_movers(self, draw: ImageDraw.ImageDraw, scene: Any, view: MapView) -> None:
        draw_movers(draw, view, scene.movers, self._mover_rgb)

    def _draw_new_events(self, scene: Any, view: MapView) -> None:
        """Draw the events since the last frame into the episode's layer (they stay for the episode)."""
        events = scene.events
        if len(events) <= self._events_drawn:
            return
        draw_events(ImageDraw.Draw(self._episode_map), view, events[self._events_drawn:])
        self._events_drawn = len(events)
        movers = movers_summary(m.kind for m in scene.movers)
        self._dynamic_text = f"movers: {movers}   last event: {event_text(events[-1])}"

    def _render_base(self, dynamic: bool = False, mission: bool = False, camera: bool = True) -> Image.Image:
        """Everything that never changes: background, legend and, with a ``camera``, the depth
        colour bar and the robot's own parts its image shows (body and lidar). With ``dynamic``
        the legend also lists forklift, worker and event; with ``mission``, goal reached and
        current target. Without a camera there is no depth to explain: no colour bar."""
        img = Image.new("RGB", FRAME_SIZE, BACKGROUND)
        draw = ImageDraw.Draw(img)
        x = SIDE_X + 12
        draw_text(draw, (x, 10), "legend", self._font, TEXT)
        y = 34
        entries = [("goal zone", GOAL)]
        if mission:
            entries += [("goal reached (ticked)", mix_colour(GOAL, category_rgb("floor"), 0.8)), ("current target", TARGET)]
        entries += [("start", START), ("robot", ROBOT)]
        if self.shield:
            entries += [("robot, shield acting", SHIELD)]
        entries += [("trajectory", TRAJECTORY),
                   ("planned path", PATH), ("lidar hits", LIDAR)]
        if dynamic:
            entries += [("forklift", mover_colour("forklift", 0)), ("worker", mover_colour("worker", 0)),
                        ("event (add / remove)", EVENT_RGB)]
        entries += [(name, category_rgb(name)) for name in ("rack", "pallet", "box", "column", "wall")]
        if camera:
            entries += [("own body (camera)", OWN_BODY), ("own lidar (camera)", OWN_LIDAR)]
        # rows of 20 px, closer when many entries would squeeze the depth bar under 100 px
        row = min(20, (MAP_PX - 16 - 100 - 24 - y) // len(entries)) if camera else 20
        for name, colour in entries:
            draw.rectangle((x, y + 2, x + 12, y + 12), fill=colour)
            draw_text(draw, (x + 20, y), name, self._small, TEXT)
            y += row
        draw.line((0, STRIP_Y, FRAME_SIZE[0], STRIP_Y), fill=(60, 64, 70))
        if not camera:
            return img
        # depth colour bar: near (0 m) at the top, as in the panel's table
        top, bottom = y + 24, MAP_PX - 16
        draw_text(draw, (x, y + 4), "depth (m)", self._small, TEXT)
        lut = depth_colours()
        rows = np.linspace(0, 255, bottom - top).astype(int)
        bar = np.repeat(lut[rows][:, None, :], 16, axis=1)
        img.paste(Image.fromarray(bar), (x, top))
        for d in range(0, int(DEPTH_MAX) + 1, 2):
            ty = top + (bottom - top - 1) * d / DEPTH_MAX
            draw.line((x + 16, ty, x + 22, ty), fill=TEXT)
            draw.text((x + 26, ty - 6), f"{d}" + ("+" if d == int(DEPTH_MAX) else ""), fill=TEXT, font=self._small)
        return img

    def _write(self, frame: np.ndarray) -> None:
        if self._video.closed:
            raise RuntimeError(f"{self.path}: recorder is closed")
        self._video.append(frame)


def label_image(text: str, font: Any, colour: tuple[int, int, int] = TEXT) -> Image.Image:
    """``text`` in ``colour`` on a background box 3 px wider on each side (the frames' labels),
    its spaces :data:`WORD_GAP_EM` wide."""
    x0, y0, x1, y1 = ImageDraw.Draw(Image.new("RGB", (1, 1))).textbbox((0, 0), text, font=font)
    width = max(x1, text_length(text, font))
    img = Image.new("RGB", (int(math.ceil(width)) + 6, int(y1) + 4), BACKGROUND)
    draw_text(ImageDraw.Draw(img), (3, 2), text, font, colour)
    return img


class LabelCache:
    """Labels (:func:`label_image`) in a frame's two fonts, each rendered once and kept: FreeType
    rendering is most of a frame's drawing time, and most labels repeat from frame to frame.
    Call it with ``(text, colour, small)``; beyond ``most`` labels all are dropped and made anew."""

    def __init__(self, font: Any, small_font: Any, most: int) -> None:
        self.font, self.small_font, self.most = font, small_font, most
        self._images: dict[tuple[str, tuple[int, int, int], bool], Image.Image] = {}

    def __call__(self, text: str, colour: tuple[int, int, int] = TEXT, small: bool = True) -> Image.Image:
        """``text`` in ``colour`` on a background box, in the small font or the regular one."""
        key = (text, colour, small)
        img = self._images.get(key)
        if img is None:
            img = label_image(text, self.small_font if small else self.font, colour)
            if len(self._images) > self.most:
                self._images.clear()
            self._images[key] = img
        return img


def draw_movers(draw: ImageDraw.ImageDraw, view: MapView, movers: Sequence[Any],
                rgbs: Sequence[tuple[int, int, int]] = ()) -> None:
    """Each mover's footprint now, in its shade (``rgbs[i]``, else :func:`mover_colour`): a forklift's
    rectangle with a heading tick, a worker's disc; outlined white while it yields."""
    for i, m in enumerate(movers):
        rgb = rgbs[i] if i < len(rgbs) else mover_colour(m.kind, i)
        edge = ROBOT if m.yielding else BACKGROUND
        x, y, yaw = m.pose
        if m.kind == "forklift":
            draw.polygon(view.to_px(forklift_corners(m.pose, m.size)), fill=rgb, outline=edge, width=1)
            half = 0.5 * m.size[0]
            tip = (x + (half + 0.25) * math.cos(yaw), y + (half + 0.25) * math.sin(yaw))
            draw.line(view.to_px([(x, y), tip]), fill=edge, width=2)
        else:
            (cx, cy), = view.to_px((x, y))
            r = max(view.metres(0.5 * m.size[0]), 2.0)
            draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=rgb, outline=edge, width=1)


def draw_events(draw: ImageDraw.ImageDraw, view: MapView, events: Sequence[dict[str, Any]]) -> None:
    """Events' footprints: an added obstacle filled in its category colour and outlined, a removed one crossed out."""
    for e in events:
        corners = view.to_px(event_corners(e))
        if e["action"] == "add":
            label = e.get("label") or ""
            fill = category_rgb(label if label in COLOURS else "pallet")
            draw.polygon(corners, fill=fill, outline=EVENT_RGB, width=2)
        else:
            draw.polygon(corners, outline=EVENT_RGB, width=1)
            draw.line((corners[0], corners[2]), fill=EVENT_RGB, width=2)
            draw.line((corners[1], corners[3]), fill=EVENT_RGB, width=2)


def mix_colour(a: tuple[int, int, int], b: tuple[int, int, int], alpha: float) -> tuple[int, int, int]:
    """``alpha`` of colour ``a`` over colour ``b``."""
    return tuple(int(round(alpha * x + (1 - alpha) * y)) for x, y in zip(a, b))  # type: ignore[return-value]
