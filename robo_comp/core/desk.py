"""What a desk of the core (competition, maps, uploads) may use of it: two small interfaces.

The core (:class:`robo_comp.core.server.Core`) implements both; a desk receives them in its
constructor and never imports the core. :class:`Access` answers "which session sent this,
whose robot is that, may it be commanded"; :class:`Outbox` queues what goes out (replies to
come, pushes, events), which leaves after the event log is flushed.
"""
from __future__ import annotations

from typing import Any, Protocol

from robo_comp.match.registry import Registry, RobotRecord
from robo_comp.core.sessions import Session


class Access(Protocol):
    """Sessions, robots and ownership, as the desks see them."""

    registry: Registry

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

    def give_task(self, r: RobotRecord, name: str, args: list[Any], queue: bool, by: str) -> dict[str, Any]:
        """Give robot ``r`` a task (ownership is the caller's check); the ``give`` reply's body."""

    def halt_and_remove(self, tag: int, reason: str) -> None:
        """Halt robot ``tag``, cancel its tasks and take it out of the match."""

    def judged_pose(self, r: RobotRecord, claim: dict[str, Any], what: str) -> tuple[float, float, float]:
        """The pose at which the match judges ``what`` (a picture, a bump) of robot ``r``: the host's
        ``claim`` only where the core's tracked pose bears it out, else the tracked pose."""


class Outbox(Protocol):
    """What goes out of the core, after the turn's log flush."""

    def send(self, ident: bytes, frame: bytes, urgent: bool = False) -> None:
        """Queue ``frame`` for connection ``ident`` (``urgent``: leaves even while the log cannot be written)."""

    def emit(self, topic: str, team: str | None, data: dict[str, Any], *, public: bool = True,
             log_it: bool = True) -> None:
        """Log an event, publish its public view and push it to the watchers who may see it."""

    def new_request_id(self) -> int:
        """A fresh id for a request the core sends to a robot host."""
