"""Architecture rules of the package, checked on its source and against PyBullet.

- Consumers (controllers, evaluation, the policy protocol, visualisation, the CLI, RL and
  benchmarks) see an env only through ``obs``, ``info`` and ``env.unwrapped.scene``: no
  private attributes of other objects, no simulation internals.
- ``bulletnav/sim/`` is physics only (no sensors); ``bulletnav/planning/`` holds pure
  algorithms (no simulation, env or sensors).
- The robot's outline, wheels and sensor mounts are read from its URDF in one place
  (:mod:`bulletnav.geometry`), which agrees with what PyBullet loads; the modules that use
  them carry none of the numbers themselves.
- The package's import graph (imports inside functions and ``TYPE_CHECKING`` blocks count)
  has no circles, and no module imports one of a higher layer (:data:`LAYERS`); every module
  imports in a fresh process in layer order. Tasks see the scene through
  :class:`bulletnav.tasks.view.TaskScene`.
- One module writes files (:mod:`bulletnav.files`: temp file + ``os.replace``, one permission
  rule); no other module makes temp files or renames them into place.
"""

from __future__ import annotations

import ast
import functools
import io
import json
import math
import os
import re
import tokenize
from pathlib import Path

import pybullet as p
import pytest

import bulletnav
import hang
from bulletnav.config import RobotConfig
from bulletnav.geometry import robot_geometry

PKG = Path(bulletnav.__file__).resolve().parent
ROOT = PKG.parent


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


# ---------------------------------------------------------------------------------------
# (a) consumers use obs, info and env.unwrapped.scene only

CONSUMERS = sorted({
    *PKG.glob("control/*.py"), PKG / "evaluation.py", PKG / "policy.py", *PKG.glob("viz/*.py"), *PKG.glob("cli/*.py"),
    *PKG.glob("rl/*.py"), *PKG.glob("bench/*.py"), *PKG.glob("sweep/*.py"), *PKG.glob("benchmark/*.py"),
})
"""Every module that drives or reads an env from outside it."""

SIM_INTERNALS = frozenset({"sim", "task", "robot", "world", "_scene"})
"""Attribute names that reach past the read-only scene view into the env's internals."""

REFLECTION = frozenset({"getattr", "setattr", "hasattr"})

NOT_ENV_INTERNALS = {
    ("bulletnav/cli/envs.py", "args.world"): "the --world option (a layout file path) on argparse's namespace",
    ("bulletnav/cli/fleet.py", "args.world"): "the --world option (a layout file path) on argparse's namespace",
    ("bulletnav/bench/env_bench.py", "cfg.robot"): "EnvConfig.robot, the robot's configuration (RobotConfig)",
    ("bulletnav/bench/physics_bench.py", "sim.robot"): "the physics benchmark drives a bare Simulation, no env",
    ("bulletnav/bench/reset_bench.py", "config.robot"): "EnvConfig.robot: the URDF the raw rebuild loads (RobotConfig)",
    ("bulletnav/rl/features.py", "robot_preset(EnvConfig(), robot).robot"):
        "the named robot preset's RobotConfig (its URDF outline), read without an env",
}
"""Exact (file, expression) pairs that carry one of the internal names without being the
env's internals. Anything else with those names is reported."""


