"""Shared fixtures: layouts written as YAML files, and a simulation factory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from bulletnav.config import PhysicsConfig, SensorsConfig
from bulletnav.sim.layout import Layout, load_layout
from bulletnav.sim.simulation import Simulation


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
    """Simulations that are closed after the test."""
    sims: list[Simulation] = []

    def _make(sensors: SensorsConfig = SensorsConfig(), physics: PhysicsConfig = PhysicsConfig()) -> Simulation:
        sim = Simulation(physics=physics, sensors=sensors)
        sims.append(sim)
        return sim

    yield _make
    for sim in sims:
        sim.close()


def drive(sim: Simulation, v: float, w: float, seconds: float) -> None:
    """Hold the command (v, w) for ``seconds`` of simulated time."""
    for _ in range(int(round(seconds * sim.physics.control_hz))):
        sim.step(v, w)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


_MEASUREMENTS: list[tuple[str, str]] = []


@pytest.fixture
def report(request):
    """Record a measured figure; all are printed in a 'measurements' section after the run."""

    def _report(what: str, value: str) -> None:
        _MEASUREMENTS.append((f"{request.node.name}: {what}", value))

    return _report


def pytest_terminal_summary(terminalreporter):
    if _MEASUREMENTS:
        terminalreporter.section("measurements")
        for what, value in _MEASUREMENTS:
            terminalreporter.write_line(f"{what} = {value}")


@pytest.fixture(scope="session")
def display():
    """An X display for GUI tests: the current one if it answers, else a private Xvfb."""
    import os
    import shutil
    import subprocess
    import time

    from bulletnav.sim.client import display_available

    if display_available():
        yield os.environ["DISPLAY"]
        return
    if shutil.which("Xvfb") is None:
        pytest.skip("no X display and Xvfb is not installed (apt-get install xvfb)")
    number = 90 + os.getpid() % 500
    proc = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    old = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = f":{number}"
    for _ in range(100):
        if display_available():
            break
        time.sleep(0.05)
    else:
        proc.kill()
        pytest.skip("Xvfb did not start")
    yield os.environ["DISPLAY"]
    proc.terminate()
    proc.wait(timeout=10)
    if old is None:
        os.environ.pop("DISPLAY", None)
    else:
        os.environ["DISPLAY"] = old
