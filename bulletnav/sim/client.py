"""PyBullet connection handling: one physics client per world, never the global default."""

from __future__ import annotations

import logging
import os
import socket
from dataclasses import dataclass

import pybullet as p

from bulletnav.config import PhysicsConfig
from bulletnav.errors import DisplayError

log = logging.getLogger(__name__)


def display_available(display: str | None = None) -> bool:
    """True when an X server answers on ``display`` (default ``$DISPLAY``).

    PyBullet's GUI connect kills the whole process when there is no X server, so every GUI
    request checks this first.
    """
    display = os.environ.get("DISPLAY") if display is None else display
    if not display:
        return False
    host, _, rest = display.rpartition(":")
    number = rest.split(".")[0]
    if not number.isdigit():
        return False
    try:
        if host in ("", "unix"):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                s.settimeout(1.0)
                try:
                    s.connect(f"/tmp/.X11-unix/X{number}")
                except OSError:
                    s.connect(f"\0/tmp/.X11-unix/X{number}")  # Linux abstract socket
            return True
        with socket.create_connection((host or "localhost", 6000 + int(number)), timeout=1.0):
            return True
    except OSError:
        return False


def connect(gui: bool = False, options: str = "") -> int:
    """Open a new physics client and return its id.

    Raises:
        DisplayError: ``gui`` is True and no X display is reachable.
    """
    if gui:
        if not display_available():
            raise DisplayError(
                "render_mode='human' / --gui needs an X display, but "
                + (f"DISPLAY={os.environ['DISPLAY']!r} does not answer" if os.environ.get("DISPLAY") else "DISPLAY is not set")
                + "; run under `xvfb-run -a` or use headless mode"
            )
        cid = p.connect(p.GUI, options=options)
    else:
        cid = p.connect(p.DIRECT)
    if cid < 0:
        raise RuntimeError("pybullet.connect failed")
    log.debug("connected pybullet client %d (gui=%s)", cid, gui)
    return cid


def configure_physics(cid: int, physics: PhysicsConfig) -> None:
    """Apply time step, gravity and solver settings to client ``cid``."""
    p.setGravity(0.0, 0.0, -physics.gravity, physicsClientId=cid)
    p.setPhysicsEngineParameter(
        fixedTimeStep=physics.physics_dt,
        numSubSteps=0,
        numSolverIterations=physics.solver_iterations,
        solverResidualThreshold=physics.solver_residual_threshold,
        enableConeFriction=int(physics.cone_friction),
        physicsClientId=cid,
    )


@dataclass
class Clock:
    """Simulated time shared by a simulation and its sensors."""

    physics_dt: float
    """Seconds per physics step."""
    control_ticks: int = 1
    """Physics steps per control step."""
    tick: int = 0
    """Physics steps since the last reset."""
    episode: int = 0
    """Resets so far; with ``tick`` it keys sensor caches."""

    @property
    def time(self) -> float:
        """Seconds of simulated time since the last reset."""
        return self.tick * self.physics_dt
