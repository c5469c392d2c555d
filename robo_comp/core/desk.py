"""What a desk of the core may use of it: small interfaces, so that no desk imports the core.

:class:`Access` answers "which session sent this, whose robot is that, may it be commanded" (the
session desk, :class:`robo_comp.core.sessiondesk.SessionDesk`, implements it); :class:`Outbox`
queues what goes out (replies to come, pushes, events), which leaves after the event log is
flushed; :class:`Transport` is what the session and robot desks need of the transport itself (the
credential the frame being handled came with, the connection limits, the core's identity). The
core (:class:`robo_comp.core.server.Core`) implements :class:`Outbox` and :class:`Transport`.
"""
from __future__ import annotations

from typing import Any, Protocol

from robo_comp.core.guard import ConnectionGuard, GuardLimits
from robo_comp.core.sessions import Session
from robo_comp.match.model import Match
from robo_comp.match.registry import Registry, RobotRecord
from robo_comp.protocol.curve import ServerKeys, ZapHandler
from robo_comp.teams.tokens import TokenBook


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


class Transport(Outbox, Protocol):
    """What the session and robot desks need of the core's transport."""

    match: Match
    tokens: TokenBook
    curve: ServerKeys | None
    #: Who the transport let in for the frame being handled (a CurveZMQ key's owner, or a PLAIN
    #: token's principal as "role:name"); None outside of a frame.
    key_owner: str | None
    zap: ZapHandler | None
    guard: ConnectionGuard | None
    pub_guard: ConnectionGuard | None
    limits: GuardLimits
    heartbeat: float
    core_id: str
    pub_port: int
    arena_payload: dict[str, Any]

    def forget_route(self, ident: bytes) -> None:
        """Connection ``ident``'s session is gone: nothing more is held for its route."""

    def to_host(self, r: RobotRecord, type_: str, body: dict[str, Any], req_id: int = 0) -> None:
        """A message to the host connection of robot ``r``."""