def _is_private(name: str) -> bool:
    """``_name`` but not ``__dunder__``."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _is_name(node: ast.AST, *names: str) -> bool:
    return isinstance(node, ast.Name) and node.id in names


def private_access(source: str, filename: str) -> list[str]:
    """``file:line: what`` for every access in ``source`` that a consumer must not make:

    - an attribute ``X._name`` (single leading underscore) where ``X`` is not ``self``/``cls``;
    - ``getattr``/``setattr``/``hasattr`` with a constant attribute name ``"_name"`` on
      anything but ``self``/``cls``;
    - an attribute named ``sim``, ``task``, ``robot``, ``world`` or ``_scene`` on anything
      but ``self`` (the env's internals: consumers read ``env.unwrapped.scene``), except the
      configuration and CLI fields listed in :data:`NOT_ENV_INTERNALS`;
    - ``from module import _name`` (the same private access, spelled as an import).
    """
    tree = ast.parse(source, filename)
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            owner = node.value
            if _is_private(node.attr) and not _is_name(owner, "self", "cls"):
                found.append((node.lineno, f"{ast.unparse(node)} (private attribute of another object)"))
            elif (node.attr in SIM_INTERNALS and not _is_name(owner, "self")
                  and (filename, ast.unparse(node)) not in NOT_ENV_INTERNALS):
                found.append((node.lineno, f"{ast.unparse(node)} (env internals: use obs, info, env.unwrapped.scene)"))
        elif isinstance(node, ast.Call) and _is_name(node.func, *REFLECTION) and len(node.args) >= 2:
            target, name = node.args[0], node.args[1]
            if (isinstance(name, ast.Constant) and isinstance(name.value, str) and _is_private(name.value)
                    and not _is_name(target, "self", "cls")):
                found.append((node.lineno, f"{ast.unparse(node)} (private attribute by name)"))
        elif isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if _is_private(alias.name):
                    module = "." * node.level + (node.module or "")
                    found.append((node.lineno, f"from {module} import {alias.name} (private name)"))
    return [f"{filename}:{line}: {what}" for line, what in sorted(found)]


def test_private_access_checker_flags_what_it_should():
    snippet = (
        "def f(env, x, obj):\n"
        "    a = env.unwrapped._scene.sim\n"          # line 2: ._scene (private, internals) and .sim
        "    b = getattr(x, \"_p\")\n"                # line 3
        "    c = self._x + obj.__class__.__name__\n"  # line 4: allowed
        "    d = cls._cache\n"                        # line 5: allowed
        "    e = env.unwrapped.scene.pose\n"          # line 6: the public view, allowed
        "    hasattr(obj, \"__len__\")\n"             # line 7: dunder, allowed
        "    setattr(obj, \"_hidden\", 1)\n"          # line 8
        "    x.robot.body\n"                          # line 9
        "    self.robot\n"                            # line 10: allowed
        "    getattr(obj, name)\n"                    # line 11: not a constant, allowed
        "from bulletnav.viz.video import _font\n"     # line 12
    )
    found = private_access(snippet, "snippet.py")
    assert [f.split(":")[1] for f in found] == ["2", "2", "3", "8", "9", "12"], found
    assert any("env.unwrapped._scene" in f and "private" in f for f in found)
    assert any(f.startswith("snippet.py:2:") and "env.unwrapped._scene.sim" in f and "internals" in f for f in found)
    assert any("getattr(x, '_p')" in f for f in found)
    assert not any("self._x" in f or "__class__" in f or "cls._cache" in f for f in found)
    # the configuration/CLI exceptions are exact: the same name elsewhere is still reported
    assert private_access("def f(args):\n    return args.world\n", "bulletnav/cli/envs.py") == []
    assert private_access("def f(args):\n    return args.world\n", "bulletnav/viz/video.py") != []
    assert private_access("def f(env):\n    return env.world\n", "bulletnav/cli/envs.py") != []


def test_consumers_use_only_obs_info_and_the_scene_view():
    assert len(CONSUMERS) >= 20 and PKG / "cli" / "envs.py" in CONSUMERS  # the globs found the modules
    violations = [v for path in CONSUMERS for v in private_access(path.read_text(), _rel(path))]
    assert not violations, f"{len(violations)} private or internal accesses in consumer modules:\n" + "\n".join(violations)


# ---------------------------------------------------------------------------------------
# (b) the import graph: sim/ is physics only, planning/ is pure algorithms

def from_module(node: ast.ImportFrom, package: str) -> str:
    """The dotted module a ``from ... import`` names, a relative one resolved against ``package``."""
    if not node.level:
        return node.module or ""
    base = package.split(".")
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def imported_modules(path: Path, root: Path = ROOT) -> list[tuple[int, str]]:
    """``(line, dotted name)`` of every module ``path`` imports from anywhere in it (functions
    and ``TYPE_CHECKING`` blocks included), relative imports resolved; ``from a import b``
    counts as both ``a`` and ``a.b`` (``b`` may be a submodule)."""
    package = ".".join(path.relative_to(root).with_suffix("").parts)
    if path.name != "__init__.py":
        package = package.rpartition(".")[0]
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = from_module(node, package)
            out.append((node.lineno, module))
            out += [(node.lineno, f"{module}.{alias.name}") for alias in node.names]
    return out


def _forbidden_imports(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    bad = []
    for path in sorted((PKG / folder).rglob("*.py")):
        for line, module in imported_modules(path):
            if any(module == f or module.startswith(f + ".") for f in forbidden):
                bad.append(f"{_rel(path)}:{line}: imports {module}")
    return bad


def test_import_checker_resolves_relative_and_nested_imports(tmp_path):
    pkg = tmp_path / "bulletnav" / "sim"
    pkg.mkdir(parents=True)
    module = pkg / "thing.py"
    module.write_text("import os\nfrom . import layout\nfrom ..sensors import lidar\n"
                      "def f():\n    import bulletnav.sensors.imu\n")
    names = [m for _, m in imported_modules(module, root=tmp_path)]
    assert {"os", "bulletnav.sim.layout", "bulletnav.sensors", "bulletnav.sensors.lidar", "bulletnav.sensors.imu"} <= set(names)


def test_sim_does_not_import_sensors():
    assert list((PKG / "sim").glob("*.py"))
    bad = _forbidden_imports("sim", ("bulletnav.sensors",))
    assert not bad, "bulletnav/sim/ is physics only; sensors are built by the scene:\n" + "\n".join(bad)


def test_planning_is_pure_algorithms():
    assert list((PKG / "planning").glob("*.py"))
    bad = _forbidden_imports("planning", ("bulletnav.sim", "bulletnav.envs", "bulletnav.sensors"))
    assert not bad, "bulletnav/planning/ must not depend on the simulation:\n" + "\n".join(bad)


# ---------------------------------------------------------------------------------------
# (c) the robot's geometry comes from its URDF, in one place

@pytest.fixture
def loaded_robot():
    """The shipped URDF loaded into a bare PyBullet client as the simulation loads it."""
    cid = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(RobotConfig().urdf_path()), [0, 0, 0],
                          flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_USE_IMPLICIT_CYLINDER, physicsClientId=cid)
        yield cid, body
    finally:
        p.disconnect(physicsClientId=cid)


def _joints(cid: int, body: int) -> dict[str, tuple]:
    return {p.getJointInfo(body, j, physicsClientId=cid)[1].decode(): p.getJointInfo(body, j, physicsClientId=cid)
            for j in range(p.getNumJoints(body, physicsClientId=cid))}


def _in_base_frame(cid: int, body: int, local: tuple[float, float, float]) -> tuple[float, float, float]:
    """PyBullet gives base-relative frames in the base's inertial frame (its centre of mass):
    shift them back into the URDF link frame (the body centre)."""
    inertial_pos, inertial_orn = p.getDynamicsInfo(body, -1, physicsClientId=cid)[3:5]
    assert inertial_orn == pytest.approx((0.0, 0.0, 0.0, 1.0))  # no rotation to undo for the shipped robot
    return tuple(a + b for a, b in zip(local, inertial_pos))


def test_robot_geometry_is_what_pybullet_loads(loaded_robot, report):
    cid, body = loaded_robot
    geometry = robot_geometry()
    joints = _joints(cid, body)

    # the outline: the base link's collision boxes, seen from above
    boxes = [s for s in p.getCollisionShapeData(body, -1, physicsClientId=cid) if s[2] == p.GEOM_BOX]
    assert len(boxes) == len(geometry.rectangles) == 3  # the body and two wheel guards
    measured = []
    for shape in boxes:
        extents, local_pos, local_orn = shape[3], shape[5], shape[6]
        assert local_orn == pytest.approx((0.0, 0.0, 0.0, 1.0))  # axis-aligned in the body frame
        cx, cy, _ = _in_base_frame(cid, body, local_pos)
        measured.append((cx, cy, extents[0] / 2, extents[1] / 2))
    ours = sorted((r.cx, r.cy, r.half_x, r.half_y) for r in geometry.rectangles)
    for mine, theirs in zip(ours, sorted(measured)):
        assert mine == pytest.approx(theirs, abs=1e-6)
    farthest = max(math.hypot(abs(cx) + hx, abs(cy) + hy) for cx, cy, hx, hy in measured)
    assert geometry.outline_radius == pytest.approx(farthest, abs=1e-6)
    assert geometry.outline_radius <= geometry.radius == RobotConfig().footprint_radius

    # the sensor mounts: the fixed joints' origins in the body frame
    lidar = _in_base_frame(cid, body, joints["lidar_joint"][14])
    camera = _in_base_frame(cid, body, joints["camera_joint"][14])
    assert geometry.lidar_mount == pytest.approx(lidar, abs=1e-6)
    assert geometry.lidar_offset == pytest.approx(lidar[0], abs=1e-6)
    assert geometry.camera_mount == pytest.approx(camera, abs=1e-6)

    # the wheels: collision sphere radius, and the distance between the two wheel joints
    left, right = joints["left_wheel_joint"], joints["right_wheel_joint"]
    wheel_shape = p.getCollisionShapeData(body, left[0], physicsClientId=cid)[0]
    assert wheel_shape[2] == p.GEOM_SPHERE
    assert geometry.wheel_radius == pytest.approx(wheel_shape[3][0], abs=1e-6)
    assert geometry.wheelbase == pytest.approx(abs(left[14][1] - right[14][1]), abs=1e-6)

    report("outline rectangles from PyBullet (cx, cy, half x, half y) m",
           ", ".join(f"({cx:.3f}, {cy:.3f}, {hx:.3f}, {hy:.3f})" for cx, cy, hx, hy in sorted(measured)))
    report("lidar mount / wheel radius / wheelbase from PyBullet (m)",
           f"{tuple(round(v, 4) for v in lidar)} / {wheel_shape[3][0]:.4f} / {abs(left[14][1] - right[14][1]):.4f}")


GEOMETRY_USERS = ("rl/features.py", "control/navigator.py", "sim/sampler.py", "evaluation.py")
"""Modules that use the robot's outline or disc: they must take it from bulletnav.geometry."""

GEOMETRY_LITERALS = (0.15, 0.12, 0.11)
"""The shipped URDF's numbers a module would copy to hard-code the outline: the body's half
length, the wheel guards' outer edge, the wheels' offset from the centre line."""

_NUMBER = re.compile(r"^(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$")


def code_literals(source: str, filename: str, values: tuple[float, ...]) -> list[str]:
    """``file:line: token`` for every number token in the code of ``source`` equal to one of
    ``values`` (comments, docstrings and other strings are not code)."""
    found = []
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.NUMBER and _NUMBER.match(tok.string) and float(tok.string) in values:
            found.append(f"{filename}:{tok.start[0]}: {tok.string}  | {tok.line.strip()}")
    return found


def test_literal_checker_reads_code_not_comments_or_strings():
    source = ('"""Body 0.3 x 0.2 m: half length 0.15."""\n'
              "HALF = 0.15  # 0.12 in a comment\n"
              "x = .11 + 1.5e-1 * 2\n"
              "label = '0.12' + str(b'0.11')\n"
              "y = 0.150 + 0.1 + 10.15\n")
    found = code_literals(source, "m.py", GEOMETRY_LITERALS)
    assert [f.split(":")[1] for f in found] == ["2", "3", "3", "5"], found


NOT_GEOMETRY = {
    "scale: float = 0.15": "ClearanceFeatures' closeness scale (m at which closeness is 1/e), not a robot dimension",
}
"""Source lines that carry one of the numbers with another meaning."""


def test_geometry_users_carry_no_outline_numbers():
    found = []
    for name in GEOMETRY_USERS:
        path = PKG / name
        found += [f for f in code_literals(path.read_text(), _rel(path), GEOMETRY_LITERALS)
                  if not any(line in f for line in NOT_GEOMETRY)]
    assert not found, ("robot geometry numbers written into modules that must read them from bulletnav.geometry:\n"
                       + "\n".join(found))


# ---------------------------------------------------------------------------------------
# (d) the package import graph: no circles, no upward imports

LAYERS: tuple[tuple[str, ...], ...] = (
    ("bulletnav", "errors", "stdio"),               # the package's ids and constants, exceptions, pybullet's banner held
    ("limits",),
    ("config",),
    ("xmlfile",),                                   # XML read with DTDs and entities refused
    ("geometry", "yamlfile", "provenance", "files", "runs"),  # runs: the row log, pool and strict JSON of a run
    ("filekinds",),                                 # what kind of file a path holds (reads with yamlfile's safe loader)
    ("sim",),
    ("sensors",),
    ("planning",),
    ("tasks",),
    ("envs", "barn"),                               # barn: the BARN worlds, score and env (reads sim, tasks, envs)
    ("control",),
    ("policy", "evaluation"),
    ("rl",),
    ("benchmark", "datasets", "fleet"),             # siblings: neither imports the other (SIBLINGS_APART)
    ("viz",),
    ("ros", "sweep", "bench"),
    ("cli",),
)
"""The package's layers, lowest first, as the code has them: a module may import modules of its
own layer or lower ones, never a higher one. Each name is a module or subpackage under
``bulletnav`` (``"bulletnav"`` is the package's own ``__init__``). The order is the one the
imports force: ``envs`` builds its scene from ``sim`` and ``sensors`` and runs ``tasks``;
``control`` and ``evaluation`` drive envs; ``rl`` trains on them; ``benchmark`` runs
controllers and models, ``fleet`` runs a fleet of them (the env, tasks and rl reused), both on
the run machinery of ``runs`` on the ground floor, neither importing the other; ``viz`` draws
scenes and fleets; ``ros`` replays recordings into ``viz``'s videos, ``sweep`` runs ``rl``
training and passes ``viz``'s learning curve in, ``bench`` measures everything; the CLI
sits on top. Benchmark reports and training draw through callables their caller passes
(``draw_layout``, ``plot_curve``), so neither imports ``viz``."""


def _module_name(path: Path, root: Path = ROOT) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(path): path for path in sorted(PKG.rglob("*.py"))}
"""Every module of the package by dotted name (a package by its ``__init__``)."""


