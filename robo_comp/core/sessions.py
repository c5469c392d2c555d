"""Sessions: a connection that said hello (or registered robots) and proved it on every message."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from robo_comp import protocol as P
from robo_comp.teams.tokens import Principal


@dataclass(slots=True)
class Session:
    """A connection that said hello (console, wall, script or robot host)."""

    ident: bytes
    who: Principal
    client: str
    last_seen: float
    #: The secret every message of this session carries (``"s"``); issued at hello/register.
    secret: str = field(default_factory=P.new_session_secret)
    #: Under CurveZMQ: the owner of the key the session was opened with (every frame must match).
    key: str | None = None
    watching: bool = False
    #: The random id the client keeps across its reconnects (hello's ``instance``): a new hello of
    #: the same principal with the same instance ends this session (see ``Core._on_hello``).
    instance: str | None = None
    tags: set[int] = field(default_factory=set)
    #: The message types this session's principal may send (``protocol.ROLE_MESSAGES``).
    allowed: frozenset[str] = frozenset()
    #: When the session was opened (wall-clock seconds, shown to the referee).
    opened: float = field(default_factory=time.time)

    def __post_init__(self) -> None:
        if not self.allowed:
            self.allowed = P.ROLE_MESSAGES.get(self.who.role, frozenset())
