"""Ownership policy: who may see and command which robot."""
from __future__ import annotations

from robo_comp.errors import ForbiddenError, NotYoursError
from robo_comp.teams.tokens import Principal


def may_see(who: Principal, robot_team: str) -> bool:
    """True when ``who`` may see a robot of ``robot_team`` (its own team, or the referee)."""
    return who.role == "referee" or who.team == robot_team


def check_owner(who: Principal, tag: int, robot_team: str) -> None:
    """Raise :class:`NotYoursError` unless ``who`` owns the robot or is the referee.

    The message does not say whose robot it is: a team learns nothing about other teams.
    """
    if not may_see(who, robot_team):
        raise NotYoursError(
            f"robot {tag} is not one of team {who.name}'s robots; a team may only see and command its own robots")


def check_referee(who: Principal, action: str) -> None:
    """Raise :class:`ForbiddenError` unless ``who`` is the referee."""
    if who.role != "referee":
        raise ForbiddenError(f"only the referee may {action}")