def package_imports(path: Path, modules: dict[str, Path] | None = None, root: Path = ROOT) -> set[str]:
    """The package modules ``path`` imports, anywhere in the file (functions and
    ``TYPE_CHECKING`` blocks included), relative imports resolved.

    The rule for packages: ``import a.b.c`` and ``from a.b import c`` (``c`` a module) depend on
    ``a.b.c`` only. Python runs the ``__init__`` of ``a`` and ``a.b`` first, but that is implied
    by every import of a submodule and is not an edge; otherwise a package whose ``__init__``
    re-exports its submodules would form a circle with each of them. ``import a.b`` and ``from
    a.b import name`` (``name`` not a module: a class, function, constant re-exported by the
    ``__init__``) depend on ``a.b``'s ``__init__``: a circle through such a re-export is real
    (it works only in one import order) and is reported.
    """
    modules = MODULES if modules is None else modules
    name = _module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names if alias.name in modules}
        elif isinstance(node, ast.ImportFrom):
            module = from_module(node, package)
            for alias in node.names:
                if f"{module}.{alias.name}" in modules:
                    out.add(f"{module}.{alias.name}")
                elif module in modules:
                    out.add(module)
    out.discard(name)
    return out


def import_graph(modules: dict[str, Path] | None = None, root: Path = ROOT) -> dict[str, set[str]]:
    """Module -> the package modules it imports (:func:`package_imports`); the package's own
    graph is read once per test session."""
    if modules is None:
        return _package_graph()
    return {name: package_imports(path, modules, root) - {name} for name, path in modules.items()}


