"""The coordinated fleet controller's settings (:class:`CoordinatedConfig`): planning,
tracking and the execution rules that keep robots from knotting, each with its unit and the
measurement behind its default."""

from __future__ import annotations

from dataclasses import dataclass, field

from bulletnav.control.navigator import ControllerConfig
from bulletnav.errors import ConfigError


@dataclass(frozen=True)
class CoordinatedConfig:
    """Windowed prioritized planning in space-time, executed without lockstep
    (:class:`~bulletnav.fleet.coordinated.CoordinatedController`)."""

    resolution: float = 0.5
    """Grid cell side (m): one plan step moves a robot one cell (4-connected) or waits."""
    clearance: float = 0.3
    """A point is free when it is at least this far (m) from every obstacle and wall (the
    robot's 0.2 m disc plus 0.1 m for tracking error)."""
    point_resolution: float = 0.1
    """Side (m) of the fine grid on which each cell's point is found: the free point of the
    cell nearest its centre (a cell with none is blocked). Robots drive from point to point;
    a move is open when the segment between the two points is free, so a narrow passage off
    the cell centres stays open."""
    repair_points: bool = True
    """Where no open move joins two parts of the map but the segment between two neighbouring
    cells' points, one in each, could be free, move those two points to the free pair nearest
    the centres that opens the move and closes no other: a passage narrower than a cell and off
    the centres (a gap beside an obstacle in a cross aisle) stays on the plan's map. Without it
    seed 3020's map fell in two halves and robots in the smaller one never moved."""
    window: int = 16
    """Steps each robot plans and reserves (WHCA*'s window)."""
    replan_margin: int = 6
    """The fleet replans when a robot has no more than this many steps of its plan left to
    execute (and at every goal change, and every ``replan_period_s``)."""
    rotate_s: float = 10.0
    """Priorities rotate at the first replan at least this long (s) after the last rotation (0:
    at every replan). Rotating at every replan (at most 2 s apart) handed the right of way back
    and forth: two robots meeting in a one-lane passage each planned to wait for the other in
    turn (seed 3108, 40-60 s). On 60 dynamic development episodes (N = 8, seeds 3000-3019,
    3100-3119, 3200-3219) 10 s gave 403 errands, 21 deadlock events and 8 robot-robot
    collisions against 382, 26 and 20 at every replan; 4 s and 20 s measured worse on seeds
    3100-3119 (docs/fleet.md)."""
    replan_min_s: float = 0.5
    """Shortest time (s) between two replans that no goal change asks for (a robot whose plan
    ends in waits reaches its end at once)."""
    replan_period_s: float = 2.0
    """Longest time (s) between two replans: a robot held up by a mover, or serving a
    collision penalty, is planned around from where it stands."""
    robustness: int = 1
    """Steps a robot keeps a cell reserved after leaving it in the plan (k-robust plans: in plan
    time a robot enters a cell no sooner than k + 1 steps after another left it)."""
    arrive_tolerance: float = 0.25
    """A robot has reached a cell on a straight run within this distance (m) of its centre,
    and steers on at the next one."""
    turn_tolerance: float = 0.12
    """A robot has reached a cell where its path turns within this distance (m) of its centre
    (tighter than ``arrive_tolerance``: cutting a corner would sweep the inner diagonal cell)."""
    leave_distance: float = 0.45
    """A robot has left a cell once its centre is this far (m) from the cell's centre (a
    robot's 0.4 m diameter plus 5 cm): only then may the robot planned there next enter it."""
    hold_radius: float = 0.05
    """A robot whose next cell is not yet free stops within this distance (m) of the centre of
    the last cell it may enter."""
    obstacle_range: float = 0.0
    """Lidar returns closer than this (m) that are not another robot mark cells blocked (the
    movers and pallet events the static plan does not know); 0 (the default) marks none: on the
    dynamic aisle warehouse (N = 8, 120 s, seeds 3000-3007) marking within 1.5 m completed 18
    errands against 50 without, its robots waiting on workers and forklifts that wait for them. The PID
    tracker's lidar blend keeps the robots off the movers, and a stuck robot backs off a
    yielding one (``yield_field``)."""
    obstacle_radius: float = 0.25
    """A lidar return blocks the cells whose centres lie within this distance (m) of it (under
    ``clearance``, so returns off the static obstacles block no free cell)."""
    obstacle_memory_s: float = 3.0
    """How long (s) a cell stays blocked after a lidar return last marked it."""
    detour_steps: int = 20
    """Where seen obstacles cut a cell off from the goal, the planner counts its distance as
    the static one plus this many steps (so a robot takes a detour shorter than that, else
    waits near the obstacle for it to move on)."""
    yield_field: float = 1.2
    """A stuck robot (``stuck_s``) near a mover that stands yielding to a robot plans to end its
    window farther than this (m) beyond the mover's bounding circle (its safety field, 1 m,
    plus the robot's 0.2 m), so that the mover drives on."""
    restarts: int = 3
    """Times a replan starts over when robots found no path, those robots planned first (then
    the rest in their order): prioritized planning with restarts, so a robot boxed in by the
    plans of robots ahead of it in priority gets its way out reserved before them."""
    block_yielding: bool = True
    """A stuck robot (``stuck_s``) plans round the movers that stand yielding to a robot (their
    footprint grown by ``yield_margin``): they stand until no robot is in their field, so a plan
    through one keeps the robot in front of it and the mover waiting for the robot. (Every
    robot planning round them measured worse: 90 errands/h against 172 at N = 8, seeds
    3004-3007, and 82 when only movers yielding for 3 s or more were planned round.)"""
    yield_margin: float = 0.22
    """How far (m) ``block_yielding`` grows a standing mover's footprint: the robot's 0.2 m
    radius and 2 cm, so a stuck robot boxed in by forklifts plans out through a gap that its
    body fits."""
    stuck_s: float = 4.0
    """A robot whose plans have kept it in place this long (s), or that has not moved
    ``stuck_distance`` in this long (its plan moves it, but a mover ahead stops it), away from
    its goal, plans around the seen obstacles whatever the detour and out of the way of a
    mover yielding to it (a forklift or worker yielding to it waits for it to leave)."""
    unknot_flips: int = 4
    """A robot commanded to stand and turn whose turn swapped direction this many times in the
    last second turns in place toward its next point, one way, until it faces it within
    0.3 rad or 4 s pass (0: off; :meth:`~bulletnav.fleet.coordinated.CoordinatedController.unknot`). Without it a robot
    boxed in between a rack and a mover can turn left and right on the spot for the rest of
    the episode (two such knots in 32 dev episodes, N = 8, seeds 3000-3031: with the turn's
    room checked, ``unknot_margin``, it undoes the one at seed 3008; at seed 3003 the turn
    would touch the robot beside it and is not made)."""
    unknot_margin: float = 0.03
    """The knot turn is made only while no lidar return lies within the robot's outline radius
    plus this (m) of its centre (a turn in place sweeps that circle; PyBullet reports contact
    from about 2 cm), so it does not swing the robot's corners into what stands beside it
    (unchecked, it did: four mover collisions at N = 8, seed 1000)."""
    stuck_distance: float = 0.25
    """How far (m) a robot must move to count as moving for ``stuck_s``."""
    hold_no_turn: float = 0.35
    """A robot that may enter no further cell does not turn in place (a command under 5 cm/s)
    while it is within this distance (m) of its hold point and its scan shows no room to turn
    (the knot turn's check, ``unknot_margin``): it stands still instead; 0: off. Without it a
    robot holding on the line between two cells, two forklifts standing for it 0.67 m away,
    turned toward the point of one cell and then the other, +1.2 and -1.2 rad/s on alternate
    steps, and touched a forklift every 6 s for the last minute of the episode (seed 6017,
    N = 8: 11 mover collisions, none with it). Standing still whenever boxed in near the hold
    point, not only instead of a turn, gave 10 deadlock events against 6 on development seeds
    3100-3119 (docs/fleet.md)."""
    drive_cone: float = 90.0
    """Near another robot (``cone_reach``), a robot whose next point lies more than this angle
    (degrees, at most 90) off its heading slows (to 0 at 90 degrees) and turns toward the
    point, where it has room to turn in place (0: off; :meth:`~bulletnav.fleet.coordinated.CoordinatedController.cone`).
    The tracker's lidar blends steer a robot boxed in by its neighbours toward the side with
    more room, and without the cone it drove on that way, off its reserved cells and into the
    robot beside it (seed 3113, static world, N = 8, 61-63 s: 0.15-0.47 m/s with its point
    95-153 degrees behind it). With it (and :func:`~bulletnav.fleet.spacetime.reserve_starts`),
    40 dynamic development episodes (N = 8, seeds 3100-3119 and 3200-3219) had 10 robot-robot
    and no mover collisions, against 36 and 8 without either (docs/fleet.md)."""
    cone_reach: float = 0.75
    """``drive_cone`` acts only while another robot's centre lies within this distance (m) and
    100 degrees of the robot's heading; elsewhere the blends may steer it round a mover (with
    the cone everywhere, 60 degrees, the same 20 dynamic episodes 3100-3119 gave 104 errands and
    20 deadlock events against 140 and 10)."""
    commit_cone: float = 60.0
    """At a replan, a robot that its plan lets into its next cell and whose heading lies within
    this angle (degrees) of that cell's point keeps the cell as its next move: the space-time
    search closes the other neighbours of its cell to it for the window (its goal too, where
    that is one of them: the robot reaches it a replan later), and plans without the
    commitment where that finds no path (0: off; :meth:`~bulletnav.fleet.coordinated.CoordinatedController.kept_moves`).
    Without it a replan, every 2 s or sooner, could hand a robot that had turned toward one cell
    another, and robots passing in a corridor turned back and forth: three robots for 20 s at
    seed 3104, dynamic, N = 8, 76-96 s. With it, on development seeds (N = 8, 120 s), 770
    errands and 44 deadlock events in 120 dynamic episodes (3000-3039, 3100-3119, 3200-3219,
    3300-3339) against 770 and 52, and 342 and 1 in 40 episodes without movers (3100-3119,
    3200-3219) against 326 and 6 (docs/design/fleet-deadlocks.md)."""
    controller: ControllerConfig = field(default_factory=lambda: ControllerConfig(safety_distance=0.35, side_margin=0.1))
    """The PID go-to-point controller that tracks the path (its lidar blends kept short: the
    plan keeps robots a cell apart)."""

    def __post_init__(self) -> None:
        if not (self.resolution > 0 and self.clearance >= 0 and self.replan_period_s > 0
                and 0 <= self.replan_min_s <= self.replan_period_s
                and 0 < self.turn_tolerance <= self.arrive_tolerance and self.hold_radius > 0
                and self.leave_distance > 0 and self.obstacle_range >= 0 and self.obstacle_radius >= 0
                and self.obstacle_memory_s >= 0 and self.hold_no_turn >= 0):
            raise ConfigError(f"coordinated planner needs resolution > 0, clearance >= 0, replan_period_s > 0, "
                              f"0 < turn_tolerance <= arrive_tolerance, hold_radius > 0, leave_distance > 0 and "
                              f"non-negative obstacle settings and hold_no_turn; got {self}")
        if not 0 <= self.drive_cone <= 90:
            raise ConfigError(f"coordinated planner needs drive_cone from 0 to 90 degrees, got {self.drive_cone!r}")
        if not 0 <= self.commit_cone <= 180:
            raise ConfigError(f"coordinated planner needs commit_cone from 0 to 180 degrees, got {self.commit_cone!r}")
        if not (0 <= self.replan_margin < self.window and self.robustness >= 0 and self.restarts >= 0):
            raise ConfigError(f"coordinated planner needs 0 <= replan_margin < window, robustness >= 0 and "
                              f"restarts >= 0; got {self}")

__all__ = ["CoordinatedConfig"]
