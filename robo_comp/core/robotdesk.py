"""Robots at the core: what consoles ask of them and what their hosts say of them.

:class:`RobotDesk` proves *who* may do each thing to a robot (a team its own robots, the referee
any, a robot's own host connection its reports), then hands the command to the match
(:class:`robo_comp.match.model.Match`), which decides *what* it does: consoles' ``robots``,
``monitor``, ``tasks``, ``give``, ``stop``, the referee's ``hosts`` and ``handover``; hosts'
``register``, ``report``/``reports``, ``task.next``, ``task.done``, ``radio``, ``leave`` and their
answers to stops (``reply``). A stop is forwarded to the robot's host and answered when the host
confirms it, or with ``E_TIMEOUT``.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Transport
from robo_comp.core.sessiondesk import SessionDesk
from robo_comp.errors import (
    AuthError, FieldError, ForbiddenError, HeldError, ImplausibleError, NotYoursError, RoboCompError, TimeoutError_,
    UnavailableError,
)
from robo_comp.protocol.states import RobotStatus
from robo_comp.teams.policy import check_referee

#: Seconds a robot's host has to confirm a stop.
STOP_TIMEOUT = 2.0


@dataclass(slots=True)
class PendingStop:
    """A stop forwarded to a robot host, waiting for its acknowledgement."""

    ident: bytes
    req_id: int
    tag: int
    deadline: float
    t0: float


class RobotDesk:
    """The robots' requests (see the module docstring). ``host_reply(ident, id, raw)`` gets the
    hosts' answers that are not stops' (the upload desk's)."""

    def __init__(self, core: Transport, access: SessionDesk, host_reply: Callable[[bytes, int, dict[str, Any]], Any]) -> None:
        self.core = core
        self.access = access
        self.match = core.match
        self.registry = core.match.registry
        self.sessions = access.sessions
        self.host_reply = host_reply
        self.pending_stops: dict[int, PendingStop] = {}

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this desk adds to the core."""
        return {"robots": self._on_robots, "monitor": self._on_monitor, "tasks": self._on_tasks,
                "give": self._on_give, "stop": self._on_stop, "hosts": self._on_hosts, "handover": self._on_handover,
                "register": self._on_register, "report": self._on_report, "reports": self._on_reports,
                "task.next": self._on_task_next, "task.done": self._on_task_done, "radio": self._on_radio,
                "leave": self._on_leave, "reply": self._on_host_reply}

    # ------------------------------------------------------------------ consoles
    def _on_robots(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.access.session(ident)
        team = None if s.who.role == "referee" else s.who.team
        return {"robots": [r.summary() for r in self.registry.of_team(team)]}

    def _on_monitor(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        return self.access.robot_for(ident, msg.body["tag"]).monitor()

    def _on_tasks(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        r = self.access.robot_for(ident, msg.body["tag"])
        return {"tag": r.tag, "advertised": list(r.tasks.values()),
                "current": r.current.summary() if r.current else None,
                "pending": r.pending.summary() if r.pending else None,
                "queued": [t.summary() for t in r.queue], "done": [t.summary() for t in r.done]}

    def _on_give(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.access.session(ident)
        r = self.access.robot_for(ident, msg.body["tag"])
        return self.match.give(r, msg.body["task"], msg.body.get("args", []), bool(msg.body.get("queue", False)),
                               s.who.name)

    def _on_stop(self, ident: bytes, msg: P.Message) -> None:
        r = self.access.robot_for(ident, msg.body["tag"])
        self.match.contest.check_robot(r.tag)
        if r.status is not RobotStatus.CONNECTED or r.session is None:
            raise UnavailableError(
                f"robot {r.tag} is {r.status}; it halts by itself when it loses the core, and cannot be reached now")
        cid = self.core.new_request_id()
        now = time.monotonic()
        self.pending_stops[cid] = PendingStop(ident, msg.id, r.tag, now + STOP_TIMEOUT, now)
        self.core.to_host(r, "stop", {"tag": r.tag}, cid)
        return None  # the reply goes out when the robot confirms (see _on_host_reply)

    def expire_stops(self, now: float) -> None:
        """Answer the stops whose robots did not confirm in time with ``E_TIMEOUT``."""
        for cid, p in list(self.pending_stops.items()):
            if now >= p.deadline:
                del self.pending_stops[cid]
                err = P.error_reply(p.req_id, TimeoutError_(
                    f"robot {p.tag} did not confirm the stop within {STOP_TIMEOUT:.0f} s; "
                    "its host may be lost (it halts on its own when it loses the core)"))
                self.core.send(p.ident, err, True)

    def _on_hosts(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        """The robot hosts (the referee's view): who, since when, last heard, which robots."""
        check_referee(self.access.session(ident).who, "list the robot hosts")
        now = time.monotonic()
        rows = []
        for sid, s in self.sessions.items():
            if s.who.role != "host":
                continue
            held = sorted(t for t in s.tags if self.registry.robots[t].session == sid)
            rows.append({"host": sid.hex(), "team": s.who.team, "client": s.client, "opened": s.opened,
                         "silent": round(now - s.last_seen, 3), "tags": held,
                         "robots": [self.registry.robots[t].robot_id for t in held]})
        rows.sort(key=lambda row: (row["team"] or "", row["opened"]))
        return {"hosts": rows}

    def _on_handover(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        """The referee hands robots over: each is halted and released by the host that holds it, and
        the next host that registers it (with its robot id) takes it."""
        who = self.access.session(ident).who
        check_referee(who, "hand robots over from one robot host to another")
        tags = msg.body["tags"]
        if not tags or len(tags) > 1000 or any(type(t) is not int for t in tags):
            raise FieldError("'tags' must be a list of 1 to 1000 robot tags")
        released = []
        for tag in tags:
            r = self.registry.get(tag)
            old = r.session
            if old is not None:  # the host halts the robot and lets it go (no separate stop)
                self.core.send(old, P.request("release", 0, {"tag": tag, "message":
                                                              "the referee handed this robot over to another host"}))
                if old in self.sessions:
                    self.sessions[old].tags.discard(tag)
            self.match.handed_over(r, who.name, old.hex() if old else None)
            released.append(tag)
        return {"released": released}

    # ------------------------------------------------------------------ robot hosts
    def _on_register(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        who = self.core.tokens.lookup(b["token"])
        team = who.team
        if who.role != "host" or team is None:
            raise ForbiddenError(
                "robots register only through the organiser's robot host, with a host token "
                "(STATE/hosts/<team>.token); a team's token gives its robots commands but never speaks "
                "for the world (see docs/security.md, 'Who runs what')")
        self.access.check_key(who)
        robot_id = b["robot_id"]
        sess = self.sessions.get(ident)
        if sess is not None and sess.who != who:
            raise AuthError(f"this connection's session speaks for {sess.who.name}; robots of "
                            f"{who.name} register on a connection of their own")
        r = self.match.admit(team, robot_id, b)  # the scenario's robots, a free start: the match's rules
        holder = self.sessions.get(r.session) if r is not None and r.session is not None and r.session != ident else None
        if r is not None and holder is not None and r.status is RobotStatus.CONNECTED:
            raise HeldError(
                f"robot {robot_id!r} (tag {r.tag}) of team {team} is held by another robot host (connected "
                f"since {time.strftime('%H:%M:%S', time.localtime(holder.opened))}, {len(holder.tags)} robots, "
                f"heard {time.monotonic() - holder.last_seen:.1f} s ago) and was not taken from it. Stop that "
                f"host first (its robots are lost after {3 * self.core.heartbeat:g} s without it, and then this "
                f"host takes them), or ask the referee: 'robo-comp ctl hosts' lists the hosts, "
                f"'robo-comp ctl handover {r.tag}' hands the robot to the next host that registers it")
        sess = self.access.open_host_session(ident, who)
        if r is not None and holder is not None:
            holder.tags.discard(r.tag)
        reply = self.match.register(team, robot_id, ident, b)
        sess.tags.add(reply["tag"])
        return dict(reply, session=sess.secret, heartbeat=self.core.heartbeat)

    def _on_report(self, ident: bytes, msg: P.Message) -> None:
        """One robot's pose (a row of the match's ``take_rows``, without its loop)."""
        b = msg.body
        r = self.access.hosted(ident, b["tag"])
        self.match.report(r, b["x"], b["y"], b["heading"], b.get("moving", False), b.get("sensors"))
        return None

    def _on_reports(self, ident: bytes, msg: P.Message) -> None:
        """Many robots of one host in one message (a host reports its robots in batches): the rows of
        the match's ``take_rows``."""
        b = msg.body
        n = P.check_reports(b)
        sess = self.sessions.get(ident)
        if sess is None:
            self.access.known(ident)
        assert sess is not None
        team = sess.who.team
        assert team is not None  # a host's session: register needs a team's host token
        foreign, refused = self.match.take_rows(ident, team, b["tags"], b["x"], b["y"], b["heading"],
                                                b.get("moving") or [False] * n, b.get("sensors") or [None] * n,
                                                b.get("sigma") or [0.0] * n)
        if foreign:  # the others' rows were taken
            raise NotYoursError(f"robots {foreign[:10]} are not hosted by this connection; register them first")
        if refused:
            raise ImplausibleError(f"the poses of robots {[t for t, _ in refused[:10]]} were not taken (the "
                                   f"referee sees why): {refused[0][1]}")
        return None

    def _on_task_next(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        t = self.match.task_next(self.access.hosted(ident, msg.body["tag"]))
        return {"task": t.wire() if t is not None else None}

    def _on_task_done(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        return self.match.task_done(self.access.hosted(ident, msg.body["tag"]), msg.body)

    def _on_radio(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        r = self.access.hosted(ident, b["tag"])
        return {"delivered": self.match.radio(r, b.get("to"), b["data"])}

    def _on_leave(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        r = self.access.hosted(ident, msg.body["tag"])
        self.match.leave(r)
        self.sessions[ident].tags.discard(r.tag)
        return {}

    def _on_host_reply(self, ident: bytes, msg: P.Message) -> None:
        raw = msg.body
        p = self.pending_stops.get(msg.id)
        if p is None:
            self.host_reply(ident, msg.id, raw)
            return None  # an upload's answer, or a late answer to a stop that already timed out
        r = self.registry.robots[p.tag]
        if r.session != ident:  # request ids are easy to guess: only the robot's own host confirms
            raise NotYoursError(f"this connection does not host robot {p.tag}; its stop is not yours to confirm")
        del self.pending_stops[msg.id]
        err, body = raw.get("error"), raw.get("body")
        send = self.core.send
        if not isinstance(err, (dict, type(None))) or not isinstance(body, (dict, type(None))):
            send(p.ident, P.error_reply(p.req_id, RoboCompError(
                f"robot {p.tag}'s host answered the stop with a malformed reply; it may not have halted")), True)
            raise FieldError("a reply's 'error' and 'body' must be maps")
        if not raw.get("ok"):
            err = err or {}
            send(p.ident, P.error_reply(p.req_id, RoboCompError(
                f"robot {p.tag} could not stop: {err.get('message', 'no reason given')}")), True)
            return None
        ms = (time.monotonic() - p.t0) * 1000
        cancelled = self.match.stopped(r, body or {}, ms)
        send(p.ident, P.ok_reply(p.req_id, {  # a stop is answered at once, even during a storage fault
            "tag": r.tag, "x": r.x, "y": r.y, "heading": r.heading, "cancelled": cancelled, "ms": ms}), True)
        return None


__all__ = ["PendingStop", "RobotDesk", "STOP_TIMEOUT"]
