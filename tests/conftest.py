"""Shared fixtures: layouts written as YAML files, simulation and scene factories."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

from bulletnav.config import EnvConfig, PhysicsConfig, RobotConfig, SensorsConfig
from bulletnav.envs.scene import Scene
from bulletnav.sim.layout import Layout, load_layout
from bulletnav.sim.simulation import Simulation
from hang import HANG_S

# One math thread per test process (unless the caller chose): `make test` runs two pytest workers
# on two cores, and torch's default of one OpenMP thread per core in each of them made test_rl's
# models (evaluation, loading, prediction) about 15 % slower than one thread each (111 s against
# 130 s for `pytest -n 2 tests/test_rl.py`). Set before anything imports torch (the imports above
# do not); the tests' subprocesses inherit it. Training pins one thread anyway.
for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


@pytest.fixture
def write_layout(tmp_path: Path):
    """Write a layout dict as YAML and load it back through the public loader."""

    def _write(data: dict, name: str = "layout.yaml") -> Layout:
        path = tmp_path / name
        path.write_text(yaml.safe_dump(data))
        return load_layout(path)

    return _write


@pytest.fixture
def make_sim():
    """Physics-only simulations (world and robot, no sensors), closed after the test."""
    sims: list[Simulation] = []

    def _make(physics: PhysicsConfig = PhysicsConfig(), robot: RobotConfig = RobotConfig()) -> Simulation:
        sim = Simulation(physics=physics, robot=robot)
        sims.append(sim)
        return sim

    yield _make
    for sim in sims:
        sim.close()


@pytest.fixture
def make_scene():
    """Scenes (physics + the robot's sensors, as an env has them), closed after the test.

    ``place(scene, layout, start, rng)`` starts an episode in one."""
    scenes: list[Scene] = []

    def _make(sensors: SensorsConfig = SensorsConfig(), physics: PhysicsConfig = PhysicsConfig()) -> Scene:
        scene = Scene(EnvConfig(sensors=sensors, physics=physics))
        scenes.append(scene)
        return scene

    yield _make
    for scene in scenes:
        scene.close()


def place(scene: Scene, layout: Layout, start: tuple[float, float, float], rng: np.random.Generator) -> None:
    """Start an episode of ``scene`` in ``layout`` with the robot at rest at ``start``; the
    sensors draw their noise generators from ``rng``."""
    scene.use_layout(layout)
    scene.place_robot(start, rng)


def drive(target: Simulation | Scene, v: float, w: float, seconds: float) -> None:
    """Hold the command (v, w) for ``seconds`` of simulated time (on a simulation, or on a
    scene, whose sensors then update every step)."""
    physics = target.config.physics if isinstance(target, Scene) else target.physics
    for _ in range(int(round(seconds * physics.control_hz))):
        target.step(v, w)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


_MEASUREMENTS: list[tuple[str, str]] = []


@pytest.fixture
def report(request):
    """Record a measured figure; all are printed in a 'measurements' section after the run."""

    def _report(what: str, value: str) -> None:
        # carried on the test's reports, so they reach the controller of a pytest-xdist run too
        request.node.user_properties.append((_MEASUREMENT, (f"{request.node.name}: {what}", str(value))))

    return _report


_MEASUREMENT = "bulletnav_measurement"


def pytest_runtest_logreport(report):
    """Collect the measurements a test recorded (its teardown report carries them all)."""
    if report.when == "teardown":
        _MEASUREMENTS.extend(tuple(v) for k, v in report.user_properties if k == _MEASUREMENT)


_GUI_CHILD = "BULLETNAV_GUI_TEST_CHILD"
"""Set in the child process that runs one GUI test (see :func:`pytest_pyfunc_call`); its value
is the file the child writes its verdict and measurements to when its session finishes."""


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """Run each test that opens PyBullet's GUI (uses the ``display`` fixture) in a fresh child
    process. PyBullet allows one in-process GUI at a time, and after several GUI connections and
    disconnections in one process a connection has been seen to hang for ever (the GUI thread
    gone, the main thread polling for it) once torch is imported; one GUI session per process,
    as every user command has, does not. The child's failure fails the test with its output.

    The child runs with ``--capture=sys``: what C code writes (PyBullet's GUI thread, Xlib) goes
    straight to the parent, so a child that dies in C still shows why. A child that never
    reaches a verdict is run once more in a new child: one that hangs (PyBullet's GUI connection
    has, rarely, hung in a fresh process under Xvfb: once in a clean-clone `make test` of
    2026-11-24) is killed after ``hang.HANG_S`` s (900, generous: a limit, not a speed check), and one that ends without its session
    finishing (PyBullet's GUI thread calls exit(1) when the X server fails it, and Xlib does on
    a broken connection: once in CI on 2026-11-27, exit 1 and no output, as the old fd capture
    swallowed it; both were PyBullet's GUI thread refused by an Xvfb resetting after its last
    client left, which :func:`bulletnav.sim.client.connect` now prevents) is rerun at once.
    A second child without a verdict fails the test; a verdict, passed or failed, is never
    retried."""
    import json
    import os
    import subprocess
    import sys
    import tempfile

    if "display" not in pyfuncitem.fixturenames or os.environ.get(_GUI_CHILD):
        return None
    with tempfile.TemporaryDirectory() as tmp:
        verdict = Path(tmp) / "verdict.json"
        env = {**os.environ, _GUI_CHILD: str(verdict)}
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--no-header", "--capture=sys",
               pyfuncitem.nodeid]
        first = ""
        for attempt in (1, 2):
            verdict.unlink(missing_ok=True)
            try:
                out = subprocess.run(cmd, env=env, cwd=pyfuncitem.config.rootpath, capture_output=True, text=True,
                                     timeout=HANG_S)
            except subprocess.TimeoutExpired as exc:
                what = f"its GUI child did not finish in {exc.timeout:.0f} s: a hang? (a hang detector, not a speed check)"
                output = f"{_text(exc.stdout)[-4000:]}\n{_text(exc.stderr)[-2000:]}"
            else:
                if verdict.exists():
                    break
                what = (f"its GUI child ended (exit {out.returncode}) before its session finished, "
                        f"DISPLAY={os.environ.get('DISPLAY')!r}")
                output = f"{out.stdout[-4000:]}\n{out.stderr[-2000:]}"
            if attempt == 2:
                pytest.fail(f"GUI test {pyfuncitem.nodeid}: {what}, and the first time {first}; its output:\n{output}",
                            pytrace=False)
            first = what
            pyfuncitem.warn(pytest.PytestWarning(f"{what}; its output:\n{output}\nrun once more in a new one"))
        result = json.loads(verdict.read_text())
        pyfuncitem.user_properties.extend((_MEASUREMENT, tuple(m)) for m in result["measurements"])
    if result["exitstatus"] != 0:
        pytest.fail(f"GUI test failed in its child process (exit {out.returncode}):\n{out.stdout[-6000:]}\n{out.stderr[-2000:]}",
                    pytrace=False)
    return True


def _text(output: str | bytes | None) -> str:
    """A child's output as text (``TimeoutExpired`` may carry bytes, or nothing)."""
    if isinstance(output, bytes):
        return output.decode(errors="replace")
    return output or ""


def pytest_sessionfinish(session, exitstatus):
    import json
    import os

    path = os.environ.get(_GUI_CHILD)
    if path:  # a GUI test's child: hand its verdict and measurements to the parent
        Path(path).write_text(json.dumps({"exitstatus": int(exitstatus), "measurements": _MEASUREMENTS}))


def pytest_terminal_summary(terminalreporter, config):
    import os

    if _MEASUREMENTS and not os.environ.get(_GUI_CHILD) and not hasattr(config, "workerinput"):
        terminalreporter.section("measurements")
        for what, value in _MEASUREMENTS:
            terminalreporter.write_line(f"{what} = {value}")


_GUI_PROBE = ("import pybullet as p; from bulletnav.sim.client import connect; "
              "p.disconnect(connect(gui=True)); print('gui ok')")


def _gui_opens(display: str) -> bool:
    """PyBullet's GUI opens on ``display``, connected as the library connects it (tried in a
    child process: when it cannot open the display, PyBullet calls exit() in its GUI thread,
    which ends the process with status 1, or deadlocks it once torch is imported)."""
    import os
    import subprocess
    import sys

    try:
        out = subprocess.run([sys.executable, "-c", _GUI_PROBE], env={**os.environ, "DISPLAY": display},
                             capture_output=True, text=True, timeout=180)  # generous: a loaded machine is slow to open it
    except subprocess.TimeoutExpired:
        return False
    return out.returncode == 0 and "gui ok" in out.stdout


@contextlib.contextmanager
def _xvfb(number: int, *args: str, wait_s: float = 120.0):
    """An Xvfb on ``:number`` (extra server ``args``), waited on until its socket answers (at
    most ``wait_s``), terminated on leaving."""
    import subprocess
    import time

    from bulletnav.sim.client import display_available

    server = subprocess.Popen(["Xvfb", f":{number}", *args, "-nolisten", "tcp"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + wait_s
        while not display_available(f":{number}") and time.monotonic() < deadline:
            time.sleep(0.05)
        yield
    finally:
        server.terminate()
        server.wait(timeout=10)


@pytest.fixture(scope="session")
def display():
    """An X display for GUI tests: the current one if it answers, else a private Xvfb on which
    PyBullet's GUI has been seen to open (a fresh Xvfb now and then refuses PyBullet's first
    connection; a new one is started then, up to three times)."""
    import os
    import shutil

    from bulletnav.sim.client import display_available

    if display_available():
        yield os.environ["DISPLAY"]
        return
    if shutil.which("Xvfb") is None:
        pytest.skip("no X display and Xvfb is not installed (apt-get install xvfb)")
    old = os.environ.get("DISPLAY")
    server = contextlib.ExitStack()
    for attempt in range(3):
        number = 90 + (os.getpid() + 7 * attempt) % 500
        server.enter_context(_xvfb(number, "-screen", "0", "1024x768x24", wait_s=5.0))
        if display_available(f":{number}") and _gui_opens(f":{number}"):
            break
        server.close()
    else:
        pytest.skip("PyBullet's GUI could not open a private Xvfb (3 tries)")
    os.environ["DISPLAY"] = f":{number}"
    yield os.environ["DISPLAY"]
    server.close()
    if old is None:
        os.environ.pop("DISPLAY", None)
    else:
        os.environ["DISPLAY"] = old


@pytest.fixture
def drawn_texts(monkeypatch) -> list[str]:
    """Every text handed to PyBullet's ``addUserDebugText`` during the test, in order (each is
    still drawn)."""
    import pybullet

    texts: list[str] = []
    real_text = pybullet.addUserDebugText

    def counting_text(text, *args, **kwargs):
        texts.append(text)
        return real_text(text, *args, **kwargs)

    monkeypatch.setattr(pybullet, "addUserDebugText", counting_text)
    return texts


def bit_equal(a, b) -> bool:
    """Exact equality of nested dicts, sequences and arrays (same dtypes, same bits, same types)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(bit_equal(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(bit_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b)
    return a == b and type(a) is type(b)


LONGEST = ("test_sweep", "test_rl", "test_demo", "test_benchmark", "test_env", "test_shield", "test_nothing_lost",
           "test_fleet_controllers", "test_viz", "test_golden", "test_movers", "test_fleet_compare", "test_json_output")
"""The modules that took longest in `make test`, longest first (each module's tests' setup and call
times summed, from ``pytest -n 2 --dist loadfile --durations=0`` on a quiet 2-core machine: 282 s
for test_sweep down to 41 s for test_json_output). Only an order: a stale entry costs speed,
never a result."""


def pytest_collection_modifyitems(config, items):
    """The longest modules first (:data:`LONGEST`), then the others with the most ``slow`` tests
    first (their order otherwise kept): `make test` hands whole modules to its two pytest-xdist
    workers in this order (``--no-loadscope-reorder``: xdist's own order, by the number of tests in
    a module, would leave test_demo's five long tests among the last), and a long module left to
    the end would keep one worker busy while the other idles."""
    slow: dict[str, int] = {}
    for item in items:
        slow[item.module.__name__] = slow.get(item.module.__name__, 0) + (item.get_closest_marker("slow") is not None)

    def key(item) -> tuple[int, int]:
        name = item.module.__name__
        return (LONGEST.index(name) if name in LONGEST else len(LONGEST), -slow[name])

    items.sort(key=key)
