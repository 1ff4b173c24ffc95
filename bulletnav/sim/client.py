"""PyBullet connection handling: one physics client per world, never the global default."""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import socket
import time
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


X_OPEN_TRIES = 10
"""Times a GUI connect (and :func:`display_accepts`) tries to open the display before it gives up."""
X_OPEN_PAUSE_S = 0.2
"""Seconds between those tries."""


def _xlib() -> ctypes.CDLL | None:
    """Xlib (``libX11``), the library PyBullet's GUI opens its window with, or None where it is absent."""
    name = ctypes.util.find_library("X11")
    if name is None:
        return None
    try:
        lib = ctypes.CDLL(name)
    except OSError:
        return None
    lib.XOpenDisplay.restype = ctypes.c_void_p
    lib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    lib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    return lib


class _HeldDisplay:
    """An open Xlib connection (or, where libX11 is absent, a stand-in), closed by :meth:`close`."""

    def __init__(self, lib: ctypes.CDLL | None = None, handle: int | None = None) -> None:
        self._lib, self._handle = lib, handle

    def close(self) -> None:
        if self._lib is not None and self._handle:
            self._lib.XCloseDisplay(self._handle)
        self._handle = None


def _open_display(display: str | None, tries: int, pause_s: float) -> _HeldDisplay | None:
    """Open ``display`` with Xlib, up to ``tries`` times ``pause_s`` apart; None when refused
    (the caller has checked that its socket answers, :func:`display_available`)."""
    lib = _xlib()
    if lib is None:
        return _HeldDisplay()
    name = None if display is None else display.encode()
    for attempt in range(tries):
        handle = lib.XOpenDisplay(name)
        if handle:
            if attempt:
                log.info("X display opened on try %d of %d", attempt + 1, tries)
            return _HeldDisplay(lib, handle)
        time.sleep(pause_s)
    return None


def display_accepts(display: str | None = None, tries: int = X_OPEN_TRIES, pause_s: float = X_OPEN_PAUSE_S) -> bool:
    """True when Xlib can open ``display`` (default ``$DISPLAY``) as PyBullet's GUI thread will:
    the X connection itself, with the authority in ``$XAUTHORITY``, not only its socket. It
    tries up to ``tries`` times ``pause_s`` apart (a server that has just started, or is
    resetting, refuses a client); where Xlib cannot be loaded the socket check
    :func:`display_available` stands in.
    """
    held = _open_display(display, tries, pause_s) if display_available(display) else None
    if held is None:
        return False
    held.close()
    return True


def connect(gui: bool = False, options: str = "") -> int:
    """Open a new physics client and return its id.

    For the GUI this process first opens the X display itself (:func:`display_accepts`'s
    tries) and holds that connection until PyBullet's GUI thread has opened its own. PyBullet's
    GUI thread calls ``exit()`` when its ``XOpenDisplay`` fails, which ends the process with
    status 1, or deadlocks it (torch's exit handlers wait for the interpreter lock, which the
    main thread holds while it waits for the GUI). An X server without ``-noreset`` (Xvfb's and
    ``xvfb-run``'s default) resets when its last client disconnects and refuses clients while
    it does; a connection opened and closed just before PyBullet's would leave PyBullet to
    meet that reset (measured: 82 of 600 opens right after a close refused on Xvfb 21.1.7,
    none with ``-noreset``). Held open, it keeps the server from resetting.

    Raises:
        DisplayError: ``gui`` is True and no X display is reachable, or it refuses this
            process's connection.
    """
    if gui:
        shown = os.environ.get("DISPLAY")
        if not display_available():
            raise DisplayError(
                "render_mode='human' / --gui needs an X display, but "
                + (f"DISPLAY={shown!r} does not answer" if shown else "DISPLAY is not set")
                + "; run under `xvfb-run -a` or use headless mode"
            )
        held = _open_display(None, X_OPEN_TRIES, X_OPEN_PAUSE_S)
        if held is None:
            raise DisplayError(
                f"render_mode='human' / --gui: the X display DISPLAY={shown!r} answers but refused the connection "
                f"(XAUTHORITY={os.environ.get('XAUTHORITY', '')!r}; {X_OPEN_TRIES} tries over "
                f"{X_OPEN_TRIES * X_OPEN_PAUSE_S:g} s); check its authority, "
                "or run under `xvfb-run -a` or use headless mode"
            )
        try:
            cid = p.connect(p.GUI, options=options)
        finally:
            held.close()
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