@functools.cache
def _package_graph() -> dict[str, set[str]]:
    return {name: package_imports(path) - {name} for name, path in MODULES.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of ``graph`` with more than one module, or one module
    importing itself (Tarjan's algorithm, iterative), each sorted, sorted by first name."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1 or node in graph.get(node, ()):
                    found.append(sorted(component))
    return sorted(found)


def test_circle_finder_finds_circles_and_only_circles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": {"e"}, "e": set(), "f": {"f"}, "g": {"e", "d"}}
    assert circles(graph) == [["a", "b", "c"], ["f"]]
    assert circles({"x": {"y"}, "y": set()}) == []


def test_package_imports_follow_the_package_rule(tmp_path):
    """A submodule import is an edge to the submodule; a name re-exported by an ``__init__`` is
    an edge to the ``__init__``; imports inside functions and TYPE_CHECKING blocks count."""
    pkg = tmp_path / "bulletnav"
    (pkg / "sub").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "sub/__init__.py": "from bulletnav.sub.a import A\n",
        "sub/a.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from bulletnav.sub.b import B\nA = 1\n",
        "sub/b.py": "def f():\n    from . import a\n    from bulletnav.sub import A\n",
        "c.py": "import bulletnav.sub.b\nfrom bulletnav.sub import a\nimport os\n",
    }
    for name, text in files.items():
        (pkg / name).write_text(text)
    modules = {_module_name(path, tmp_path): path for path in sorted(pkg.rglob("*.py"))}
    graph = import_graph(modules, root=tmp_path)
    assert graph["bulletnav.c"] == {"bulletnav.sub.b", "bulletnav.sub.a"}  # no edge to bulletnav.sub's __init__
    assert graph["bulletnav.sub.a"] == {"bulletnav.sub.b"}
    assert graph["bulletnav.sub.b"] == {"bulletnav.sub.a", "bulletnav.sub"}  # ``A`` through the __init__
    # b -> sub (the re-export) -> a -> b: a real circle; c's submodule imports add none
    assert circles(graph) == [["bulletnav.sub", "bulletnav.sub.a", "bulletnav.sub.b"]]


def test_the_package_import_graph_has_no_circles():
    graph = import_graph()
    assert len(graph) >= 80 and graph["bulletnav.envs.scene"]  # the scan found the package and its imports
    found = circles(graph)
    assert not found, "import circles (each a set of modules that import each other):\n" + "\n".join(
        " <-> ".join(c) for c in found)


def layer_of(module: str) -> int:
    """The index in :data:`LAYERS` of ``module`` (by its longest listed prefix).

    Raises:
        KeyError: the module is in no layer.
    """
    best, found = -1, None
    for i, names in enumerate(LAYERS):
        for name in names:
            full = "bulletnav" if name == "bulletnav" else f"bulletnav.{name}"
            if (module == full or (name != "bulletnav" and module.startswith(full + "."))) and len(full) > best:
                best, found = len(full), i
    if found is None:
        raise KeyError(f"{module} is in no layer of LAYERS: add it to the layer it belongs to")
    return found


def test_every_module_has_a_layer_and_layers_are_disjoint():
    names = [n for layer in LAYERS for n in layer]
    assert len(names) == len(set(names))
    assert layer_of("bulletnav.sim.layout") == layer_of("bulletnav.sim") < layer_of("bulletnav.viz.plots")
    assert layer_of("bulletnav") == 0
    missing = []
    for module in MODULES:
        try:
            layer_of(module)
        except KeyError as exc:
            missing.append(str(exc))
    assert not missing, "\n".join(missing)


def test_no_module_imports_a_higher_layer():
    upward = []
    for module, imports in import_graph().items():
        for target in sorted(imports):
            if layer_of(target) > layer_of(module):
                upward.append(f"{_rel(MODULES[module])}: imports {target} "
                              f"(layer {LAYERS[layer_of(target)]} above {LAYERS[layer_of(module)]})")
    assert not upward, "imports of a higher layer:\n" + "\n".join(upward)


SIBLINGS_APART: dict[tuple[str, str], str] = {
    ("fleet", "benchmark"): "the fleet comparison runs on bulletnav.runs (row log, pool, strict JSON), as the "
                            "benchmark runner does; the proxemic zones it shares are bulletnav.evaluation's",
    ("benchmark", "fleet"): "the benchmark scores single-robot episodes; it has no use for the fleet",
}
"""Units of one layer that must not import each other, anywhere in a file (functions and
``TYPE_CHECKING`` blocks count, as everywhere in :func:`import_graph`): (importer, imported) ->
why. No import between them is allowed, lazy or not."""


def unit_of(module: str) -> str:
    """The unit of :data:`LAYERS` a module belongs to: ``bulletnav.fleet.compare`` -> ``fleet``."""
    return "bulletnav" if module == "bulletnav" else module.split(".")[1]


def unit_graph(graph: dict[str, set[str]] | None = None) -> dict[str, set[str]]:
    """The import graph between units (subpackages and top-level modules): unit -> the other
    units some module of it imports (module-level, function-level and ``TYPE_CHECKING`` imports
    alike)."""
    graph = import_graph() if graph is None else graph
    units: dict[str, set[str]] = {}
    for module, imports in graph.items():
        units.setdefault(unit_of(module), set()).update(unit_of(t) for t in imports)
    return {u: targets - {u} for u, targets in units.items()}


def layer_graph_text(graph: dict[str, set[str]] | None = None) -> str:
    """The layers, lowest first, each unit with the units it imports (``python tests/test_architecture.py``)."""
    units = unit_graph(graph)
    lines = []
    for i, names in enumerate(LAYERS):
        lines.append(f"layer {i}: " + ", ".join(
            f"{n} -> {{{', '.join(sorted(units.get(n, ())))}}}" for n in names))
    return "\n".join(lines)


def test_the_unit_graph_has_no_circles_and_siblings_stay_apart():
    """Between subpackages too (a circle of units is a circle of layers), and fleet and
    benchmark, which share a layer, import nothing of each other."""
    units = unit_graph()
    assert {"fleet", "benchmark", "runs", "cli"} <= set(units) and "runs" in units["fleet"] and "runs" in units["benchmark"]
    found = circles(units)
    assert not found, "circles between subpackages:\n" + "\n".join(" <-> ".join(c) for c in found)
    apart = [f"{_rel(MODULES[m])}: imports {t} ({why})" for (a, b), why in SIBLINGS_APART.items()
             for m, imports in import_graph().items() if unit_of(m) == a for t in sorted(imports) if unit_of(t) == b]
    assert not apart, "imports between siblings that stay apart:\n" + "\n".join(apart)
    # the check sees a lazy import: one inside a function makes fleet import benchmark
    lazy = {**import_graph(), "bulletnav.fleet.probe": {"bulletnav.benchmark.runner"}}
    assert "benchmark" in unit_graph(lazy)["fleet"]


IMPORT_IN_LAYER_ORDER = r"""
import importlib, json, sys
order, layers = json.loads(sys.argv[1]), json.loads(sys.argv[2])
for name in order:
    before = {m for m in sys.modules if m == "bulletnav" or m.startswith("bulletnav.")}
    importlib.import_module(name)
    loaded = sorted(m for m in sys.modules if (m == "bulletnav" or m.startswith("bulletnav.")) and m not in before)
    higher = [m for m in loaded if m in layers and layers[m] > layers[name]]
    if higher:
        sys.exit(f"importing {name} (layer {layers[name]}) loaded higher layers: {higher}")
print(len(order))
"""


@pytest.mark.slow
def test_every_module_imports_in_a_fresh_process_in_layer_order():
    """One fresh interpreter imports every module, lowest layer first; each import must work
    with only lower layers loaded and must load no module of a higher layer."""
    import json
    import sys

    layers = {m: layer_of(m) for m in MODULES}
    order = sorted(MODULES, key=lambda m: (layers[m], m))
    done = hang.run([sys.executable, "-c", IMPORT_IN_LAYER_ORDER, json.dumps(order), json.dumps(layers)],
                    "importing every module in layer order", cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    assert int(done.stdout.split()[-1]) == len(MODULES)


def test_tasks_see_the_scene_through_the_protocol():
    """Both scenes a task runs on satisfy :class:`~bulletnav.tasks.view.TaskScene`, and no task
    module imports the env package."""
    import gymnasium as gym

    from bulletnav.fleet.scene import RobotSlot
    from bulletnav.tasks.view import TaskScene

    bad = _forbidden_imports("tasks", ("bulletnav.envs", "bulletnav.fleet"))
    assert not bad, "tasks see the scene through bulletnav.tasks.view.TaskScene:\n" + "\n".join(bad)
    env = gym.make("bulletnav/Warehouse-v0")
    try:
        env.reset(seed=0)
        assert isinstance(env.unwrapped._scene, TaskScene)
    finally:
        env.close()
    members = ("layout", "free_space", "geometry", "robot", "sensors", "place_robot", "in_collision", "nearest_mover")
    init = ast.unparse(ast.parse((PKG / "fleet" / "scene.py").read_text()))
    missing = [m for m in members if not hasattr(RobotSlot, m) and f"self.{m} =" not in init]
    assert not missing, f"RobotSlot lacks {missing} of TaskScene"
    assert not isinstance(object(), TaskScene)  # the check can fail


# ---------------------------------------------------------------------------------------
# (e) one module writes files

WRITER = PKG / "files.py"

RENAMES_AND_TEMP_FILES = {("os", "replace"), ("os", "rename"), ("os", "renames"), ("tempfile", "mkstemp"),
                          ("tempfile", "mktemp"), ("tempfile", "NamedTemporaryFile")}
"""``module.function`` pairs that make a temporary file or move one into place: only
:mod:`bulletnav.files` calls them (scratch folders, ``tempfile.mkdtemp`` and
``TemporaryDirectory``, are not output files and may be made anywhere)."""


def temp_file_calls(source: str, filename: str) -> list[str]:
    """``file:line: what`` for every call in ``source`` of :data:`RENAMES_AND_TEMP_FILES`, as
    ``os.replace(...)``, through an alias (``import os as o``) or imported by name (``from os
    import replace``)."""
    tree = ast.parse(source, filename)
    modules: dict[str, str] = {}   # local name -> module, for ``import os [as o]``
    functions: dict[str, str] = {}  # local name -> "module.function", for ``from os import replace``
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            modules.update({alias.asname or alias.name: alias.name for alias in node.names})
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            functions.update({alias.asname or alias.name: f"{node.module}.{alias.name}" for alias in node.names
                              if (node.module, alias.name) in RENAMES_AND_TEMP_FILES})
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if (isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name)
                and (modules.get(func.value.id), func.attr) in RENAMES_AND_TEMP_FILES):
            found.append(f"{filename}:{node.lineno}: {modules[func.value.id]}.{func.attr}")
        elif isinstance(func, ast.Name) and func.id in functions:
            found.append(f"{filename}:{node.lineno}: {functions[func.id]}")
    return found


def test_temp_file_checker_flags_what_it_should():
    snippet = ("import os\nimport os as o\nimport tempfile\nfrom os import replace as mv\nfrom tempfile import mkdtemp\n"
               "os.replace(a, b)\n"                  # 6
               "o.rename(a, b)\n"                    # 7
               "tempfile.NamedTemporaryFile()\n"     # 8
               "mv(a, b)\n"                          # 9
               "mkdtemp()\n"                         # 10: a scratch folder, allowed
               "'x'.replace('a', 'b')\n"             # 11: str.replace, allowed
               "path.replace(b)\n"                   # 12: not the os module, allowed
               "tempfile.TemporaryDirectory()\n")    # 13: allowed
    found = temp_file_calls(snippet, "m.py")
    assert [f.split(":")[1] for f in found] == ["6", "7", "8", "9"], found


def test_only_the_files_module_makes_temp_files_and_renames():
    scanned = sorted(PKG.rglob("*.py"))
    assert WRITER in scanned and temp_file_calls(WRITER.read_text(), _rel(WRITER))  # the scan sees the writer's own
    found = [f for path in scanned if path != WRITER for f in temp_file_calls(path.read_text(), _rel(path))]
    assert not found, "files are written through bulletnav.files (temp file + os.replace, one permission rule):\n" + \
        "\n".join(found)


@pytest.fixture
def umask_027():
    """The process umask set to 027 (not the usual 022, so the rule is seen to follow it)."""
    old = os.umask(0o027)
    try:
        yield 0o027
    finally:
        os.umask(old)


class _Crash(Exception):
    pass


def test_a_write_that_fails_midway_leaves_the_old_file_whole_and_no_temp_file(tmp_path, umask_027):
    from bulletnav import files

    target = tmp_path / "out" / "data.bin"
    files.write_bytes(target, b"old contents")
    assert target.read_bytes() == b"old contents"
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask_027 == 0o640  # what open() gives a new file

    def half_then_crash(f):
        f.write(b"new cont")
        raise _Crash

    with pytest.raises(_Crash):
        files.write_with(target, half_then_crash)
    assert target.read_bytes() == b"old contents"
    assert sorted(p.name for p in target.parent.iterdir()) == ["data.bin"]

    # a streaming writer's temp file: created with the rule's mode, discarded or put in place
    tmp = files.temp_path(target, ".mp4")
    assert tmp.parent == target.parent and tmp.name.startswith(".data.bin.") and tmp.name.endswith(".tmp.mp4")
    assert tmp.stat().st_mode & 0o777 == 0o640
    files.discard(tmp)
    assert sorted(p.name for p in target.parent.iterdir()) == ["data.bin"]
    tmp = files.temp_path(target)
    tmp.write_bytes(b"streamed")
    os.chmod(target, 0o600)  # an existing file's mode is not kept: the new file follows the rule
    files.finish(tmp, target)
    assert target.read_bytes() == b"streamed" and target.stat().st_mode & 0o777 == 0o640
    assert sorted(p.name for p in target.parent.iterdir()) == ["data.bin"]


def test_a_failed_rename_removes_the_temp_file(tmp_path, monkeypatch):
    from bulletnav import files

    target = tmp_path / "data.json"
    files.write_json(target, {"a": 1})

    def refuse(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError, match="disk full"):
        files.write_json(target, {"a": 2})
    tmp = files.temp_path(target)
    with pytest.raises(OSError, match="disk full"):
        files.finish(tmp, target)
    monkeypatch.undo()
    assert json.loads(target.read_text()) == {"a": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["data.json"]


def test_the_writers_write_what_they_are_given(tmp_path):
    """Bytes, text and JSON byte for byte as the standard library writes them; a PNG that
    Pillow reads back pixel for pixel."""
    import numpy as np
    from PIL import Image

    from bulletnav import files

    assert files.write_bytes(tmp_path / "a.bin", b"\x00\xff").read_bytes() == b"\x00\xff"
    assert files.write_text(tmp_path / "b.txt", "é\n").read_bytes() == "é\n".encode()
    record = {"x": np.float32(0.5), "n": np.int64(3), "v": np.arange(3), "p": Path("/a"), "t": int}
    files.write_json(tmp_path / "c.json", record)
    assert (tmp_path / "c.json").read_text() == json.dumps(
        {"x": 0.5, "n": 3, "v": [0, 1, 2], "p": "/a", "t": "builtins.int"}, indent=2) + "\n"
    with pytest.raises(TypeError):
        files.write_json(tmp_path / "d.json", {"s": {1, 2}})
    assert not (tmp_path / "d.json").exists()
    image = np.random.default_rng(0).integers(0, 256, (7, 5, 3), dtype=np.uint8)
    files.save_image(image, tmp_path / "e.png", optimize=True)
    assert np.array_equal(np.asarray(Image.open(tmp_path / "e.png")), image)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "b.txt", "c.json", "e.png"]


# ---------------------------------------------------------------------------------------
# (f) no function over 80 lines

MAX_FUNCTION_LINES = 80
"""The most lines a function of the package may span, from its ``def`` to its last line
(decorators not counted), except the numeric kernels in :data:`LONG_FUNCTIONS`. Ruff's
``C901`` and ``PLR0915`` (pyproject.toml) bound the branches and statements of the same
functions; ruff has no rule for lines."""

LONG_FUNCTIONS = {
    "bulletnav/planning/astar.py::_astar_kernel": (
        "numba kernel: 8-connected A* over a flattened, bordered grid with its binary heap (integer "
        "keys ordering f) pushed and popped inline in one compiled loop; its paths are pinned bit for "
        "bit by the golden traces, and the loop's state (heap, g, parents, flags) is one unit"),
}
"""``"path::qualified name"`` -> why it may be longer than :data:`MAX_FUNCTION_LINES` (numeric
kernels only, each still over the limit: a stale entry fails)."""


def function_lengths(source: str, filename: str) -> dict[str, int]:
    """``"filename::qualified name"`` (``Class.method``, ``outer.inner``) -> lines spanned, of
    every function and method in ``source``."""
    out: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = f"{prefix}{child.name}"
                out[f"{filename}::{name}"] = child.end_lineno - child.lineno + 1
                visit(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(source, filename), "")
    return out


def test_function_length_checker_measures_what_it_should():
    snippet = ("@decorator\n"                   # line 1: not counted
               "def f(x):\n"                     # line 2
               "    def g():\n"                  # line 3
               "        return 1\n"              # line 4
               "    return g() + x\n"            # line 5
               "class C:\n"
               "    def m(self):\n"
               "        if self:\n"
               "            pass\n"
               "\n"
               "        return None\n"
               "async def h():\n"
               "    pass\n")
    assert function_lengths(snippet, "s.py") == {"s.py::f": 4, "s.py::f.g": 2, "s.py::C.m": 5, "s.py::h": 2}


def test_no_function_is_over_80_lines_but_the_listed_kernels():
    lengths = {k: n for path in sorted(PKG.rglob("*.py")) for k, n in function_lengths(path.read_text(), _rel(path)).items()}
    assert len(lengths) > 1000  # the walk found the package's functions
    long = {k: n for k, n in lengths.items() if n > MAX_FUNCTION_LINES and k not in LONG_FUNCTIONS}
    assert not long, (f"functions over {MAX_FUNCTION_LINES} lines (split them along their seams; only numeric "
                      f"kernels may be listed in LONG_FUNCTIONS, with the reason):\n"
                      + "\n".join(f"{n:4d} {k}" for k, n in sorted(long.items(), key=lambda e: -e[1])))
    stale = {k: lengths.get(k) for k in LONG_FUNCTIONS if lengths.get(k, 0) <= MAX_FUNCTION_LINES}
    assert not stale, f"LONG_FUNCTIONS entries gone or no longer over {MAX_FUNCTION_LINES} lines (remove them): {stale}"


if __name__ == "__main__":
    print(layer_graph_text())
