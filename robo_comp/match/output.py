"""What the match says to the world around it: events, and directives to the robots' hosts.

The match (:class:`~robo_comp.match.model.Match`) has no sockets. Whoever drives it gives it a
:class:`MatchOutput`: the core (events into its log, its PUB socket and its watchers; directives
to a robot's host connection) or the engine (events into the match's log in simulated time;
directives to the robots it runs itself). The same commands so cause the same events and the
same directives, live and on the engine.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from robo_comp.match.registry import RobotRecord


class MatchOutput(Protocol):
    """Where the match's events and directives go."""

    def emit(self, topic: str, team: str | None, data: dict[str, Any], *, log_it: bool = True) -> None:
        """An event of ``topic`` about ``team`` (None: the match's own; ``"*"``: for everyone); who
        may see what of it is the table's (:mod:`robo_comp.protocol.topics`). ``log_it`` False: not
        recorded (the live position feed)."""

    def to_host(self, r: RobotRecord, type_: str, body: dict[str, Any]) -> None:
        """A directive to the host that runs robot ``r``: ``task.start``, ``task.interrupt``,
        ``stop`` (no answer awaited), ``radio`` (a teammate's message)."""

    def to_hosts(self, type_: str, body: dict[str, Any]) -> None:
        """A directive to every robot host: ``hold`` (the match paused or finished, or resumed)."""

    def finished(self) -> None:
        """The match has just finished (once): the driver writes the results where it keeps them."""

    def discovered(self, r: RobotRecord, find: dict[str, Any]) -> None:
        """A find was reported (not a duplicate): the map service marks it for the team."""


__all__ = ["MatchOutput"]
