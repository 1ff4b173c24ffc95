"""Gazebo SDF worlds: the ``box`` and ``cylinder`` collision shapes of a world's models, placed
in the world frame, as bulletnav obstacles.

Every ``<model>`` (nested ones too) is walked; each ``<link>``'s ``<collision>`` geometry is placed
at model pose ∘ link pose ∘ collision pose (each ``<pose>`` relative to its parent, or to the frame
its ``relative_to`` names: ``world``, ``__model__``, a link or a ``<frame>`` of the same model, or
a model or frame of the world). A pose is ``x y z roll pitch yaw`` (radians; degrees with
``degrees="true"``; ``x y z qx qy qz qw`` with ``rotation_format="quat_xyzw"``), rotations
composed as SDF does (fixed axes: R = Rz(yaw) Ry(pitch) Rx(roll)).

What is built: a box with one of its axes vertical (its footprint the other two, turned by the
yaw of the first) and a cylinder whose axis is vertical; each stands on the floor up to its
top (a shape floating above the floor is built down to the floor, with a warning). A plane
whose normal is +z is the ground and builds nothing. Everything else is refused with the
model's name, never dropped: a mesh, sphere, capsule, ellipsoid, heightmap, polyline or other
plane; a tilted shape; a shape wholly under the floor; an ``<include>`` (except Gazebo's own
``ground_plane`` and ``sun``, which hold a ground plane and a light); an ``<actor>`` or a
``<population>``. A ``<state>`` (a world saved from Gazebo) is applied as Gazebo applies it on
loading: its model and link poses (world frame) replace the composed ones, its ``<insertions>``
are built and its ``<deletions>`` are not. Visuals are ignored (the collisions are what the robot meets); models that
are not ``<static>`` are built as static obstacles too (bulletnav has no pushable bodies).

The file is parsed by :func:`bulletnav.xmlfile.parse_xml`: a DOCTYPE or an entity declaration is
refused in any encoding, so no entity from a user's file is ever expanded, and elements nest at
most :data:`~bulletnav.xmlfile.MAX_DEPTH` deep.
"""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bulletnav.errors import LayoutError
from bulletnav.xmlfile import XmlRefused, parse_xml

log = logging.getLogger(__name__)

MAX_BYTES = 64 * 1024 * 1024
"""Largest SDF file read (bytes); BARN's worlds are ~40 kB."""
TOLERANCE = 1e-6
"""How far from vertical (cosine) an axis may be and still count as vertical."""
BUILTIN_INCLUDES = ("ground_plane", "sun")
"""Models an ``<include>`` may name: Gazebo's stock ground plane (the floor) and sun (a light)."""
_REFUSED_GEOMETRY = ("mesh", "sphere", "capsule", "ellipsoid", "heightmap", "polyline", "image")


@dataclass(frozen=True)
class Shape:
    """One buildable collision shape in the world frame."""

    model: str
    """The model's scoped name (``outer::inner``) and the collision's, for messages and labels."""
    kind: str
    """``box`` or ``cylinder``."""
    center: tuple[float, float]
    """Footprint centre (m, world frame)."""
    size: tuple[float, float]
    """Box footprint (m, along its yaw and across it); (2 r, 2 r) for a cylinder."""
    yaw: float
    """Footprint rotation about z (rad)."""
    bottom: float
    top: float
    """Lowest and highest z of the shape (m)."""

    def corners(self) -> np.ndarray:
        """The footprint's bounding points (the box's four corners, the cylinder's bounding square)."""
        hx, hy = self.size[0] / 2, self.size[1] / 2
        if self.kind == "cylinder":
            return np.array(self.center) + np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        return np.array(self.center) + local @ np.array([[c, s], [-s, c]])


