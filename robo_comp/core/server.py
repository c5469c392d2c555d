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
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import zmq

from robo_comp import protocol as P
from robo_comp.core.competition import Competition
from robo_comp.protocol.curve import ServerKeys, ZapHandler, load_server_keys, secure_plain_server, secure_server
from robo_comp.core.mapdesk import MapDesk
from robo_comp.core.uploads import UploadDesk
from robo_comp.core.eventlog import EventLog, StorageFault
from robo_comp.core.guard import (
    HANDSHAKE_SECONDS,
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
from robo_comp.core.sessions import Session
from robo_comp.match.model import Match
from robo_comp.match.registry import RobotRecord
from robo_comp.protocol.states import Phase, RobotStatus
from robo_comp.errors import (
    AuthError,
    FieldError,
    ForbiddenError,
    HeldError,
    ImplausibleError,
    MalformedError,
    NotYoursError,
    RateLimitError,
    RoboCompError,
    StorageError,
    TimeoutError_,
    UnavailableError,
)
from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.scoring.config import ScoringConfig
from robo_comp.match.clock import CLOCK_PERIOD
from robo_comp.teams.policy import check_owner, check_referee
from robo_comp.teams.tokens import ORGANISER, REFEREE, Principal, TokenBook
from robo_comp.world.public import arena_payload
from robo_comp.world.scenario import Scenario

log = logging.getLogger("robo_comp.core")

#: How long a console session may stay silent before it is forgotten (watchers heartbeat).
SESSION_IDLE = 300.0
STOP_TIMEOUT = 2.0
#: Events queued per PUB subscriber before the slowest ones start missing events (ZMQ_SNDHWM).
#: Positions travel conflated (one batch per team per pose period), so 2,000 events are tens of
#: seconds of a 1,000-robot match.
PUB_QUEUE = 2_000
#: Position batches per second: reports that arrive in between are conflated (the newest pose wins).
POSE_HZ = 10.0
#: Robots per ``robot.positions`` event (and per logged sample record): one such chunk is the
#: largest piece of background work between two looks at the socket.
POSE_CHUNK = 500
#: Frames held back while the log cannot be written, at most (the oldest go first).
HELD_FRAMES = 50_000
#: Requests served while the event log cannot be written: they log nothing, or (stop) must never
#: wait for a disk; everything else gets E_STORAGE and changes nothing.
STORAGE_FREE = frozenset({"hello", "heartbeat", "bye", "watch", "robots", "monitor", "tasks", "snapshot", "arena",
                          "stats", "score", "map", "map.delta", "picture.get", "extensions", "stop", "report",
                          "reports", "reply"})


@dataclass(slots=True)
class PendingStop:
    """A stop forwarded to a robot host, waiting for its acknowledgement."""

    ident: bytes
    req_id: int
    tag: int
    deadline: float
    t0: float


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
        self._arena_payload = arena_payload(scenario, self.tokens.teams)
        #: CurveZMQ (``--curve``): the core's keys and the allow list from STATE/keys, else None.
        self.curve: ServerKeys | None = load_server_keys(self.state_dir, self.tokens.teams) if curve else None
        self._zap: ZapHandler | None = None
        # who the transport let in for the frame being handled: the CurveZMQ key's owner, or the
        # PLAIN token's principal as "role:name" (the ZAP handler's user id); see _drain
        self._key_owner: str | None = None
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
        self.sessions: dict[bytes, Session] = {}
        # Who watches what: team name -> routing ids, and the referee's under None.
        self.watchers: dict[str | None, set[bytes]] = {}
        self.pending_stops: dict[int, PendingStop] = {}
        self.next_core_req = 1
        # The core owns its context: the ZAP endpoint (the transport's credential check) is one per context.
        self.ctx = zmq.Context()
        copy_received(self.ctx)  # a received frame holds its own size, not a shared 8 KiB buffer (see guard.py)
        # Connections are file descriptors: take all the process may have, and bound them (see bind)
        nofile = raise_fd_limit()
        self.ctx.set(zmq.MAX_SOCKETS, max(1024, min(nofile, 65_535)))
        self.limits = GuardLimits.for_fd_limit(nofile, max_connections, max_per_address or PER_ADDRESS)
        self._guard: ConnectionGuard | None = None
        self._pub_guard: ConnectionGuard | None = None
        self.router: zmq.Socket | None = None
        self.pub: zmq.Socket | None = None
        self._running = False
        self._stop_asked = False  # a SIGTERM during start-up must not be lost when the loop starts
        self.started = time.monotonic()
        self.core_id = secrets.token_hex(8)  # tells clients when they talk to a restarted core
        self.stats = {"received": 0, "errors": 0, "events": 0, "dropped": 0, "unrouted": 0}
        # Frames to send after this turn's log flush: (socket, frames, urgent). While the log cannot be
        # written, only urgent ones leave (heartbeats, stops, refusals, reads, unlogged feed events);
        # the others wait in _held until the records they acknowledge are in the log.
        self._out: list[tuple[zmq.Socket, list[bytes], bool]] = []
        self._held: list[tuple[zmq.Socket, list[bytes], bool]] = []
        #: Why the event log cannot be written now (None while it can): see _commit.
        self.storage_fault: str | None = None
        self._fault_since = 0.0
        # Routes whose connection went away (a send found no peer): nothing is pushed to them until
        # their session proves itself again there, so whoever takes such an id next gets nothing.
        self._unproven: set[bytes] = set()
        # True while the short path of _handle may serve a proved message (no unproven route, no
        # storage fault); otherwise every message takes _prove's full path.
        self._plain_turn = True
        # Refusals of connections without a session, counted per (type, code) and logged once a beat
        # (a flood of bad hellos must not flood the log and the referee's console).
        self._refused_anon: dict[tuple[str, str, Principal | None], list[Any]] = {}
        # Background work cut into slices of bounded size (position batches, position samples for the
        # log): the loop does one slice per turn and looks at its socket in between, so that a stop
        # never waits behind a whole batch of 10,000 robots.
        self._slices: deque[Callable[[], None]] = deque()
        self._urgent = False  # an urgent frame (a stop, its answer) is queued: send before handling more
        self.pose_period = 1.0 / pose_hz
        self._handlers: dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]] = {
            "hello": self._on_hello, "heartbeat": self._on_heartbeat, "bye": self._on_bye,
            "watch": self._on_watch, "robots": self._on_robots, "monitor": self._on_monitor,
            "tasks": self._on_tasks, "give": self._on_give, "stop": self._on_stop,
            "snapshot": self._on_snapshot, "register": self._on_register, "report": self._on_report,
            "reports": self._on_reports,
            "task.next": self._on_task_next, "task.done": self._on_task_done, "radio": self._on_radio,
            "leave": self._on_leave, "reply": self._on_host_reply, "arena": self._on_arena, "stats": self._on_stats,
            "hosts": self._on_hosts, "handover": self._on_handover,
        }
        log_path = self.state_dir / "events.log"
        # the log is opened after recovery (below); the desks reach it through the core
        self.maps = MapDesk(self, self, scenario)
        self.competition = Competition(self, self, self.match, self.state_dir, lambda: self.events)
        self.uploads = UploadDesk(self, self, self.state_dir, approve_uploads or scenario.approve_uploads)
        for desk in (self.competition, self.maps, self.uploads):
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
        self._zap = ZapHandler(self.ctx, self.curve.allowed if self.curve is not None else None,
                               self.tokens.lookup)
        _seed_routing_ids()
        self.router = self.ctx.socket(zmq.ROUTER)
        if self.curve is not None:
            secure_server(self.router, self.curve)
        else:
            secure_plain_server(self.router)
        self.router.setsockopt(zmq.LINGER, 0)
        self.router.setsockopt(zmq.MAXMSGSIZE, P.SOCKET_MAX_FRAME)
        # A second connection that presents a routing id in use is ignored by libzmq, never handed
        # the first one's messages (handover would give it the session's pushes and cut the owner off).
        self.router.setsockopt(zmq.ROUTER_HANDOVER, 0)
        # A send to a route with no connection fails (EHOSTUNREACH) instead of vanishing: the core
        # then stops pushing to that route until its session proves itself there again.
        self.router.setsockopt(zmq.ROUTER_MANDATORY, 1)
        # Dead connections (a cut cable) are dropped by ZMTP heartbeats, so that their ids free up.
        self.router.setsockopt(zmq.HEARTBEAT_IVL, int(max(1.0, self.heartbeat) * 2000))
        self.router.setsockopt(zmq.HEARTBEAT_TIMEOUT, int(max(1.0, self.heartbeat) * 10_000))
        # a connection that has not proved a credential within this time is closed by libzmq
        self.router.setsockopt(zmq.HANDSHAKE_IVL, int(HANDSHAKE_SECONDS * 1000))
        self.router.setsockopt(zmq.SNDHWM, 100_000)
        self.router.setsockopt(zmq.RCVHWM, 100_000)
        if self.port == 0:
            self.port = self.router.bind_to_random_port(f"tcp://{self.host}")
        else:
            self.router.bind(f"tcp://{self.host}:{self.port}")
        self._guard = ConnectionGuard.watch(self.router, self.port, self.limits, hold=True)
        self._zap.admit = self._admit
        self.pub = self.ctx.socket(zmq.PUB)
        self.pub.setsockopt(zmq.LINGER, 0)
        # A slow subscriber (a wall on a weak link) gets at most this many events queued for it,
        # then PUB drops for that subscriber only: bounded memory, and the core never waits.
        self.pub.setsockopt(zmq.SNDHWM, PUB_QUEUE)
        secure_server(self.pub, self.curve)
        self.pub.setsockopt(zmq.MAXMSGSIZE, 1024)  # subscriptions: a topic, a few bytes
        if self.pub_port == 0:
            self.pub_port = self.pub.bind_to_random_port(f"tcp://{self.host}")
        else:
            self.pub.bind(f"tcp://{self.host}:{self.pub_port}")
        self._pub_guard = ConnectionGuard.watch(self.pub, self.pub_port, self.limits, PUB_INBOUND)
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
                                         "arena": self._arena_payload})
        if self.recovered is not None:
            self.emit("core.recovered", None, self.recovered.to_dict())
        self._commit()

    def close(self) -> None:
        """Close the sockets and the log of a core that will not run (its start failed)."""
        for guard in (self._guard, self._pub_guard):
            if guard is not None:
                guard.close()
        for sock in (self.router, self.pub):
            if sock is not None:
                sock.close(0)
        self.router = self.pub = None
        if self._zap is not None:
            self._zap.close()
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
        if self._zap is not None:
            poller.register(self._zap.sock, zmq.POLLIN)
        for guard in (self._guard, self._pub_guard):
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
                if self.pending_stops or self.uploads.busy:
                    timeout = min(timeout, 0.05)
                if self.storage_fault is not None:  # try the log again soon: resume within a fraction of a second
                    timeout = min(timeout, 0.2)
                if self.match.posed:
                    timeout = min(timeout, max(0.0, next_pose - time.monotonic()))
                if self.match.contest.phase is Phase.RUNNING:
                    timeout = min(timeout, max(0.0, next_clock - time.monotonic()))
                if self._slices:  # background work left: look at the socket, then do the next slice
                    timeout = 0.0
                pub_guard = self._pub_guard
                # what each connection sent (PUB's subscribers) or holds (the ROUTER's), looked at often
                if (pub_guard is not None and pub_guard.sweeping) or (self._guard is not None and self._guard.sweeping):
                    timeout = min(timeout, SWEEP_SECONDS)
                if poller.poll(math.ceil(timeout * 1000)):
                    if self._guard is not None:  # connections counted before their handshakes are judged
                        self._guard.serve()
                    if pub_guard is not None:
                        pub_guard.serve()
                    if self._zap is not None:
                        self._zap.serve()
                    self._drain()
                    with contextlib.suppress(BlockingIOError):
                        wake.recv(4096)
                now = time.monotonic()
                if pub_guard is not None:
                    pub_guard.sweep(now)
                if self._guard is not None:
                    self._guard.sweep(now)
                if self.pending_stops:
                    self._expire_stops(now)
                if self.uploads.busy:
                    self.uploads.expire(now)
                if now >= next_pose:
                    self._queue_positions()
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
            for guard in (self._guard, self._pub_guard):
                if guard is not None:
                    guard.close()
            self.router.close(0)
            assert self.pub is not None
            self.pub.close(0)
            if self._zap is not None:  # after the servers: no handshake may find no handler
                self._zap.close()
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
            self._key_owner = owner if isinstance(owner, str) else None
            # the rest of the message as bytes (cheaper than a Frame per part)
            frames = [first.bytes, *router.recv_multipart()] if first.more else [first.bytes]
            if self._guard is not None:  # what this connection was handed, against what it sent (guard.py)
                self._guard.took(first, frames)
            self.stats["received"] += 1
            ident = frames[0]
            if len(frames) != 2:
                self._send_error(ident, 0, MalformedError(
                    f"expected exactly one frame per message, got {len(frames) - 1}"), None)
                continue
            self._handle(ident, frames[1])
            if self._urgent:  # a stop (or its answer) waits: send it before handling more
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
            if found is not None and self._plain_turn:
                try:
                    proved = _compare(secret, found.secret) and found.key == self._key_owner
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
        if self._key_owner != sess.key:
            if self.curve is not None:
                raise AuthError(f"this session was opened with {sess.key}'s CurveZMQ key; a frame sent with "
                                f"{self._key_owner}'s key does not belong to it")
            raise AuthError(f"this session was opened by a connection that presented {sess.key}'s token; a "
                            f"frame of a connection that presented {self._key_owner}'s does not belong to it")
        sess.last_seen = time.monotonic()
        if self._unproven:
            self._unproven.discard(ident)
            self._replan()
        return sess

    def _replan(self) -> None:
        """Whether _handle's short path may serve proved messages (see ``_plain_turn``)."""
        self._plain_turn = not self._unproven and self.storage_fault is None

    def _send_error(self, ident: bytes, req_id: int, err: RoboCompError, sess: Session | None,
                    msg_type: str = "?") -> None:
        self.stats["errors"] += 1
        self._reply(ident, P.error_reply(req_id, err))
        if self.storage_fault is not None:  # nothing more is logged until the log can be written
            return
        if sess is None or msg_type in P.NOTIFICATIONS:  # counted, and logged once a beat (see _log_refused)
            key = (msg_type, err.code, sess.who if sess is not None else None)
            row = self._refused_anon.get(key)
            if row is None:
                self._refused_anon[key] = [1, err.message]
            else:
                row[0] += 1
            return
        self.emit("refused", sess.who.team, {"by": sess.who.name, "type": msg_type,
                                             "code": err.code, "message": err.message}, public=False)

    def _log_refused(self) -> None:
        """One ``refused`` event per (type, code, sender) with its ``count`` for the refusals since
        the last beat of connections without a session and of notifications (a report refused ten
        times a second is one line a beat for the referee, not ten)."""
        rows, self._refused_anon = self._refused_anon, {}
        for (msg_type, code, who), (count, message) in sorted(rows.items(), key=lambda kv: (kv[0][0], kv[0][1])):
            self.emit("refused", who.team if who is not None else None, {
                "by": who.name if who is not None else "unknown", "type": msg_type, "code": code,
                "message": message, "count": count}, public=False)

    def _admit(self, principal: Any) -> str | None:
        """Asked by the ZAP handler about every principal that proved itself: None lets it in, a
        sentence refuses the handshake (the core is full but for the referee and hosts, or the
        principal holds its share of the sessions)."""
        assert self._guard is not None
        why = self._guard.admit(principal)
        if why is None and not isinstance(principal, str):
            why = self._sessions_full(principal)
        return why

    def _sessions_full(self, who: Principal) -> str | None:
        """A sentence when ``who`` holds its share of sessions (a quarter of the core's connections;
        the referee and hosts have no share), else None."""
        if who.role in ("referee", "host"):
            return None
        share = max(16, self.limits.total // 4)
        held = sum(1 for s in self.sessions.values() if s.who == who)
        if held >= share:
            return (f"{who.name} holds {held} sessions, its share of this core's {self.limits.total} connections; "
                    "close some (or say bye) before opening more")
        return None

    def _log_refused_handshakes(self) -> None:
        """One ``refused`` event (type ``connect``) and one log line per peer address whose
        handshakes the transport refused since the last beat (no valid token or key, ``E_AUTH``)
        or whose connections the guard cut (over a limit, ``E_RATE``), with their ``count``: a
        flood is logged in bulk."""
        rows: list[tuple[str, str, int, str]] = []
        if self._zap is not None:
            for (mechanism, address), row in sorted(self._zap.take_refused().items()):
                rows.append(("E_AUTH", address, row.count, f"{row.count} connection(s) from {address or 'an unknown address'} "
                             f"were refused ({mechanism}: {row.reason}); libzmq closed them before reading a message"))
        for guard in (self._guard, self._pub_guard):
            if guard is None:
                continue
            for address, cut in sorted(guard.take_cut().items()):
                rows.append(("E_RATE", address, cut.count, f"{cut.count} connection(s) from {address} were cut at "
                             f"once ({cut.reason}); the match goes on"))
        for code, address, count, message in rows:
            log.warning("%s", message)
            self.emit("refused", None, {"by": "unknown", "type": "connect", "code": code, "message": message,
                                        "count": count, "address": address}, public=False)

    # ------------------------------------------------------------------ output
    def send(self, ident: bytes, frame: bytes, urgent: bool = False) -> None:
        """Queue a frame for session ``ident`` (a push, or a reply that comes later); it leaves in
        :meth:`_commit`, after the log flush.

        A route whose connection went away gets nothing until its session proves itself there
        again (see :meth:`_prove`): whoever presents that routing id next gets no push."""
        if self._unproven and ident in self._unproven:
            self.stats["unrouted"] += 1
            return
        if urgent:
            self._urgent = True
        # the router exists once bound, and nothing is queued before: no None check on this hot path
        self._out.append((self.router, [ident, frame], urgent))  # type: ignore[arg-type]

    def _reply(self, ident: bytes, frame: bytes) -> None:
        """Queue the reply to the message that just came from ``ident`` (whoever sent it). During a
        storage fault it leaves at once: only requests that log nothing are served then."""
        self._out.append((self.router, [ident, frame], self.storage_fault is not None))  # type: ignore[arg-type]

    def _commit(self) -> None:
        """Flush the event log, then send every queued reply and event.

        Nothing is acknowledged before the events it caused were handed to the OS (and, with
        ``--fsync``, forced to disk): an acknowledged event survives ``kill -9`` of the core.
        """
        self._urgent = False
        self.match.contest.flush_score()
        try:
            self.events.flush()
        except StorageFault as fault:
            if self.storage_fault is None:
                self._storage_failed(fault)
            out = [entry for entry in self._out if entry[2]]
            self._held.extend(entry for entry in self._out if not entry[2])
            self._out = []
            if len(self._held) > HELD_FRAMES:  # bounded: the oldest pushes go (replies time out)
                self.stats["dropped"] += len(self._held) - HELD_FRAMES
                del self._held[:len(self._held) - HELD_FRAMES]
        else:
            if self.storage_fault is not None:
                self._storage_restored()
            out, self._held, self._out = self._held + self._out, [], []
        for sock, frames, _urgent in out:
            try:
                sock.send_multipart(frames, zmq.NOBLOCK)
            except zmq.Again:  # a peer's queue is full (slow consumer): drop, never block the loop
                self.stats["dropped"] += 1
            except zmq.ZMQError as e:
                if e.errno == zmq.EHOSTUNREACH and frames[0] in self.sessions:
                    # the session's connection is gone: whoever presents this id next must prove it
                    self._unproven.add(frames[0])
                    self._plain_turn = False
                log.debug("send failed: %s", e)

    # ------------------------------------------------------------------ events
    def _storage_failed(self, fault: StorageFault) -> None:
        """The log cannot be written: refuse what must be logged until it can (see _handle)."""
        self.storage_fault = (f"the core cannot write its event log ({fault}): until it can, it refuses what "
                              "would change the match (E_STORAGE); reads, stops and heartbeats go on. "
                              "Organiser: free space on the state folder's disk (or fix it); the core goes on "
                              "by itself")
        self._fault_since = time.monotonic()
        self._plain_turn = False
        self.stats["storage_faults"] = self.stats.get("storage_faults", 0) + 1
        log.error("%s", self.storage_fault)
        self.emit("core.storage", None, {"ok": False, "message": self.storage_fault, "errno": fault.errno},
                  log_it=False)

    def _storage_restored(self) -> None:
        seconds = time.monotonic() - self._fault_since
        self.storage_fault = None
        self._replan()
        log.warning("the event log is written again after %.1f s", seconds)
        self.emit("core.storage", None, {"ok": True, "seconds": round(seconds, 3),
                                         "message": f"the event log is written again (after {seconds:.1f} s)"})
        try:
            self.events.flush()  # the event above
        except StorageFault:
            pass  # full again at once: the next turn notices

    def emit(self, topic: str, team: str | None, data: dict[str, Any], *, public: bool = True,
             log_it: bool = True) -> None:
        """Log an event, publish its public view, and push it to watchers who may see it (an
        event that is not logged goes out even while the log cannot be written)."""
        self.stats["events"] += 1
        if log_it:
            self.events.append(topic, team, data)
        view = P.public_event(topic, data) if public else None  # the one table (protocol/topics.py)
        if view is not None and self.pub is not None:
            self._out.append((self.pub, [topic.encode(), P.pack(view)], not log_it))
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

    def _set_watch(self, s: Session, on: bool) -> None:
        s.watching = on
        group = self.watchers.setdefault(s.who.team, set())
        if on:
            group.add(s.ident)
        else:
            group.discard(s.ident)

    def _forget(self, ident: bytes) -> Session | None:
        s = self.sessions.pop(ident, None)
        if s is not None:
            self._set_watch(s, False)
        if self._unproven:
            self._unproven.discard(ident)
            self._replan()
        return s

    # ------------------------------------------------------------------ helpers
    def session(self, ident: bytes) -> Session:
        s = self.sessions.get(ident)
        if s is None:
            raise AuthError("say 'hello' with your team token first (the client does this for you)")
        return s

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

    def _check_known(self, ident: bytes) -> None:
        if ident not in self.sessions:
            raise AuthError("this connection is not known to the core (did the core restart?); "
                            "say hello and register your robots again")

    def hosted(self, ident: bytes, tag: int) -> RobotRecord:
        """The robot ``tag`` as reported by its host connection ``ident``."""
        self._check_known(ident)
        r = self.registry.robots.get(tag)
        if r is None or r.session != ident:
            raise NotYoursError(f"robot {tag} is not hosted by this connection; register it first")
        if r.status is not RobotStatus.CONNECTED:
            self.match.heard(r)
        return r

    # ------------------------------------------------------------------ the match's output (MatchOutput)
    def to_host(self, r: RobotRecord, type_: str, body: dict[str, Any], req_id: int = 0) -> None:
        """A directive to the host connection of robot ``r`` (a stop leaves at once, whatever the
        log's state: safety first)."""
        if r.session is not None:
            self.send(r.session, P.request(type_, req_id, body), type_ == "stop")

    def to_hosts(self, type_: str, body: dict[str, Any]) -> None:
        """A directive to every robot host connection (``hold``)."""
        frame = P.request(type_, 0, body)
        for ident in self.host_sessions():
            self.send(ident, frame)

    def finished(self) -> None:
        """The match has just finished: its results go into the state folder."""
        self.competition.write_results_now()

    def discovered(self, r: RobotRecord, find: dict[str, Any]) -> None:
        """A find was reported: the map service marks it for the team."""
        self.maps.discovery(r.tag, r.team, find["x"], find["y"], find["kind"], find["evidence"])

    def has_session(self, ident: bytes) -> bool:
        """Whether connection ``ident`` has a session."""
        return ident in self.sessions

    def new_request_id(self) -> int:
        """A fresh id for a request the core sends to a robot host (its reply comes as ``reply``)."""
        cid = self.next_core_req
        self.next_core_req += 1
        return cid

    def host_sessions(self) -> list[bytes]:
        """Routing ids of the connections that host robots."""
        return [ident for ident, s in self.sessions.items() if s.tags]

    # ------------------------------------------------------------------ timers
    def _queue_positions(self) -> None:
        """Queue the newest pose of every robot that reported since the last batch for publishing,
        in ``robot.positions`` events per team of at most :data:`POSE_CHUNK` robots, one per loop
        turn: however often robots report, subscribers get at most ``pose_hz`` positions per robot
        per second (conflation)."""
        posed, self.match.posed = self.match.posed, {}
        for team in sorted(posed):
            tags = sorted(posed[team])
            for k in range(0, len(tags), POSE_CHUNK):
                self._slices.append(partial(self._publish_chunk, team, tags[k:k + POSE_CHUNK]))

    def _publish_chunk(self, team: str, tags: list[int]) -> None:
        """One ``robot.positions`` event for robots ``tags`` of ``team``. A robot that was lost or
        left since it reported is left out: its ``robot.lost``/``robot.left`` went first."""
        batch = self.match.position_batch(team, tags)
        if batch is not None:
            self.emit("robot.positions", team, batch, log_it=False)

    def _publish_positions(self) -> None:
        """Publish every robot that reported since the last batch now (a replay's step)."""
        self._queue_positions()
        while self._slices:
            self._slices.popleft()()

    def _log_positions(self) -> None:
        """Queue the robots that moved since the last heartbeat for the log, as batched records of
        at most :data:`POSE_CHUNK` robots (the feed had a batch every pose period; the log keeps one
        sample per robot per beat)."""
        moved = self.match.moved
        if not moved or self.storage_fault is not None:  # samples: none kept while the log is down
            return
        tags = sorted(moved)
        moved.clear()
        for k in range(0, len(tags), POSE_CHUNK):
            self._slices.append(partial(self._log_chunk, tags[k:k + POSE_CHUNK]))

    def _log_chunk(self, tags: list[int]) -> None:
        if self.storage_fault is not None:
            return
        self.events.append("robot.positions", None, self.match.position_sample(tags))

    def _tick(self, now: float) -> None:
        """Heartbeats out, lost detection, idle sessions forgotten, the match clock, map deltas."""
        self._log_positions()
        if self._refused_anon:
            self._log_refused()
        self.match.tell_integrity()
        if ((self._zap is not None and self._zap.refusals_waiting) or (self._guard and self._guard.cuts_waiting)
                or (self._pub_guard and self._pub_guard.cuts_waiting)):
            self._log_refused_handshakes()
        self.maps.push()
        self.match.contest.tick()
        hb = P.request("heartbeat", 0, {"t": time.time(), "core_id": self.core_id})
        limit = 3 * self.heartbeat
        for ident, s in list(self.sessions.items()):
            silent = now - s.last_seen
            if s.tags:
                self.send(ident, hb, True)
                if silent > limit:
                    for tag in s.tags:
                        r = self.registry.robots[tag]
                        if r.session == ident:
                            self.match.lost(r, f"no message from its host for {silent:.1f} s")
            elif s.watching:
                self.send(ident, hb, True)
                if silent > max(SESSION_IDLE / 10, limit * 10):
                    self._set_watch(s, False)
            elif silent > SESSION_IDLE:
                self._forget(ident)

    def _expire_stops(self, now: float) -> None:
        for cid, p in list(self.pending_stops.items()):
            if now >= p.deadline:
                del self.pending_stops[cid]
                err = P.error_reply(p.req_id, TimeoutError_(
                    f"robot {p.tag} did not confirm the stop within {STOP_TIMEOUT:.0f} s; "
                    "its host may be lost (it halts on its own when it loses the core)"))
                self.send(p.ident, err, True)

    # ------------------------------------------------------------------ session requests
    def _check_key(self, who: Principal) -> None:
        """With CurveZMQ a team's key lets in that team only, the organiser's key the robot hosts
        (and the referee's key any role); with PLAIN, the token of the hello is the one the
        connection proved (the same principal)."""
        owner = self._key_owner
        if self.curve is not None:
            if who.role == "host":
                if owner not in (REFEREE, ORGANISER):
                    raise AuthError(f"this connection uses {owner}'s key; a robot host's token needs the "
                                    f"organiser's key ({ORGANISER}.key_secret)")
            elif owner not in (REFEREE, who.name):
                raise AuthError(f"this connection uses team {owner}'s key; {who.name}'s token needs {who.name}'s key")
        elif self._zap is None or self._zap.principals.get(owner or "") != who:
            raise AuthError(f"this connection proved {owner or 'nobody'} when it connected; say hello with "
                            "the same token the connection presented (the client does this for you)")

    def _on_hello(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.tokens.lookup(msg.body["token"])
        self._check_key(who)
        instance = msg.body.get("instance")
        if instance is not None and not P.INSTANCE_MIN <= len(instance) <= P.INSTANCE_MAX:
            raise FieldError(f"hello's 'instance' must be a random id of {P.INSTANCE_MIN} to {P.INSTANCE_MAX} "
                             "characters (robo_comp.protocol.new_instance_id), kept across reconnects")
        full = self._sessions_full(who) if ident not in self.sessions else None
        if full is not None:
            raise RateLimitError(full)
        old = self._forget(ident)  # only a proved hello gets here with a session (see _prove)
        sess = Session(ident, who, str(msg.body.get("client", "client"))[:64], time.monotonic(),
                       key=self._key_owner, instance=instance)
        if instance is not None:  # the same client again (a new connection): its old session ends now
            for other in [o for o in self.sessions.values() if o.instance == instance and o.who == who]:
                self._end_session(other, "its client said hello again on a new connection")
        self.sessions[ident] = sess
        if old is not None and old.who == who:
            sess.tags = old.tags
            self._set_watch(sess, old.watching)
        elif old is not None:  # the same program, now someone else: its robots are not the new one's
            self._release_robots(old, "its host's connection now speaks for someone else")
        return {"session": sess.secret, "role": who.role, "team": who.team, "protocol": P.PROTOCOL_VERSION,
                "core_id": self.core_id,
                "match": self.match.contest.state(),
                "pub_port": self.pub_port, "heartbeat": self.heartbeat, "teams": self.tokens.teams,
                "arena": {"name": self.scenario.name, "width": self._arena_payload["width"],
                          "height": self._arena_payload["height"]}}

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
            self._end_session(s, "its host said bye without leaving")
        return {}

    def _end_session(self, s: Session, why: str) -> None:
        """Forget session ``s`` (a bye, or its client's new hello); its robots are lost until they
        register again."""
        self._forget(s.ident)
        for tag in s.tags:
            r = self.registry.robots[tag]
            if r.session == s.ident:
                self.match.lost(r, why)

    def _on_watch(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.session(ident)
        self._set_watch(s, bool(msg.body.get("on", True)))
        return {"watching": s.watching}

    def _on_robots(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.session(ident)
        team = None if s.who.role == "referee" else s.who.team
        return {"robots": [r.summary() for r in self.registry.of_team(team)]}

    def _on_monitor(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        return self.robot_for(ident, msg.body["tag"]).monitor()

    def _on_tasks(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        r = self.robot_for(ident, msg.body["tag"])
        return {"tag": r.tag, "advertised": list(r.tasks.values()),
                "current": r.current.summary() if r.current else None,
                "pending": r.pending.summary() if r.pending else None,
                "queued": [t.summary() for t in r.queue], "done": [t.summary() for t in r.done]}

    def _on_arena(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        self.session(ident)
        return self._arena_payload

    def _on_stats(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        check_referee(self.session(ident).who, "read the core's counters")
        by_status: dict[str, int] = {}
        for r in self.registry.robots.values():
            by_status[r.status] = by_status.get(r.status, 0) + 1
        sessions_by: dict[str, int] = {}
        for s in self.sessions.values():
            sessions_by[s.who.name] = sessions_by.get(s.who.name, 0) + 1
        guard = self._guard
        return dict(self.stats, robots=by_status, sessions=len(self.sessions), sessions_by=sessions_by,
                    connections=guard.open if guard else 0, connections_cut=guard.cut_total if guard else 0,
                    connection_limit=self.limits.total,
                    log_seq=self.events.seq,
                    storage=self.storage_fault, log_unwritten=self.events.unwritten,
                    uptime=time.monotonic() - self.started,
                    recovered=self.recovered.to_dict() if self.recovered is not None else None)

    def _on_snapshot(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.session(ident)
        team = None if s.who.role == "referee" else s.who.team
        return dict(self.match.snapshot(team), arena=self._arena_payload, teams=self.tokens.teams,
                    seq=self.events.seq)

    def _on_give(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        s = self.session(ident)
        r = self.robot_for(ident, msg.body["tag"])
        return self.match.give(r, msg.body["task"], msg.body.get("args", []), bool(msg.body.get("queue", False)),
                               s.who.name)

    def _on_stop(self, ident: bytes, msg: P.Message) -> None:
        r = self.robot_for(ident, msg.body["tag"])
        self.match.contest.check_robot(r.tag)
        if r.status is not RobotStatus.CONNECTED or r.session is None:
            raise UnavailableError(
                f"robot {r.tag} is {r.status}; it halts by itself when it loses the core, and cannot be reached now")
        cid = self.new_request_id()
        now = time.monotonic()
        self.pending_stops[cid] = PendingStop(ident, msg.id, r.tag, now + STOP_TIMEOUT, now)
        self.to_host(r, "stop", {"tag": r.tag}, cid)
        return None  # the reply goes out when the robot confirms (see _on_host_reply)

    def _on_hosts(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        """The robot hosts (the referee's view): who, since when, last heard, which robots."""
        check_referee(self.session(ident).who, "list the robot hosts")
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
        who = self.session(ident).who
        check_referee(who, "hand robots over from one robot host to another")
        tags = msg.body["tags"]
        if not tags or len(tags) > 1000 or any(type(t) is not int for t in tags):
            raise FieldError("'tags' must be a list of 1 to 1000 robot tags")
        released = []
        for tag in tags:
            r = self.registry.get(tag)
            old = r.session
            if old is not None:  # the host halts the robot and lets it go (no separate stop)
                self.send(old, P.request("release", 0, {"tag": tag, "message":
                                                         "the referee handed this robot over to another host"}))
                if old in self.sessions:
                    self.sessions[old].tags.discard(tag)
            self.match.handed_over(r, who.name, old.hex() if old else None)
            released.append(tag)
        return {"released": released}

    # ------------------------------------------------------------------ robot-host requests
    def _on_register(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        who = self.tokens.lookup(b["token"])
        team = who.team
        if who.role != "host" or team is None:
            raise ForbiddenError(
                "robots register only through the organiser's robot host, with a host token "
                "(STATE/hosts/<team>.token); a team's token gives its robots commands but never speaks "
                "for the world (see docs/security.md, 'Who runs what')")
        self._check_key(who)
        robot_id = b["robot_id"]
        sess = self.sessions.get(ident)
        if sess is not None and sess.who != who:
            raise AuthError(f"this connection's session speaks for {sess.who.name}; robots of "
                            f"{who.name} register on a connection of their own")
        r = self.match.admit(team, robot_id, b)  # the scenario's robots, a free start: the match's rules
        if (r is not None and r.session is not None and r.session != ident and r.session in self.sessions
                and r.status is RobotStatus.CONNECTED):
            holder = self.sessions[r.session]
            raise HeldError(
                f"robot {robot_id!r} (tag {r.tag}) of team {team} is held by another robot host (connected "
                f"since {time.strftime('%H:%M:%S', time.localtime(holder.opened))}, {len(holder.tags)} robots, "
                f"heard {time.monotonic() - holder.last_seen:.1f} s ago) and was not taken from it. Stop that "
                f"host first (its robots are lost after {3 * self.heartbeat:g} s without it, and then this "
                f"host takes them), or ask the referee: 'robo-comp ctl hosts' lists the hosts, "
                f"'robo-comp ctl handover {r.tag}' hands the robot to the next host that registers it")
        if sess is None:
            full = self._sessions_full(who)
            if full is not None:
                raise RateLimitError(full)
            sess = Session(ident, who, "robots", time.monotonic(), key=self._key_owner)
            self.sessions[ident] = sess
        if r is not None and r.session is not None and r.session != ident and r.session in self.sessions:
            self.sessions[r.session].tags.discard(r.tag)
        reply = self.match.register(team, robot_id, ident, b)
        sess.tags.add(reply["tag"])
        return dict(reply, session=sess.secret, heartbeat=self.heartbeat)

    def _on_report(self, ident: bytes, msg: P.Message) -> None:
        """One robot's pose (a row of the match's ``take_rows``, without its loop)."""
        b = msg.body
        r = self.hosted(ident, b["tag"])
        self.match.report(r, b["x"], b["y"], b["heading"], b.get("moving", False), b.get("sensors"))
        return None

    def _on_reports(self, ident: bytes, msg: P.Message) -> None:
        """Many robots of one host in one message (a host reports its robots in batches): the rows of
        the match's ``take_rows``."""
        b = msg.body
        n = P.check_reports(b)
        self._check_known(ident)
        team = self.sessions[ident].who.team
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
        t = self.match.task_next(self.hosted(ident, msg.body["tag"]))
        return {"task": t.wire() if t is not None else None}

    def _on_task_done(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        return self.match.task_done(self.hosted(ident, msg.body["tag"]), msg.body)

    def _on_radio(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        r = self.hosted(ident, b["tag"])
        return {"delivered": self.match.radio(r, b.get("to"), b["data"])}

    def _on_leave(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        r = self.hosted(ident, msg.body["tag"])
        self.match.leave(r)
        self.sessions[ident].tags.discard(r.tag)
        return {}

    def _on_host_reply(self, ident: bytes, msg: P.Message) -> None:
        raw = msg.body
        p = self.pending_stops.get(msg.id)
        if p is None:
            self.uploads.host_reply(ident, msg.id, raw)
            return None  # an upload's answer, or a late answer to a stop that already timed out
        r = self.registry.robots[p.tag]
        if r.session != ident:  # request ids are easy to guess: only the robot's own host confirms
            raise NotYoursError(f"this connection does not host robot {p.tag}; its stop is not yours to confirm")
        del self.pending_stops[msg.id]
        err, body = raw.get("error"), raw.get("body")
        if not isinstance(err, (dict, type(None))) or not isinstance(body, (dict, type(None))):
            self.send(p.ident, P.error_reply(p.req_id, RoboCompError(
                f"robot {p.tag}'s host answered the stop with a malformed reply; it may not have halted")), True)
            raise FieldError("a reply's 'error' and 'body' must be maps")
        if not raw.get("ok"):
            err = err or {}
            self.send(p.ident, P.error_reply(p.req_id, RoboCompError(
                f"robot {p.tag} could not stop: {err.get('message', 'no reason given')}")), True)
            return None
        ms = (time.monotonic() - p.t0) * 1000
        cancelled = self.match.stopped(r, body or {}, ms)
        self.send(p.ident, P.ok_reply(p.req_id, {  # a stop is answered at once, even during a storage fault
            "tag": r.tag, "x": r.x, "y": r.y, "heading": r.heading, "cancelled": cancelled, "ms": ms}), True)
        return None


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
