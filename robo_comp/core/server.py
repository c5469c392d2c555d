"""The core: one ROUTER loop with one poller, a PUB socket for events, ownership on every command.

Robot hosts and consoles connect DEALER sockets to the ROUTER. A connection becomes a
*session* by saying ``hello`` with a token (a team's or the referee's); robot hosts then
``register`` robots. A session belongs to whoever proved it, never to a routing id: the reply to
``hello`` carries a random session secret, and every later message must carry it (checked in
constant time, and under CurveZMQ together with the key the frame came with) or it is refused with
``E_AUTH`` and changes nothing (see ``docs/security.md``). Every command names a robot tag and is
checked against the session's principal (``robo_comp.teams.policy``). Events go to the PUB socket (the public view for
walls) and, in full, to the sessions that ``watch`` and may see them.
"""
from __future__ import annotations

import contextlib
import ctypes
import gc
import hmac
import json
import logging
import math
import os
import secrets
import signal
import socket
import time
import traceback
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zmq

from robo_comp import protocol as P
from robo_comp.core.competition import Competition
from robo_comp.protocol.curve import ServerKeys, ZapHandler, load_server_keys
from robo_comp.core.mapdesk import MapDesk
from robo_comp.core.teamdesk import TeamDesk
from robo_comp.core.videodesk import VideoDesk
from robo_comp.core.uploads import UploadDesk
from robo_comp.core.eventlog import EventLog
from robo_comp.core.guard import (
    PER_ADDRESS,
    PUB_INBOUND,
    SWEEP_SECONDS,
    ConnectionGuard,
    GuardLimits,
    copy_received,
    raise_fd_limit,
)
from robo_comp.private_files import private_dir
from robo_comp.core.recovery import RecoveryReport, recover
from robo_comp.core.robotdesk import RobotDesk
from robo_comp.core.sessiondesk import SessionDesk
from robo_comp.core.feed import PositionFeed
from robo_comp.core.outqueue import OutQueue
from robo_comp.core.sessions import Session
from robo_comp.core.sockets import open_pub, open_router
from robo_comp.match.model import Match
from robo_comp.match.registry import RobotRecord
from robo_comp.protocol.states import Phase
from robo_comp.errors import (
    AuthError,
    ForbiddenError,
    MalformedError,
    RoboCompError,
    StorageError,
)
from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.scoring.config import ScoringConfig
from robo_comp.match.clock import CLOCK_PERIOD
from robo_comp.teams.policy import check_referee
from robo_comp.teams.tokens import Principal, TokenBook
from robo_comp.world.public import arena_payload
from robo_comp.world.scenario import Scenario

log = logging.getLogger("robo_comp.core")

#: Position batches per second: reports that arrive in between are conflated (the newest pose wins).
POSE_HZ = 10.0
#: Requests served while the event log cannot be written: they log nothing, or (stop) must never
#: wait for a disk; everything else gets E_STORAGE and changes nothing.
STORAGE_FREE = frozenset({"hello", "heartbeat", "bye", "watch", "robots", "monitor", "tasks", "snapshot", "arena",
                          "stats", "score", "map", "map.delta", "picture.get", "extensions", "stop", "report",
                          "reports", "reply"})


