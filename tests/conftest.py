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
