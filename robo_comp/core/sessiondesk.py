"""Sessions at the core: who is connected, as whom, and what each may reach.

:class:`SessionDesk` opens and ends sessions (``hello``, ``bye``, ``heartbeat``, ``watch``), keeps
who watches what, checks that the token of a ``hello`` is the credential the connection proved at
the transport, forgets silent consoles and marks a silent host's robots lost. It is the core's
:class:`~robo_comp.core.desk.Access` for the other desks: the session of a connection, a robot as
its team commands it or as its host reports it. Refusals of strangers are counted here and told
to the referee in bulk once a beat.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Transport
from robo_comp.core.sessions import Session
from robo_comp.errors import AuthError, FieldError, NotYoursError, RateLimitError, RoboCompError
from robo_comp.match.registry import RobotRecord
from robo_comp.protocol.states import RobotStatus
from robo_comp.teams.policy import check_owner
from robo_comp.teams.tokens import ORGANISER, REFEREE, Principal

log = logging.getLogger("robo_comp.core")

#: How long a console session may stay silent before it is forgotten (watchers heartbeat).
SESSION_IDLE = 300.0


class SessionDesk:
    """Sessions, watchers and the proofs a ``hello`` needs (see the module docstring).

    ``sessions`` and ``watchers`` are the core's own maps (its loop reads them on every message)."""

    def __init__(self, core: Transport, sessions: dict[bytes, Session], watchers: dict[str | None, set[bytes]]) -> None:
        self.core = core
        self.match = core.match
        self.registry = core.match.registry
        self.sessions = sessions
        #: Who watches what: team name -> routing ids, and the referee's under None.
        self.watchers = watchers
        # Refusals of connections without a session (and of notifications), counted per (type, code,
        # sender) and logged once a beat: a flood of bad hellos must not flood the log.
        self.refused: dict[tuple[str, str, Principal | None], list[Any]] = {}

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this desk adds to the core."""
        return {"hello": self._on_hello, "heartbeat": self._on_heartbeat, "bye": self._on_bye,
                "watch": self._on_watch}

    # ------------------------------------------------------------------ Access
    def session(self, ident: bytes) -> Session:
        """The session of connection ``ident`` (``E_AUTH`` if it has none)."""
        s = self.sessions.get(ident)
        if s is None:
            raise AuthError("say 'hello' with your team token first (the client does this for you)")
        return s

    def has_session(self, ident: bytes) -> bool:
        """Whether connection ``ident`` has a session."""
        return ident in self.sessions

    def robot_for(self, ident: bytes, tag: int) -> RobotRecord:
        """The robot ``tag`` as commanded by session ``ident`` (ownership checked)."""
        s = self.session(ident)
        r = self.registry.robots.get(tag)
        if r is None:
            if s.who.role == "referee":
                self.registry.get(tag)
            raise NotYoursError(
                f"robot {tag} is not one of team {s.who.name}'s robots; a team may only see and command its own robots")
        check_owner(s.who, tag, r.team)
        return r

    def known(self, ident: bytes) -> None:
        """``E_AUTH`` for a connection the core does not know (it restarted since)."""
        if ident not in self.sessions:
            raise AuthError("this connection is not known to the core (did the core restart?); "
                            "say hello and register your robots again")

    def hosted(self, ident: bytes, tag: int) -> RobotRecord:
        """The robot ``tag`` as reported by its host connection ``ident``."""
        self.known(ident)
        r = self.registry.robots.get(tag)
        if r is None or r.session != ident:
            raise NotYoursError(f"robot {tag} is not hosted by this connection; register it first")
        if r.status is not RobotStatus.CONNECTED:
            self.match.heard(r)
        return r

    def host_sessions(self) -> list[bytes]:
        """Routing ids of the connections that host robots."""
        return [ident for ident, s in self.sessions.items() if s.tags]

    # ------------------------------------------------------------------ proofs and limits
    def check_key(self, who: Principal) -> None:
        """With CurveZMQ a team's key lets in that team only, the organiser's key the robot hosts
        (and the referee's key any role); with PLAIN, the token of the hello is the one the
        connection proved (the same principal)."""
        owner = self.core.key_owner
        if self.core.curve is not None:
            if who.role == "host":
                if owner not in (REFEREE, ORGANISER):
                    raise AuthError(f"this connection uses {owner}'s key; a robot host's token needs the "
                                    f"organiser's key ({ORGANISER}.key_secret)")
            elif owner not in (REFEREE, who.name):
                raise AuthError(f"this connection uses team {owner}'s key; {who.name}'s token needs {who.name}'s key")
        elif self.core.zap is None or self.core.zap.principals.get(owner or "") != who:
            raise AuthError(f"this connection proved {owner or 'nobody'} when it connected; say hello with "
                            "the same token the connection presented (the client does this for you)")

    def admit(self, principal: Any) -> str | None:
        """Asked by the ZAP handler about every principal that proved itself: None lets it in, a
        sentence refuses the handshake (the core is full but for the referee and hosts, or the
        principal holds its share of the sessions)."""
        guard = self.core.guard
        assert guard is not None
        why = guard.admit(principal)
        if why is None and not isinstance(principal, str):
            why = self.sessions_full(principal)
        return why

    def sessions_full(self, who: Principal) -> str | None:
        """A sentence when ``who`` holds its share of sessions (a quarter of the core's connections;
        the referee and hosts have no share), else None."""
        if who.role in ("referee", "host"):
            return None
        total = self.core.limits.total
        share = max(16, total // 4)
        held = sum(1 for s in self.sessions.values() if s.who == who)
        if held >= share:
            return (f"{who.name} holds {held} sessions, its share of this core's {total} connections; "
                    "close some (or say bye) before opening more")
        return None

    def open_host_session(self, ident: bytes, who: Principal) -> Session:
        """The session of a robot host that registers on connection ``ident`` with no ``hello``."""
        sess = self.sessions.get(ident)
        if sess is None:
            full = self.sessions_full(who)
            if full is not None:
                raise RateLimitError(full)
            sess = Session(ident, who, "robots", time.monotonic(), key=self.core.key_owner)
            self.sessions[ident] = sess
        return sess

    # ------------------------------------------------------------------ sessions
    def set_watch(self, s: Session, on: bool) -> None:
        """Session ``s`` watches (gets pushed events) or stops."""
        s.watching = on
        group = self.watchers.setdefault(s.who.team, set())
        if on:
            group.add(s.ident)
        else:
            group.discard(s.ident)

    def forget(self, ident: bytes) -> Session | None:
        """Forget the session of ``ident`` (returns it, if there was one)."""
        s = self.sessions.pop(ident, None)
        if s is not None:
            self.set_watch(s, False)
        self.core.forget_route(ident)
        return s

    def _on_hello(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        core = self.core
        who = core.tokens.lookup(msg.body["token"])
        self.check_key(who)
        instance = msg.body.get("instance")
        if instance is not None and not P.INSTANCE_MIN <= len(instance) <= P.INSTANCE_MAX:
            raise FieldError(f"hello's 'instance' must be a random id of {P.INSTANCE_MIN} to {P.INSTANCE_MAX} "
                             "characters (robo_comp.protocol.new_instance_id), kept across reconnects")
        full = self.sessions_full(who) if ident not in self.sessions else None
        if full is not None:
            raise RateLimitError(full)
        old = self.forget(ident)  # only a proved hello gets here with a session (see Core._prove)
        sess = Session(ident, who, str(msg.body.get("client", "client"))[:64], time.monotonic(),
                       key=core.key_owner, instance=instance)
        if instance is not None:  # the same client again (a new connection): its old session ends now
            for other in [o for o in self.sessions.values() if o.instance == instance and o.who == who]:
                self.end_session(other, "its client said hello again on a new connection")
        self.sessions[ident] = sess
        if old is not None and old.who == who:
            sess.tags = old.tags
            self.set_watch(sess, old.watching)
        elif old is not None:  # the same program, now someone else: its robots are not the new one's
            self._release_robots(old, "its host's connection now speaks for someone else")
        arena = core.arena_payload
        return {"session": sess.secret, "role": who.role, "team": who.team, "protocol": P.PROTOCOL_VERSION,
                "core_id": core.core_id, "match": self.match.contest.state(),
                "pub_port": core.pub_port, "heartbeat": core.heartbeat, "teams": core.tokens.teams,
                "arena": {"name": self.match.scenario.name, "width": arena["width"], "height": arena["height"]}}

    def _release_robots(self, s: Session, why: str) -> None:
        """Detach the robots of session ``s`` from its connection (they are lost until they register again)."""
        for tag in s.tags:
            r = self.registry.robots[tag]
            if r.session == s.ident:
                self.match.lost(r, why)
                r.session = None
        s.tags = set()

    def _on_heartbeat(self, ident: bytes, msg: P.Message) -> None:
        s = self.sessions.get(ident)
        if s is not None:
            for tag in s.tags:
                r = self.registry.robots[tag]
                if r.session == ident and r.status is RobotStatus.LOST:
                    self.match.heard(r)
        return None

    def _on_bye(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.sessions.get(ident)
        if s is not None:
            self.end_session(s, "its host said bye without leaving")
        return {}

    def end_session(self, s: Session, why: str) -> None:
        """Forget session ``s`` (a bye, or its client's new hello); its robots are lost until they
        register again."""
        self.forget(s.ident)
        for tag in s.tags:
            r = self.registry.robots[tag]
            if r.session == s.ident:
                self.match.lost(r, why)

    def _on_watch(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.session(ident)
        self.set_watch(s, bool(msg.body.get("on", True)))
        return {"watching": s.watching}

    def beat(self, now: float) -> None:
        """Once a heartbeat: heartbeats to hosts and watchers, a silent host's robots lost, a silent
        watcher unwatched, a long-silent console forgotten; and the refusals since the last beat."""
        core = self.core
        hb = P.request("heartbeat", 0, {"t": time.time(), "core_id": core.core_id})
        limit = 3 * core.heartbeat
        for ident, s in list(self.sessions.items()):
            silent = now - s.last_seen
            if s.tags:
                core.send(ident, hb, True)
                if silent > limit:
                    for tag in s.tags:
                        r = self.registry.robots[tag]
                        if r.session == ident:
                            self.match.lost(r, f"no message from its host for {silent:.1f} s")
            elif s.watching:
                core.send(ident, hb, True)
                if silent > max(SESSION_IDLE / 10, limit * 10):
                    self.set_watch(s, False)
            elif silent > SESSION_IDLE:
                self.forget(ident)
        self.tell_refused()

    # ------------------------------------------------------------------ refusals, told in bulk
    def count_refused(self, msg_type: str, err: RoboCompError, sess: Session | None) -> None:
        """A refusal of a connection without a session, or of a notification: counted, and told to
        the referee once a beat (a report refused ten times a second is one line a beat, not ten)."""
        key = (msg_type, err.code, sess.who if sess is not None else None)
        row = self.refused.get(key)
        if row is None:
            self.refused[key] = [1, err.message]
        else:
            row[0] += 1

    def tell_refused(self) -> None:
        """One ``refused`` event per (type, code, sender) with its ``count`` for the refusals counted
        since the last beat, and one per peer address whose handshakes the transport refused (no
        valid token or key, ``E_AUTH``) or whose connections the guard cut (over a limit,
        ``E_RATE``): a flood is logged in bulk."""
        core = self.core
        if self.refused:
            rows, self.refused = self.refused, {}
            for (msg_type, code, who), (count, message) in sorted(rows.items(), key=lambda kv: (kv[0][0], kv[0][1])):
                core.emit("refused", who.team if who is not None else None, {
                    "by": who.name if who is not None else "unknown", "type": msg_type, "code": code,
                    "message": message, "count": count})
        zap, guards = core.zap, [g for g in (core.guard, core.pub_guard) if g is not None]
        if not ((zap is not None and zap.refusals_waiting) or any(g.cuts_waiting for g in guards)):
            return
        cuts: list[tuple[str, str, int, str]] = []
        if zap is not None:
            for (mechanism, address), row in sorted(zap.take_refused().items()):
                cuts.append(("E_AUTH", address, row.count, f"{row.count} connection(s) from {address or 'an unknown address'} "
                             f"were refused ({mechanism}: {row.reason}); libzmq closed them before reading a message"))
        for guard in guards:
            for address, cut in sorted(guard.take_cut().items()):
                cuts.append(("E_RATE", address, cut.count, f"{cut.count} connection(s) from {address} were cut at "
                             f"once ({cut.reason}); the match goes on"))
        for code, address, count, message in cuts:
            log.warning("%s", message)
            core.emit("refused", None, {"by": "unknown", "type": "connect", "code": code, "message": message,
                                        "count": count, "address": address})


__all__ = ["SESSION_IDLE", "SessionDesk"]
