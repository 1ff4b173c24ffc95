"""Architecture rules of the package, checked on its source and against PyBullet.

- Consumers (controllers, evaluation, the policy protocol, visualisation, the CLI, RL and
  benchmarks) see an env only through ``obs``, ``info`` and ``env.unwrapped.scene``: no
  private attributes of other objects, no simulation internals.
- ``bulletnav/sim/`` is physics only (no sensors); ``bulletnav/planning/`` holds pure
  algorithms (no simulation, env or sensors).
- The robot's outline, wheels and sensor mounts are read from its URDF in one place
  (:mod:`bulletnav.geometry`), which agrees with what PyBullet loads; the modules that use
  them carry none of the numbers themselves.
"""

from __future__ import annotations

import ast
import io
import math
import re
import tokenize
from pathlib import Path

import pybullet as p
import pytest

import bulletnav
from bulletnav.config import RobotConfig
from bulletnav.geometry import robot_geometry

PKG = Path(bulletnav.__file__).resolve().parent
ROOT = PKG.parent


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


# ---------------------------------------------------------------------------------------
# (a) consumers use obs, info and env.unwrapped.scene only

CONSUMERS = sorted({
    *PKG.glob("control/*.py"), PKG / "evaluation.py", PKG / "policy.py", *PKG.glob("viz/*.py"), PKG / "cli.py",
    *PKG.glob("rl/*.py"), *PKG.glob("bench/*.py"), *PKG.glob("sweep/*.py"), *PKG.glob("benchmark/*.py"),
})
"""Every module that drives or reads an env from outside it."""

SIM_INTERNALS = frozenset({"sim", "task", "robot", "world", "_scene"})
"""Attribute names that reach past the read-only scene view into the env's internals."""

REFLECTION = frozenset({"getattr", "setattr", "hasattr"})

NOT_ENV_INTERNALS = {
    ("bulletnav/cli.py", "args.world"): "the --world option (a layout file path) on argparse's namespace",
    ("bulletnav/bench/env_bench.py", "cfg.robot"): "EnvConfig.robot, the robot's configuration (RobotConfig)",
    ("bulletnav/bench/physics_bench.py", "sim.robot"): "the physics benchmark drives a bare Simulation, no env",
    ("bulletnav/bench/reset_bench.py", "config.robot"): "EnvConfig.robot: the URDF the raw rebuild loads (RobotConfig)",
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
    assert private_access("def f(args):\n    return args.world\n", "bulletnav/cli.py") == []
    assert private_access("def f(args):\n    return args.world\n", "bulletnav/viz/video.py") != []
    assert private_access("def f(env):\n    return env.world\n", "bulletnav/cli.py") != []


def test_consumers_use_only_obs_info_and_the_scene_view():
    assert len(CONSUMERS) >= 20 and PKG / "cli.py" in CONSUMERS  # the globs found the modules
    violations = [v for path in CONSUMERS for v in private_access(path.read_text(), _rel(path))]
    assert not violations, f"{len(violations)} private or internal accesses in consumer modules:\n" + "\n".join(violations)


# ---------------------------------------------------------------------------------------
# (b) the import graph: sim/ is physics only, planning/ is pure algorithms

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
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                module = ".".join([*base, node.module] if node.module else base)
            else:
                module = node.module or ""
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
