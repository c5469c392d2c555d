"""A client's session with a core, as plain state: the one session every client keeps.

The public client (:class:`robo_comp.client.Client`, blocking), the consoles' and the web
gateway's link (:class:`robo_comp.link.CoreLink`, asyncio) and the robot host
(:class:`robo_comp.robots.host.RobotHost`, its own poll loop) each do their I/O their own way, but
keep their session with this one object, so that they say hello, carry the secret, beat and
notice a lost or restarted core the same way:

* :meth:`ClientSession.hello` opens a session on a new connection (a new connection has no secret
  until the core's reply gives one; the ``instance`` is kept across reconnects, so the core ends
  the client's old session when it says hello again);
* :meth:`ClientSession.opened` takes the hello reply (the secret, the heartbeat, the core's id);
* :meth:`ClientSession.frame` makes every later message, carrying the secret;
* :meth:`ClientSession.beat_due` and :meth:`ClientSession.silent` time the heartbeats both ways;
* :meth:`ClientSession.heard` reads what came in and says when the session is gone: the core
  forgot it (``E_AUTH``: it restarted) or another core process answers (its heartbeats carry
  another id).

No sockets, no clock of its own: the caller passes ``now`` (monotonic seconds).
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

from robo_comp.protocol.wire import new_instance_id, request

#: Heartbeats of silence after which the core counts as lost.
SILENT_BEATS = 3


class Gone(enum.Enum):
    """Why a session is over (what :meth:`ClientSession.heard` may say)."""

    FORGOTTEN = "the core does not know this connection's session (it restarted)"
    RESTARTED = "another core process answers (the core restarted)"


@dataclass
class ClientSession:
    """One client's session (see the module docstring): ``token`` proves who it is, ``client``
    names the program (``robots``, ``console``, ``wall``, ...)."""

    token: str
    client: str
    #: Kept across reconnects: the core ends this client's old session when it says hello again.
    instance: str = field(default_factory=new_instance_id)
    #: The secret of the current connection's session (None until the hello reply gives one).
    secret: str | None = None
    #: The hello reply: role, team, heartbeat, the match, the arena, ...
    info: dict[str, Any] = field(default_factory=dict)
    #: The id of the core process the session is with (its heartbeats carry it).
    core_id: str | None = None
    next_id: int = 1
    last_tx: float = 0.0
    last_rx: float = 0.0

    @property
    def heartbeat(self) -> float:
        """The core's heartbeat interval in seconds (1 before the first hello)."""
        return float(self.info.get("heartbeat", 1.0))

    def request_id(self) -> int:
        """A fresh request id."""
        i = self.next_id
        self.next_id += 1
        return i

    def hello(self, now: float = 0.0, **extra: Any) -> tuple[int, bytes]:
        """A new connection's first message (its request id and frame): the session of the
        connection before it is over, so no secret goes with it."""
        self.secret = None
        rid = self.request_id()
        self.last_tx = self.last_rx = now
        return rid, request("hello", rid, {"token": self.token, "client": self.client, "instance": self.instance,
                                           **extra})

    def opened(self, body: dict[str, Any]) -> bool:
        """Take the core's hello reply; True when it comes from another core process than the
        session before (a restarted core)."""
        self.info = dict(body)
        self.secret = body.get("session")
        restarted = self.core_id is not None and body.get("core_id") not in (None, self.core_id)
        self.core_id = body.get("core_id") or self.core_id
        return restarted

    def frame(self, type_: str, body: dict[str, Any], now: float = 0.0, rid: int | None = None) -> tuple[int, bytes]:
        """A message of this session (its request id and frame; ``rid`` 0 for one that wants no
        answer)."""
        rid = self.request_id() if rid is None else rid
        self.last_tx = now
        return rid, request(type_, rid, body, self.secret)

    def beat_due(self, now: float) -> bool:
        """Whether a heartbeat is due (nothing was sent for a heartbeat interval)."""
        return now - self.last_tx >= self.heartbeat

    def silent(self, now: float, floor: float = 0.0, beats: float = SILENT_BEATS) -> bool:
        """Whether the core has been silent for ``beats`` heartbeats (and ``floor`` seconds)."""
        return now - self.last_rx > max(beats * self.heartbeat, floor)

    def heard(self, msg: dict[str, Any], now: float) -> Gone | None:
        """Something came from the core: None, or why the session is over (a reply ``E_AUTH``,
        a heartbeat of another core process)."""
        self.last_rx = now
        kind = msg.get("type")
        if kind == "reply":
            err = msg.get("error")
            if not msg.get("ok") and isinstance(err, dict) and err.get("code") == "E_AUTH" and self.secret:
                return Gone.FORGOTTEN
        elif kind == "heartbeat":
            body = msg.get("body")
            cid = body.get("core_id") if isinstance(body, dict) else None
            if cid is not None and self.core_id is not None and cid != self.core_id:
                return Gone.RESTARTED
        return None

    def bye(self) -> bytes:
        """The message that ends the session (best effort: no answer is awaited)."""
        return request("bye", self.request_id(), {}, self.secret)


__all__ = ["ClientSession", "Gone", "SILENT_BEATS"]
