"""Teamwork's requests at the core: a team's reallocation setting, and the obstacles robots report.

What they do to the match is :class:`robo_comp.match.teamwork.TeamWork`'s (the engine has it
too); this desk proves who asks: a team sets its own reallocation (the referee names the team),
and only a robot's own host reports an obstacle for it.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Access, Outbox
from robo_comp.errors import FieldError, NotYoursError


class TeamDesk:
    """The ``teamwork`` and ``obstacle`` request handlers."""

    def __init__(self, access: Access, out: Outbox) -> None:
        self.access = access
        self.out = out

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this module adds to the core."""
        return {"teamwork": self._on_teamwork, "obstacle": self._on_obstacle}

    def _on_teamwork(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        team = msg.body.get("team")
        if who.role == "referee":
            if team is None:
                raise FieldError("the referee names the team: 'team'")
        elif team not in (None, who.team):
            raise NotYoursError(f"team {who.team} sets its own teamwork, not team {team}'s")
        else:
            team = who.team
        match = self.access.match
        name = match.contest.team_arg(team)
        on = msg.body.get("reallocate")
        if on is None:
            return {"team": name, "reallocate": match.teamwork.reallocate.get(name, False), "moved": []}
        return match.set_reallocate(name, on, who.name)

    def _on_obstacle(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        r = self.access.hosted(ident, b["tag"])
        return {"new": self.access.match.obstacle(r, b["x"], b["y"])}
