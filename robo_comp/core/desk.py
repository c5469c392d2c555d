"""What a desk of the core (competition, maps, uploads) may use of it: two small interfaces.

The core (:class:`robo_comp.core.server.Core`) implements both; a desk receives them in its
constructor and never imports the core. :class:`Access` answers "which session sent this,
whose robot is that, may it be commanded"; :class:`Outbox` queues what goes out (replies to
come, pushes, events), which leaves after the event log is flushed.
"""
from __future__ import annotations

from typing import Any, Protocol

from robo_comp.core.sessions import Session
from robo_comp.match.model import Match
from robo_comp.match.registry import Registry, RobotRecord


class Access(Protocol):
    """Sessions, robots and ownership, as the desks see them."""

    registry: Registry
    #: The match the core drives (robots, tasks, the contest): what a command may do is its check.
    match: Match

    def session(self, ident: bytes) -> Session:
        """The session of connection ``ident`` (``E_AUTH`` if it has none)."""

    def has_session(self, ident: bytes) -> bool:
        """Whether connection ``ident`` has a session."""

    def robot_for(self, ident: bytes, tag: int) -> RobotRecord:
        """Robot ``tag`` as commanded by session ``ident``: ``E_NOT_YOURS`` unless it may."""

    def hosted(self, ident: bytes, tag: int) -> RobotRecord:
        """Robot ``tag`` as reported by its own host connection ``ident`` (``E_NOT_YOURS`` otherwise)."""

    def host_sessions(self) -> list[bytes]:
        """The connections that host robots."""



class Outbox(Protocol):
    """What goes out of the core, after the turn's log flush."""

    def send(self, ident: bytes, frame: bytes, urgent: bool = False) -> None:
        """Queue ``frame`` for connection ``ident`` (``urgent``: leaves even while the log cannot be written)."""

    def emit(self, topic: str, team: str | None, data: dict[str, Any], *, log_it: bool = True) -> None:
        """Log an event, publish its public view and push it to the watchers who may see it."""

    def new_request_id(self) -> int:
        """A fresh id for a request the core sends to a robot host."""