class Core:
    """The ZeroMQ ROUTER core. Create, ``bind()``, then ``run()`` (blocks until ``stop()``/signal)."""

    def __init__(self, state_dir: Path, scenario: Scenario, teams: list[str] | None = None, *,
                 host: str = "127.0.0.1",
                 port: int = 5555, pub_port: int = 0, heartbeat: float = 1.0, fsync: bool = False,
                 practice: bool = False, scoring: ScoringConfig | None = None, plugins: Any = None,
                 approve_uploads: bool = False, curve: bool = False, pose_hz: float = POSE_HZ,
                 robots_per_team: int | None = None, max_speed: float | None = None,
                 max_connections: int | None = None, max_per_address: int | None = None) -> None:
        self.state_dir = private_dir(state_dir)  # tokens, logs, uploads, pictures: the organiser's (0700)
        self.scenario = scenario
        self.tokens = TokenBook(self.state_dir, teams or [t.name for t in scenario.teams])
        self.arena_payload = arena_payload(scenario, self.tokens.teams)
        #: CurveZMQ (``--curve``): the core's keys and the allow list from STATE/keys, else None.
        self.curve: ServerKeys | None = load_server_keys(self.state_dir, self.tokens.teams) if curve else None
        #: The transport's credential check (ZAP), made in bind().
        self.zap: ZapHandler | None = None
        #: Who the transport let in for the frame being handled: the CurveZMQ key's owner, or the
        #: PLAIN token's principal as "role:name" (the ZAP handler's user id); see _drain.
        self.key_owner: str | None = None
        self.host = host
        self.port = port
        self.pub_port = pub_port
        self.heartbeat = heartbeat
        self.pm = plugins or get_plugin_manager()
        #: The match this core drives (robots, their tasks, the contest): no sockets; its events and
        #: directives come back through this core's MatchOutput methods (emit, to_host, ...).
        self.match = Match(scenario, self.tokens.teams, self, self.pm,
                           scoring=scoring or ScoringConfig.from_table(scenario.scoring), practice=practice,
                           robots_per_team=robots_per_team, max_speed=max_speed)
        self.registry = self.match.registry
        #: Who sees team code's debug drawing in replays (protocol.topics.DEBUG_REPLAY); set by the CLI.
        self.debug_replay = "team"
        self.sessions: dict[bytes, Session] = {}
        # Who watches what: team name -> routing ids, and the referee's under None.
        self.watchers: dict[str | None, set[bytes]] = {}
        self.next_core_req = 1
        # The core owns its context: the ZAP endpoint (the transport's credential check) is one per context.
        self.ctx = zmq.Context()
        copy_received(self.ctx)  # a received frame holds its own size, not a shared 8 KiB buffer (see guard.py)
        # Connections are file descriptors: take all the process may have, and bound them (see bind)
        nofile = raise_fd_limit()
        self.ctx.set(zmq.MAX_SOCKETS, max(1024, min(nofile, 65_535)))
        self.limits = GuardLimits.for_fd_limit(nofile, max_connections, max_per_address or PER_ADDRESS)
        #: The connection guards of the ROUTER and PUB sockets (made in bind()).
        self.guard: ConnectionGuard | None = None
        self.pub_guard: ConnectionGuard | None = None
        self.router: zmq.Socket | None = None
        self.pub: zmq.Socket | None = None
        self._running = False
        self._stop_asked = False  # a SIGTERM during start-up must not be lost when the loop starts
        self.started = time.monotonic()
        self.core_id = secrets.token_hex(8)  # tells clients when they talk to a restarted core
        self.stats = {"received": 0, "errors": 0, "events": 0, "dropped": 0, "unrouted": 0}
        #: What goes out, after each turn's log flush (core/outqueue.py).
        self.out = OutQueue(self.stats, self.sessions, self.emit)
        # Background work cut into slices of bounded size (position batches, position samples for the
        # log): the loop does one slice per turn and looks at its socket in between, so that a stop
        # never waits behind a whole batch of 10,000 robots.
        self._slices: deque[Callable[[], None]] = deque()
        #: The robots' poses: the live feed's conflated batches and the log's samples (core/feed.py).
        self.feed = PositionFeed(self.match, self.emit, self._log_sample, self._slices)
        self.pose_period = 1.0 / pose_hz
        self._handlers: dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]] = {
            "snapshot": self._on_snapshot, "arena": self._on_arena, "stats": self._on_stats}
        log_path = self.state_dir / "events.log"
        # The desks: each proves who may ask what and hands the rest to the match; the session desk
        # is the others' Access. The log is opened after recovery (below); they reach it through the core.
        self.access = SessionDesk(self, self.sessions, self.watchers)
        self.maps = MapDesk(self.access, self, scenario)
        self.competition = Competition(self.access, self, self.match, self.state_dir, lambda: self.events)
        self.uploads = UploadDesk(self.access, self, self.state_dir, approve_uploads or scenario.approve_uploads)
        self.robots = RobotDesk(self, self.access, self.uploads.host_reply)
        self.teamdesk = TeamDesk(self.access, self)
        self.videodesk = VideoDesk(self.access, self, self.state_dir)
        for desk in (self.access, self.robots, self.competition, self.maps, self.uploads, self.teamdesk, self.videodesk):
            self._handlers.update(desk.handlers())
        self.recovered: RecoveryReport | None = None
        if log_path.exists() and log_path.stat().st_size > 0:
            self.recovered = recover(self.match, log_path)
            self.events = EventLog(log_path, fsync=fsync, seq=self.recovered.seq,
                                   good_end=self.recovered.good_end, legacy=self.recovered.legacy_tail)
        else:
            self.events = EventLog(log_path, fsync=fsync)

    # ------------------------------------------------------------------ sockets and loop
    def bind(self, before_announce: Callable[[], None] | None = None) -> None:
        """Bind the ROUTER and PUB sockets and write ``STATE/core.json``.

        ``before_announce`` runs once the ports are known and before ``core.json`` says the core is
        up (the CLI writes ``match.json`` there: whoever waits for ``core.json`` reads the match's
        file as this core runs it, never the one before an ``--override``)."""
        # the credential check is up before the first handshake can start: a CurveZMQ key from
        # STATE/keys, else a token as the PLAIN password (nothing of a peer without one is buffered)
        self.zap = ZapHandler(self.ctx, self.curve.allowed if self.curve is not None else None,
                              self.tokens.lookup)
        _seed_routing_ids()
        self.router, self.port = open_router(self.ctx, self.host, self.port, self.curve, self.heartbeat)
        self.guard = ConnectionGuard.watch(self.router, self.port, self.limits, hold=True)
        self.zap.admit = self.access.admit
        self.pub, self.pub_port = open_pub(self.ctx, self.host, self.pub_port, self.curve)
        self.pub_guard = ConnectionGuard.watch(self.pub, self.pub_port, self.limits, PUB_INBOUND)
        shown = "127.0.0.1" if self.host in ("0.0.0.0", "*") else self.host
        info = {"router": f"tcp://{shown}:{self.port}", "pub": f"tcp://{shown}:{self.pub_port}",
                "pid": os.getpid(), "protocol": P.PROTOCOL_VERSION, "teams": self.tokens.teams,
                "heartbeat": self.heartbeat, "arena": self.scenario.name}
        if self.curve is not None:
            info.update(curve=True, curve_public=self.curve.public.decode())
        if before_announce is not None:
            before_announce()
        tmp = self.state_dir / "core.json.tmp"
        tmp.write_text(json.dumps(info, indent=2))
        os.replace(tmp, self.state_dir / "core.json")
        self.emit("core.started", None, {"router": info["router"], "teams": self.tokens.teams,
                                         "arena": self.arena_payload, "debug_replay": self.debug_replay})
        if self.recovered is not None:
            self.emit("core.recovered", None, self.recovered.to_dict())
        self._commit()

    def close(self) -> None:
        """Close the sockets and the log of a core that will not run (its start failed)."""
        for guard in (self.guard, self.pub_guard):
            if guard is not None:
                guard.close()
        for sock in (self.router, self.pub):
            if sock is not None:
                sock.close(0)
        self.router = self.pub = None
        if self.zap is not None:
            self.zap.close()
        self.ctx.term()  # the core's own context (see __init__)
        self.events.close()

    def stop(self) -> None:
        """Ask the loop to end after the current turn (or, before it started, not to start)."""
        self._stop_asked = True
        self._running = False

    def run(self) -> None:
        """Serve until :meth:`stop` or SIGINT/SIGTERM. One thread, one poller."""
        if self.router is None:
            self.bind()
        assert self.router is not None
        # A signal wakes the poller through this pair (Python writes a byte to it), so SIGTERM
        # ends the loop at once instead of after the poll's timeout (up to a heartbeat).
        wake, wake_w = socket.socketpair()
        wake.setblocking(False)
        wake_w.setblocking(False)
        old_wakeup: int | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                signal.signal(sig, lambda *_: self.stop())
            except ValueError:  # not in the main thread (tests may run a core in a thread)
                pass
        try:
            old_wakeup = signal.set_wakeup_fd(wake_w.fileno(), warn_on_full_buffer=False)
        except ValueError:  # not in the main thread: stop() is called by the owner, between polls
            pass
        # What exists now (modules, the arena, recovered state) lives as long as the core: keep it
        # out of the collector's generations, and collect young objects less often, so that
        # a full collection does not stall a stop behind it.
        gc.collect()
        gc.freeze()
        gc.set_threshold(20_000, 50, 100)
        poller = zmq.Poller()
        poller.register(self.router, zmq.POLLIN)
        if self.zap is not None:
            poller.register(self.zap.sock, zmq.POLLIN)
        for guard in (self.guard, self.pub_guard):
            if guard is not None:
                poller.register(guard.monitor, zmq.POLLIN)
        poller.register(wake, zmq.POLLIN)
        self._running = not self._stop_asked
        next_tick = time.monotonic() + self.heartbeat
        next_pose = time.monotonic() + self.pose_period
        next_clock = time.monotonic()  # the match clock's record in the log (see MatchClock)
        try:
            while self._running:
                if next_tick - time.monotonic() > self.heartbeat:  # the clock went back: beat now
                    next_tick = next_pose = time.monotonic()
                timeout = max(0.0, next_tick - time.monotonic())
                if self.robots.pending_stops or self.uploads.busy:
                    timeout = min(timeout, 0.05)
                if self.storage_fault is not None:  # try the log again soon: resume within a fraction of a second
                    timeout = min(timeout, 0.2)
                if self.match.posed:
                    timeout = min(timeout, max(0.0, next_pose - time.monotonic()))
                if self.match.contest.phase is Phase.RUNNING:
                    timeout = min(timeout, max(0.0, next_clock - time.monotonic()))
                if self._slices:  # background work left: look at the socket, then do the next slice
                    timeout = 0.0
                pub_guard = self.pub_guard
                # what each connection sent (PUB's subscribers) or holds (the ROUTER's), looked at often
                if (pub_guard is not None and pub_guard.sweeping) or (self.guard is not None and self.guard.sweeping):
                    timeout = min(timeout, SWEEP_SECONDS)
                if poller.poll(math.ceil(timeout * 1000)):
                    if self.guard is not None:  # connections counted before their handshakes are judged
                        self.guard.serve()
                    if pub_guard is not None:
                        pub_guard.serve()
                    if self.zap is not None:
                        self.zap.serve()
                    self._drain()
                    with contextlib.suppress(BlockingIOError):
                        wake.recv(4096)
                now = time.monotonic()
                if pub_guard is not None:
                    pub_guard.sweep(now)
                if self.guard is not None:
                    self.guard.sweep(now)
                if self.robots.pending_stops:
                    self.robots.expire_stops(now)
                if self.uploads.busy:
                    self.uploads.expire(now)
                if now >= next_pose:
                    self.feed.queue()
                    next_pose = now + self.pose_period
                if now >= next_tick:
                    self._tick(now)
                    next_tick = now + self.heartbeat
                if now >= next_clock:
                    if self.storage_fault is None:  # (not while the log cannot be written, like positions)
                        self.competition.log_clock()
                    next_clock = now + CLOCK_PERIOD
                if self._slices:
                    self._slices.popleft()()
                self._commit()
        finally:
            if old_wakeup is not None:
                signal.set_wakeup_fd(old_wakeup)
            wake.close()
            wake_w.close()
            self.competition.log_clock()  # a clean stop records the clock to the last moment
            self._commit()
            self.events.close()
            for guard in (self.guard, self.pub_guard):
                if guard is not None:
                    guard.close()
            self.router.close(0)
            assert self.pub is not None
            self.pub.close(0)
            if self.zap is not None:  # after the servers: no handshake may find no handler
                self.zap.close()
            self.ctx.term()  # the core's own context (see __init__)

    def _drain(self, budget: int = 2000) -> None:
        """Handle every message waiting on the ROUTER (up to ``budget``) without blocking."""
        router = self.router
        assert router is not None
        for _ in range(budget):
            try:  # who the transport let in (the ZAP handler named the key's owner or the token's principal)
                first = router.recv(zmq.NOBLOCK, copy=False)  # the routing id: its properties name the peer
            except zmq.Again:
                return
            owner = first.get("User-Id")
            self.key_owner = owner if isinstance(owner, str) else None
            # the rest of the message as bytes (cheaper than a Frame per part)
            frames = [first.bytes, *router.recv_multipart()] if first.more else [first.bytes]
            if self.guard is not None:  # what this connection was handed, against what it sent (guard.py)
                self.guard.took(first, frames)
            self.stats["received"] += 1
            ident = frames[0]
            if len(frames) != 2:
                self._send_error(ident, 0, MalformedError(
                    f"expected exactly one frame per message, got {len(frames) - 1}"), None)
                continue
            self._handle(ident, frames[1])
            if self.out.urgent:  # a stop (or its answer) waits: send it before handling more
                return

    def _handle(self, ident: bytes, frame: bytes) -> None:
        req_id = 0
        msg_type = "?"
        sess: Session | None = None  # the session this message proved it belongs to
        try:
            raw, req_id = P.decode_envelope(frame)
            found = self.sessions.get(ident)
            secret: Any = raw.get("s")
            # proved (the common case, kept short): the session's secret, compared in constant time;
            # a refusal below (a bad field, say) is then the session's, else nobody's
            proved = False
            if found is not None and self.out.plain:
                try:
                    proved = _compare(secret, found.secret) and found.key == self.key_owner
                except TypeError:  # not ASCII text (bytes, a number, nil ...): not a secret of ours
                    pass
            if proved:
                sess = found
            msg = P.validate(raw, req_id)
            msg_type = msg.type
            if sess is not None:  # proved above
                sess.last_seen = time.monotonic()
            else:
                sess = self._prove(ident, msg.type, secret)
                if self.storage_fault is not None and msg.type not in STORAGE_FREE:
                    raise StorageError(self.storage_fault)
            if sess is not None and msg_type not in sess.allowed:
                raise ForbiddenError(_role_refusal(sess.who, msg_type))
            body = self._handlers[msg.type](ident, msg)
            if body is not None:
                self._reply(ident, P.ok_reply(req_id, body))
        except RoboCompError as err:
            self._send_error(ident, req_id, err, sess, msg_type)
        except Exception:  # never let one bad message take the core down
            log.error("internal error on %s: %s", msg_type, traceback.format_exc())
            self._send_error(ident, req_id, RoboCompError(
                "the core hit an internal error on this request; it was logged and the core goes on"),
                sess, msg_type)

    def _prove(self, ident: bytes, type_: str, secret: Any) -> Session | None:
        """The session this message belongs to, or None for a message that may come without one
        (a ``hello``/``register`` opening a session, a ``bye`` ending none); raise ``E_AUTH``
        for anything else. A session is proved by its secret (constant-time compare) and, under
        CurveZMQ, by the key the frame came with; the connection's routing id proves nothing."""
        sess = self.sessions.get(ident)
        if sess is None:
            if type_ in P.OPENING:
                _check_route(ident)
                return None
            if type_ == "bye":
                return None
            raise AuthError("this connection has no session: say 'hello' with your team token first "
                            "(the client does this for you); after a core restart, say hello again")
        if type(secret) is not str or not _same(secret, sess.secret):
            raise AuthError(
                "this message does not carry the session secret of this connection's session: every "
                "message after 'hello' must carry the 'session' value the hello reply gave (as \"s\"); "
                "a program that took another connection's routing id gets nothing")
        if self.key_owner != sess.key:
            if self.curve is not None:
                raise AuthError(f"this session was opened with {sess.key}'s CurveZMQ key; a frame sent with "
                                f"{self.key_owner}'s key does not belong to it")
            raise AuthError(f"this session was opened by a connection that presented {sess.key}'s token; a "
                            f"frame of a connection that presented {self.key_owner}'s does not belong to it")
        sess.last_seen = time.monotonic()
        self.out.proved(ident)
        return sess

    def _send_error(self, ident: bytes, req_id: int, err: RoboCompError, sess: Session | None,
                    msg_type: str = "?") -> None:
        self.stats["errors"] += 1
        self._reply(ident, P.error_reply(req_id, err))
        if self.storage_fault is not None:  # nothing more is logged until the log can be written
            return
        if sess is None or msg_type in P.NOTIFICATIONS:  # counted, and logged once a beat
            self.access.count_refused(msg_type, err, sess)
            return
        self.emit("refused", sess.who.team, {"by": sess.who.name, "type": msg_type,
                                             "code": err.code, "message": err.message})

    # ------------------------------------------------------------------ output
    def send(self, ident: bytes, frame: bytes, urgent: bool = False) -> None:
        """Queue a frame for session ``ident`` (a push, or a reply that comes later); it leaves in
        :meth:`_commit`, after the log flush; nothing goes to a route whose connection went away
        until its session proves itself there again (see :meth:`_prove`)."""
        self.out.push(self.router, ident, frame, urgent)  # type: ignore[arg-type]  # bound before any send

    def _reply(self, ident: bytes, frame: bytes) -> None:
        """Queue the reply to the message that just came from ``ident`` (whoever sent it)."""
        self.out.reply(self.router, ident, frame)  # type: ignore[arg-type]

    @property
    def storage_fault(self) -> str | None:
        """Why the event log cannot be written now (None while it can)."""
        return self.out.storage_fault

    def _commit(self) -> None:
        """Flush the event log, then send every queued reply and event (see core/outqueue.py): the
        scoreboard goes out with the replies that changed it."""
        self.match.contest.flush_score()
        self.out.commit(self.events)

    def emit(self, topic: str, team: str | None, data: dict[str, Any], *, log_it: bool = True) -> None:
        """Log an event, publish its public view, and push it to watchers who may see it (an
        event that is not logged goes out even while the log cannot be written)."""
        self.stats["events"] += 1
        if log_it:
            self.events.append(topic, team, data)
        view = P.public_event(topic, data)  # who may see what: the one table (protocol/topics.py)
        if view is not None and self.pub is not None:
            self.out.publish(self.pub, [topic.encode(), P.pack(view)], not log_it)
        if team == P.EVERYONE:
            targets: list[bytes] = [i for group in self.watchers.values() for i in group]
        else:
            referee = self.watchers.get(None)
            own = self.watchers.get(team) if team is not None else None
            targets = [*(referee or ()), *(own or ())]
        if targets:
            frame = P.request("event", 0, {"topic": topic, "team": team, "data": data})
            for ident in targets:
                self.send(ident, frame, not log_it)
        if topic != "robot.positions":
            self.pm.hook.robo_comp_event(topic=topic, team=team, data=data)

    def forget_route(self, ident: bytes) -> None:
        """Connection ``ident``'s session is gone: it is no longer an unproven route."""
        self.out.proved(ident)

    # ------------------------------------------------------------------ the match's output (MatchOutput)
    def to_host(self, r: RobotRecord, type_: str, body: dict[str, Any], req_id: int = 0) -> None:
        """A directive to the host connection of robot ``r`` (a stop leaves at once, whatever the
        log's state: safety first)."""
        if r.session is not None:
            self.send(r.session, P.request(type_, req_id, body), type_ == "stop")

    def to_hosts(self, type_: str, body: dict[str, Any]) -> None:
        """A directive to every robot host connection (``hold``)."""
        frame = P.request(type_, 0, body)
        for ident in self.access.host_sessions():
            self.send(ident, frame)

    def finished(self) -> None:
        """The match has just finished: its results go into the state folder."""
        self.competition.write_results_now()

    def discovered(self, r: RobotRecord, find: dict[str, Any]) -> None:
        """A find was reported: the map service marks it for the team."""
        self.maps.discovery(r.tag, r.team, find["x"], find["y"], find["kind"], find["evidence"])

    def new_request_id(self) -> int:
        """A fresh id for a request the core sends to a robot host (its reply comes as ``reply``)."""
        cid = self.next_core_req
        self.next_core_req += 1
        return cid

    # ------------------------------------------------------------------ timers
    def _log_sample(self, tags: list[int]) -> None:
        """A sample of robots ``tags``' poses into the log (none while it cannot be written)."""
        if self.storage_fault is None:
            self.events.append("robot.positions", None, self.match.position_sample(tags))

    def _tick(self, now: float) -> None:
        """Once a heartbeat: position samples into the log, the referee's integrity events, map
        deltas, the match clock; heartbeats, lost robots, idle sessions and refusals (the session
        desk's)."""
        if self.storage_fault is None:  # samples: none kept while the log cannot be written
            self.feed.sample()
        self.match.tell_integrity()
        self.maps.push()
        self.match.contest.tick()
        self.access.beat(now)

    # ------------------------------------------------------------------ the core's own requests
    def _on_arena(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        self.access.session(ident)
        return self.arena_payload

    def _on_stats(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        check_referee(self.access.session(ident).who, "read the core's counters")
        by_status: dict[str, int] = {}
        for r in self.registry.robots.values():
            by_status[r.status] = by_status.get(r.status, 0) + 1
        sessions_by: dict[str, int] = {}
        for s in self.sessions.values():
            sessions_by[s.who.name] = sessions_by.get(s.who.name, 0) + 1
        guard = self.guard
        return dict(self.stats, robots=by_status, sessions=len(self.sessions), sessions_by=sessions_by,
                    connections=guard.open if guard else 0, connections_cut=guard.cut_total if guard else 0,
                    connection_limit=self.limits.total,
                    log_seq=self.events.seq,
                    storage=self.storage_fault, log_unwritten=self.events.unwritten,
                    uptime=time.monotonic() - self.started,
                    recovered=self.recovered.to_dict() if self.recovered is not None else None)

    def _on_snapshot(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.access.session(ident)
        team = None if s.who.role == "referee" else s.who.team
        return dict(self.match.snapshot(team), arena=self.arena_payload, teams=self.tokens.teams,
                    seq=self.events.seq)


_compare = hmac.compare_digest


def _same(given: str, secret: str) -> bool:
    """Constant-time comparison of a session secret (text that is not ASCII never matches)."""
    try:
        return hmac.compare_digest(given, secret)
    except TypeError:  # compare_digest takes ASCII text only
        return False


#: Shortest routing id a client may choose (ids made by libzmq itself start with a zero byte).
MIN_ROUTING_ID = 16


def _check_route(ident: bytes) -> None:
    """A session opens only on a connection whose routing id cannot be guessed: one that libzmq
    made up (a zero byte, then a number from a counter seeded at random by :func:`_seed_routing_ids`)
    or a random one of :data:`MIN_ROUTING_ID` bytes or more chosen by the client."""
    if ident[:1] != b"\x00" and len(ident) < MIN_ROUTING_ID:
        raise AuthError(f"this connection's routing id has {len(ident)} bytes; a client that chooses its "
                        f"own must make it random and at least {MIN_ROUTING_ID} bytes long "
                        "(robo_comp.protocol.new_routing_id), or set none at all")


def _seed_routing_ids() -> None:
    """libzmq numbers the connections that set no routing id with a counter that starts at C's
    ``rand()``, which nothing seeds: every core would hand out the same ids (``0x006b8b4567``,
    ...), so that anyone could claim the id the next connection will get, and an id taken that way
    makes libzmq abort the core when it hands it out. Seed it at random before the ROUTER exists."""
    try:
        ctypes.CDLL(None).srand(secrets.randbits(32))
    except (OSError, AttributeError):  # no C library to reach (not Linux/macOS): nothing to seed
        log.debug("could not seed libzmq's routing id counter")


def _role_refusal(who: Principal, type_: str) -> str:
    """The sentence for a message a principal's role may not send (see ``protocol.ROLE_MESSAGES``)."""
    if who.role == "host":
        return (f"a robot host runs robots and reports what happens to them; {type_!r} is for the consoles "
                "of a team or the referee, with their own tokens")
    return (f"{type_!r} is a robot host's message: only the organiser's robot hosts (STATE/hosts/) say where "
            f"robots are and what they see. {who.name}'s token gives robots commands, uploads code and reads "
            "its own robots; it never speaks for the world")