class _World:
    """What the walk found: the shapes, and whether a ground plane was among them; and the
    world-frame poses of models and links that the world's ``<state>`` sets (Gazebo applies them
    when it loads the world: a world saved from Gazebo has one)."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.shapes: list[Shape] = []
        self.ground = False
        self.state: dict[str, np.ndarray] = {}
        """``model`` or ``model/link`` (scoped ``outer::inner`` names) -> world pose."""
        self.deleted: set[str] = set()

    def read_state(self, state: ET.Element) -> None:
        for deletions in state.findall("deletions"):
            self.deleted.update((n.text or "").strip() for n in deletions.findall("name"))

        def walk(model: ET.Element, prefix: str) -> None:
            name = prefix + _name(model, "")
            if model.find("pose") is not None:
                self.state[name] = _pose(model, self.where, f"state of model {name!r}")[0]
            for link in model.findall("link"):
                if link.find("pose") is not None:
                    self.state[f"{name}/{_name(link, '')}"] = _pose(link, self.where, f"state of model {name!r}")[0]
            for inner in model.findall("model"):
                walk(inner, name + "::")

        for model in state.findall("model"):
            walk(model, "")


def _refuse(where: str, who: str, what: str) -> LayoutError:
    return LayoutError(f"{where}: {who}: {what}")


def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _numbers(text: str | None, n: int, where: str, who: str, field: str) -> list[float]:
    parts = (text or "").split()
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise _refuse(where, who, f"<{field}> must hold {n} finite numbers, got {(text or '').strip()!r}")
    return values


def _pose(elem: ET.Element | None, where: str, who: str) -> tuple[np.ndarray, str]:
    """The 4x4 transform of an element's ``<pose>`` and its ``relative_to`` ('' for the parent)."""
    pose = elem.find("pose") if elem is not None else None
    t = np.eye(4)
    if pose is None:
        return t, ""
    fmt = pose.get("rotation_format", "euler_rpy")
    if fmt == "quat_xyzw":
        x, y, z, qx, qy, qz, qw = _numbers(pose.text, 7, where, who, "pose")
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if norm < 1e-12:
            raise _refuse(where, who, "<pose> has a zero quaternion")
        qx, qy, qz, qw = qx / norm, qy / norm, qz / norm, qw / norm
        t[:3, :3] = [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                     [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                     [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]
    elif fmt == "euler_rpy":
        text = (pose.text or "").strip()
        x, y, z, roll, pitch, yaw = _numbers(text, 6, where, who, "pose") if text else [0.0] * 6
        if pose.get("degrees", "false").strip().lower() in ("true", "1"):
            roll, pitch, yaw = (math.radians(a) for a in (roll, pitch, yaw))
        t[:3, :3] = _rotation(roll, pitch, yaw)
    else:
        raise _refuse(where, who, f"<pose rotation_format={fmt!r}> is neither euler_rpy nor quat_xyzw")
    t[:3, 3] = (x, y, z)
    return t, (pose.get("relative_to") or pose.get("frame") or "").strip()  # SDF <= 1.6 named it frame


def _name(elem: ET.Element, fallback: str) -> str:
    return elem.get("name") or fallback


def _is_static(elem: ET.Element) -> bool:
    static = elem.find("static")
    return static is not None and (static.text or "").strip().lower() in ("true", "1")


class _Scope:
    """The frames a model's poses may be ``relative_to``: ``__model__``, its links, frames and
    nested models, each resolved (to the world) once, cycles refused."""

    def __init__(self, where: str, who: str, model_t: np.ndarray, parent: _Scope | None,
                 elems: dict[str, ET.Element]) -> None:
        self.where, self.who, self.parent, self.elems = where, who, parent, elems
        self.resolved: dict[str, np.ndarray] = {"__model__": model_t} if model_t is not None else {}
        self.model_t = model_t
        self._busy: set[str] = set()

    def frame(self, name: str, asker: str) -> np.ndarray:
        if name == "world":
            return np.eye(4)
        if name in self.resolved:
            return self.resolved[name]
        if name in self.elems:
            if name in self._busy:
                raise _refuse(self.where, self.who, f"the poses of {sorted(self._busy)} are relative_to each other (a cycle)")
            self._busy.add(name)
            elem = self.elems[name]
            local, rel = _pose(elem, self.where, f"{self.who}::{name}")
            attached = elem.get("attached_to", "").strip() if elem.tag == "frame" else ""
            base = self.frame(rel or attached or "__model__", name) if self.model_t is not None else (
                self.frame(rel or attached, name) if (rel or attached) else np.eye(4))
            self.resolved[name] = base @ local
            self._busy.discard(name)
            return self.resolved[name]
        if self.parent is not None:
            return self.parent.frame(name, asker)
        raise _refuse(self.where, self.who, f"{asker}'s pose is relative_to {name!r}, which names no frame, link or model here")


def _scope_elems(parent: ET.Element) -> dict[str, ET.Element]:
    return {e.get("name", ""): e for e in parent if e.tag in ("link", "frame", "model") and e.get("name")}


def _include(elem: ET.Element, where: str, world: _World, who_prefix: str) -> None:
    uri = (elem.findtext("uri") or "").strip()
    name = elem.findtext("name") or uri.rstrip("/").rsplit("/", 1)[-1] or "<include>"
    stock = uri.rstrip("/").rsplit("/", 1)[-1].replace(" ", "_").lower()
    if stock in BUILTIN_INCLUDES and (uri.startswith("model://") or "fuel" in uri):
        if stock == "ground_plane":
            world.ground = True
        return
    raise _refuse(where, f"{who_prefix}include {name!r}", f"<include> of {uri!r} cannot be built: bulletnav reads only "
                  "box and cylinder collisions written in the file (paste the model's SDF into the world)")


def _model(elem: ET.Element, where: str, world: _World, parent: _Scope, prefix: str) -> None:
    name = prefix + _name(elem, "<unnamed model>")
    if name in world.deleted:
        log.info("%s: model %r is deleted by the world's <state>: not built", where, name)
        return
    who = f"model {name!r}"
    local, rel = _pose(elem, where, who)
    base = parent.frame(rel, who) if rel else (parent.model_t if parent.model_t is not None else np.eye(4))
    model_t = world.state.get(name, base @ local)
    scope = _Scope(where, who, model_t, parent, _scope_elems(elem))
    if not _is_static(elem) and elem.find("link") is not None:
        log.info("%s: %s is not <static>: built as a static obstacle", where, who)
    for child in elem:
        if child.tag == "model":
            _model(child, where, world, scope, name + "::")
        elif child.tag == "include":
            _include(child, where, world, f"{who}: ")
        elif child.tag == "link":
            _link(child, where, world, scope, name)


def _link(elem: ET.Element, where: str, world: _World, scope: _Scope, model: str) -> None:
    link_name = _name(elem, "<unnamed link>")
    link_t = scope.frame(link_name, f"link {link_name!r}") if elem.get("name") else scope.model_t
    link_t = world.state.get(f"{model}/{link_name}", link_t)
    for collision in elem.findall("collision"):
        cname = _name(collision, "<unnamed collision>")
        who = f"model {model!r} (link {link_name!r}, collision {cname!r})"
        local, rel = _pose(collision, where, who)
        t = (scope.frame(rel, who) if rel else link_t) @ local
        geometry = collision.find("geometry")
        kinds = [g.tag for g in geometry] if geometry is not None else []
        if not kinds or kinds == ["empty"]:
            continue
        kind, g = kinds[0], geometry[0]  # type: ignore[index]
        if kind == "plane":
            normal = _numbers(g.findtext("normal", "0 0 1"), 3, where, who, "normal")
            n = (t[:3, :3] @ np.array(normal)) / max(float(np.linalg.norm(normal)), 1e-12)
            if n[2] < 1.0 - TOLERANCE:
                raise _refuse(where, who, f"a <plane> with normal {np.round(n, 6).tolist()} is not the ground and cannot be built")
            world.ground = True
            continue
        if kind in ("box", "cylinder"):
            world.shapes.append(_shape(kind, g, t, where, who, model))
            continue
        refused = f"a <{kind}> geometry" + (" (a mesh file)" if kind == "mesh" else "")
        raise _refuse(where, who, f"{refused} cannot be built: bulletnav builds box and cylinder collisions only")


def _shape(kind: str, g: ET.Element, t: np.ndarray, where: str, who: str, model: str) -> Shape:
    r = t[:3, :3]
    if kind == "box":
        dims = _numbers(g.findtext("size"), 3, where, who, "box><size")
        if min(dims) <= 0:
            raise _refuse(where, who, f"<box><size> must be positive, got {dims}")
        vertical = [k for k in range(3) if abs(r[2, k]) >= 1.0 - TOLERANCE]
        if not vertical:
            raise _refuse(where, who, "the box is tilted (no axis vertical): bulletnav builds shapes standing on the floor only")
        k = vertical[0]
        a, b = [i for i in range(3) if i != k]
        yaw = math.atan2(r[1, a], r[0, a])
        footprint, height = (dims[a], dims[b]), dims[k]
    else:
        radius = _numbers(g.findtext("radius"), 1, where, who, "cylinder><radius")[0]
        height = _numbers(g.findtext("length"), 1, where, who, "cylinder><length")[0]
        if radius <= 0 or height <= 0:
            raise _refuse(where, who, f"<cylinder> radius and length must be positive, got {radius}, {height}")
        if abs(r[2, 2]) < 1.0 - TOLERANCE:
            raise _refuse(where, who, "the cylinder is tilted (its axis is not vertical): bulletnav builds upright cylinders only")
        footprint, yaw = (2 * radius, 2 * radius), 0.0
    z = float(t[2, 3])
    bottom, top = z - height / 2, z + height / 2
    if top <= TOLERANCE:
        raise _refuse(where, who, f"the {kind} lies under the floor (top at z = {top:.3f} m)")
    if bottom > 0.01:
        log.warning("%s: %s floats %.2f m above the floor: built down to the floor", where, who, bottom)
    return Shape(model, kind, (float(t[0, 3]), float(t[1, 3])), footprint, yaw, bottom, top)


def read_shapes(path: str | Path) -> tuple[list[Shape], bool, str]:
    """The buildable shapes of an SDF file (a ``<world>``, or ``<model>``s at the top level).

    Returns:
        (shapes, whether a ground plane was found, the world's name).

    Raises:
        LayoutError: the file is missing, too large, declares a DOCTYPE or ENTITY, nests
            elements too deep, is not XML or not SDF, or holds something that cannot be built
            (named with its model).
    """
    path = Path(path)
    where = str(path)
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise LayoutError(f"{where}: {size:,} bytes, more than the {MAX_BYTES:,} an SDF world may have")
        raw = path.read_bytes()
    except OSError as exc:
        raise LayoutError(f"{where}: cannot read the SDF file ({exc.strerror or exc})") from None
    try:
        root = parse_xml(raw)
    except XmlRefused as exc:
        raise LayoutError(f"{where}: {exc}") from None
    if root.tag != "sdf":
        raise LayoutError(f"{where}: the root element is <{root.tag}>, not <sdf>")
    worlds = root.findall("world")
    if len(worlds) > 1:
        raise LayoutError(f"{where}: {len(worlds)} <world>s; bulletnav builds a file with one")
    top = worlds[0] if worlds else root
    world = _World(where)
    for state in top.findall("state"):
        world.read_state(state)
    scope = _Scope(where, f"world {top.get('name', '')!r}", None, None, _scope_elems(top))  # type: ignore[arg-type]
    inserted = [m for state in top.findall("state") for ins in state.findall("insertions") for m in ins.findall("model")]
    for child in [*top, *inserted]:
        if child.tag == "model":
            _model(child, where, world, scope, "")
        elif child.tag == "include":
            _include(child, where, world, "")
        elif child.tag in ("actor", "population"):
            raise _refuse(where, f"{child.tag} {_name(child, '<unnamed>')!r}",
                          f"an <{child.tag}> cannot be built: bulletnav builds static box and cylinder collisions only")
    return world.shapes, world.ground, top.get("name", "")


__all__ = ["Shape", "read_shapes"]
