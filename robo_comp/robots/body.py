"""Minimal grid kinematics for simulated robots: turn to face a neighbour cell, then drive.

Coordinates are cells, x to the right and y down (rows); headings are degrees clockwise
from east (0 = east, 90 = south). Moves go between neighbouring free cells, so a robot
halted half-way always stands on the segment between two free cells.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from robo_comp.robots.steps import Capture, Move, Step, Turn, Wait

CAPTURE_SECONDS = 0.2


def _angle_diff(a: float, b: float) -> float:
    """Signed smallest rotation from heading ``a`` to ``b`` in degrees (-180, 180]."""
    d = (b - a) % 360.0
    return d - 360.0 if d > 180.0 else d


@dataclass(slots=True)
class Body:
    """Pose and the step in progress of one simulated robot."""

    x: float
    y: float
    heading: float = 0.0
    speed: float = 2.0  # cells per second
    turn_rate: float = 180.0  # degrees per second
    step: Step | None = None
    _goal_heading: float | None = None
    _timer: float = 0.0

    @property
    def moving(self) -> bool:
        """True while a step is in progress."""
        return self.step is not None

    def cell(self) -> tuple[int, int]:
        """The cell the robot is in (nearest cell centre)."""
        return int(round(self.x)), int(round(self.y))

    def begin(self, step: Step) -> None:
        """Start ``step`` from the current pose."""
        self.step = step
        if isinstance(step, Move):
            dx, dy = step.x - self.x, step.y - self.y
            self._goal_heading = math.degrees(math.atan2(dy, dx)) % 360.0 if (dx or dy) else None
        elif isinstance(step, Turn):
            self._goal_heading = (self.heading + step.degrees) % 360.0
            self._timer = abs(step.degrees) / self.turn_rate
        elif isinstance(step, Capture):
            self._timer = CAPTURE_SECONDS
        elif isinstance(step, Wait):
            self._timer = max(0.0, step.seconds)

    def halt(self) -> None:
        """Stop at once, wherever the robot is."""
        self.step = None
        self._goal_heading = None

    def _turn(self, dt: float) -> float:
        """Turn towards the goal heading; return the unused part of ``dt``."""
        if self._goal_heading is None:
            return dt
        diff = _angle_diff(self.heading, self._goal_heading)
        need = abs(diff) / self.turn_rate
        if need <= dt:
            self.heading = self._goal_heading
            self._goal_heading = None
            return dt - need
        self.heading = (self.heading + math.copysign(self.turn_rate * dt, diff)) % 360.0
        return 0.0

    def update(self, dt: float) -> bool:
        """Advance the current step by ``dt`` seconds; True when it finished in this update."""
        step = self.step
        if step is None:
            return False
        if isinstance(step, Move):
            dt = self._turn(dt)
            if self._goal_heading is not None or dt <= 0:
                return False
            dx, dy = step.x - self.x, step.y - self.y
            dist = math.hypot(dx, dy)
            travel = self.speed * dt
            if travel >= dist:
                self.x, self.y = float(step.x), float(step.y)
                self.step = None
                return True
            self.x += dx / dist * travel
            self.y += dy / dist * travel
            return False
        if isinstance(step, Turn):
            self._turn(dt)
            if self._goal_heading is None:
                self.step = None
                return True
            return False
        self._timer -= dt
        if self._timer <= 0:
            self.step = None
            return True
        return False
