"""A robot's status, moved by one owner: every transition of every robot goes through here.

::

    connected --lost--> lost --returned--> connected
    connected|lost --left--> left --registered--> connected
    any --disqualified--> disqualified            (for the rest of the match)

Nothing else in robo_comp writes a robot's ``status`` (``tests/test_architecture.py`` checks
it). A move announces itself (``robot.lost``, ``robot.returned``, ``robot.left``) and feeds
the scoring rules where they count it (a robot lost costs its team the ``robot_lost`` penalty).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from robo_comp.match.output import MatchOutput
from robo_comp.match.registry import RobotRecord
from robo_comp.protocol.states import RobotStatus

#: status -> the statuses it may move to.
TRANSITIONS: dict[RobotStatus, frozenset[RobotStatus]] = {
    RobotStatus.CONNECTED: frozenset({RobotStatus.LOST, RobotStatus.LEFT, RobotStatus.DISQUALIFIED}),
    RobotStatus.LOST: frozenset({RobotStatus.CONNECTED, RobotStatus.LEFT, RobotStatus.DISQUALIFIED}),
    RobotStatus.LEFT: frozenset({RobotStatus.CONNECTED, RobotStatus.DISQUALIFIED}),
    RobotStatus.DISQUALIFIED: frozenset(),
}


class Lifecycle:
    """The one writer of robots' statuses (see the module docstring).

    ``feed(event)`` gives a scoring-relevant event to the rules (the match's scoring);
    ``is_disqualified(tag)`` tells a robot the referee took out of the match."""

    def __init__(self, out: MatchOutput, feed: Callable[[dict[str, Any]], None],
                 is_disqualified: Callable[[int], bool]) -> None:
        self.out = out
        self.feed = feed
        self.is_disqualified = is_disqualified

    @staticmethod
    def _move(r: RobotRecord, to: RobotStatus) -> bool:
        if r.status is to:
            return False
        if to not in TRANSITIONS[r.status]:
            return False
        r.status = to
        if to is not RobotStatus.CONNECTED:
            r.moving = False
        return True

    def lost(self, r: RobotRecord, why: str) -> bool:
        """A connected robot's host went silent (or let it go): it is lost until its host speaks
        again. Returns whether it was connected."""
        if r.status is not RobotStatus.CONNECTED or not self._move(r, RobotStatus.LOST):
            return False
        self.out.emit("robot.lost", r.team, {"tag": r.tag, "x": r.x, "y": r.y, "message": why})
        self.feed({"kind": "robot.lost", "team": r.team, "tag": r.tag})
        return True

    def returned(self, r: RobotRecord) -> None:
        """A lost robot's host spoke again: connected (a disqualified robot stays out)."""
        if r.status is not RobotStatus.CONNECTED and not self.is_disqualified(r.tag):
            if self._move(r, RobotStatus.CONNECTED):
                self.out.emit("robot.returned", r.team, {"tag": r.tag, "x": r.x, "y": r.y})

    def registered(self, r: RobotRecord) -> RobotStatus:
        """A robot registered (new, or again with its robot id): connected, unless the referee
        disqualified it. Returns the status it had (the ``robot.returned`` event says it)."""
        was = r.status
        if self.is_disqualified(r.tag):
            self._move(r, RobotStatus.DISQUALIFIED)
        else:
            self._move(r, RobotStatus.CONNECTED)
        return was

    def left(self, r: RobotRecord) -> None:
        """Its host took it out of the arena; it comes back by registering again."""
        if self._move(r, RobotStatus.LEFT):
            self.out.emit("robot.left", r.team, {"tag": r.tag, "x": r.x, "y": r.y})

    def disqualified(self, r: RobotRecord) -> None:
        """The referee took it out of the match (for good)."""
        self._move(r, RobotStatus.DISQUALIFIED)

    @staticmethod
    def restore(r: RobotRecord, status: RobotStatus) -> None:
        """Set the status a logged event recorded (recovery: the log is the truth, no event)."""
        r.status = status
        if status is not RobotStatus.CONNECTED:
            r.moving = False


__all__ = ["Lifecycle", "TRANSITIONS"]
