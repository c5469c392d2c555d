"""Robot drivers: what turns a task's steps into motion.

:class:`ArenaDriver` drives a robot in the host's simulated arena (ground truth, collisions,
zones); what the robot *believes* about its pose comes from the positioning system and dead
reckoning (:class:`robo_comp.world.localization.Localization`), and that is what it reports.
Other drivers (the ER1's) plug in through the ``robo_comp_driver`` hook.
"""
from __future__ import annotations

import math
from typing import Any

from robo_comp.robots.steps import Capture, Move, Step, Turn, Wait
from robo_comp.world.arena import Arena
from robo_comp.world.localization import Localization

CAPTURE_SECONDS = 0.2
#: How far (cells) before what its front sensor sees a freely driving robot stops.
STOP_SHORT = 0.02


class PoseReadings:
    """``x``, ``y``, ``heading`` and ``cell()`` of a driver, from its ``pose`` (what it believes),
    and the end of a step, which every driver decides the same way."""

    step: Step | None
    _timer: float

    @property
    def pose(self) -> tuple[float, float, float]:
        """The believed ``(x, y, heading)``; each driver says where it takes it from."""
        raise NotImplementedError

    @property
    def moving(self) -> bool:
        """True while a step is in progress."""
        return self.step is not None

    def _start_timer(self, step: Step) -> None:
        """A picture or a wait lasts a fixed time (moves and turns end when the robot stops)."""
        if isinstance(step, Capture):
            self._timer = CAPTURE_SECONDS
        elif isinstance(step, Wait):
            self._timer = max(0.0, step.seconds)

    def _step_ended(self, moving: bool, dt: float) -> bool:
        """After ``dt`` seconds: True (and no step any more) when the current step is over. A
        move or turn is over when the robot no longer ``moving``; a picture or a wait when its
        time has run out."""
        if isinstance(self.step, (Move, Turn)):
            if moving:
                return False
        else:
            self._timer -= dt
            if self._timer > 0:
                return False
        self.step = None
        return True

    @property
    def x(self) -> float:
        """Believed x."""
        return self.pose[0]

    @property
    def y(self) -> float:
        """Believed y."""
        return self.pose[1]

    @property
    def heading(self) -> float:
        """Believed heading in degrees (0 = +x, 90 = +y)."""
        return self.pose[2]

    def cell(self) -> tuple[int, int]:
        """The cell the robot believes it is in."""
        x, y, _ = self.pose
        return int(round(x)), int(round(y))


class ArenaDriver(PoseReadings):
    """One robot of a simulated :class:`Arena`, commanded one step at a time."""

    def __init__(self, arena: Arena, tag: str, localization: Localization) -> None:
        self.arena = arena
        self.tag = tag
        self.loc = localization
        self.step: Step | None = None
        self.bump: dict[str, Any] | None = None
        self._timer = 0.0

    # what the robot believes (estimate) ------------------------------------
    @property
    def pose(self) -> tuple[float, float, float]:
        """Estimated (x, y, heading): what the robot and its team see."""
        return self.loc.estimate(self.tag)

    def truth(self) -> tuple[float, float, float]:
        """The true pose (the arena's; for the camera and the referee, not for the team)."""
        p = self.arena.pose(self.tag)
        return p.x, p.y, p.heading

    # commands ----------------------------------------------------------------
    def begin(self, step: Step) -> None:
        """Start ``step``: a move turns by the bearing of the cell from where the robot believes it
        is and drives the believed distance (a grid4 robot rounds them to 90° and whole cells)."""
        self.step = step
        self.bump = None
        if isinstance(step, Move):
            x, y, h = self.pose
            dx, dy = step.x - x, step.y - y
            turn = (math.degrees(math.atan2(dy, dx)) - h + 180.0) % 360.0 - 180.0
            dist = math.hypot(dx, dy)
            if self.arena.drive != "grid4":  # a grid4 robot drives whole cells; a free one stops short
                # of what its front sensor sees rather than touch it (a believed distance a little long)
                dist = min(dist, max(0.0, self.arena.clearance(self.tag, self.arena.pose(self.tag).heading + turn)
                                     - STOP_SHORT))
            self.arena.command(self.tag, "turn", turn)
            self.arena.command(self.tag, "forward", dist, append=True)
        elif isinstance(step, Turn):
            self.arena.command(self.tag, "turn", step.degrees)
        else:
            self._start_timer(step)

    def halt(self) -> None:
        """Stop at once (a movement stopped half-way leaves the robot less sure where it is:
        :meth:`Localization.interrupted`)."""
        if self.arena.is_moving(self.tag):
            self.loc.interrupted(self.tag)
        self.arena.command(self.tag, "halt")
        self.step = None

    def sees_crossing(self, x: int, y: int) -> bool:
        """Whether another robot (of any team) is in the neighbouring cell ``(x, y)`` (where the robot
        believes it is going) or driving into it: the cell it would really drive into."""
        bx, by = self.cell()
        p = self.arena.pose(self.tag)
        return self.arena.driving_into(self.tag, math.floor(p.x + 0.5) + x - bx, math.floor(p.y + 0.5) + y - by)

    @property
    def grid_exact(self) -> bool:
        """Whether a move ends exactly in its cell (a grid4 robot settles on the grid); a freely
        driving one may end a little long (robots.traffic keeps teammates out of the cell beyond)."""
        return self.arena.drive == "grid4"

    def sees_blocked(self, x: int, y: int) -> bool:
        """Whether the robot's range sensors see the neighbouring cell ``(x, y)`` (where it believes
        it is going) blocked by debris, something the map does not show: the cell it would really
        drive into, from where it really is."""
        bx, by = self.cell()
        p = self.arena.pose(self.tag)
        cx, cy = math.floor(p.x + 0.5) + x - bx, math.floor(p.y + 0.5) + y - by
        debris = self.arena.debris
        return 0 <= cy < debris.shape[0] and 0 <= cx < debris.shape[1] and bool(debris[cy, cx])

    def update(self, dt: float) -> bool:
        """After the arena stepped: True when the current step finished (or a bump ended it)."""
        if self.step is None:
            return False
        if self.bump is not None:  # stopped half-way by a bump
            self.loc.interrupted(self.tag)
        ended = self._step_ended(self.bump is None and self.arena.is_moving(self.tag), dt)
        if ended and self.bump is None:
            self.loc.settled(self.tag)
        return ended
