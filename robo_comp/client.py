"""The public Python client: talk to a core as a team, the referee, a wall or a script.

    from robo_comp.client import Client
    with Client("tcp://127.0.0.1:5555", token) as c:
        for row in c.robots():
            print(row["tag"], row["status"])
        c.give(101, "goTo", [3, 4])
        c.stop(101)

Replies come back as plain dicts; error replies raise the matching
:class:`robo_comp.errors.RoboCompError` subclass, whose ``code`` is the protocol's.
"""
from __future__ import annotations

import argparse
import json
import time
from collections import deque
from pathlib import Path
from typing import Any, TypeVar
from urllib.parse import urlparse

import zmq

from robo_comp import protocol as P
from robo_comp.protocol.curve import (
    HANDSHAKE_EVENTS,
    client_keys,
    handshake_error,
    secure_client,
    secure_plain_client,
)
from robo_comp.errors import ConnectionLostError, FieldError, TimeoutError_
from robo_comp.protocol.replies import reply_body
from robo_comp.protocol.session import ClientSession


def resolve_core(core: str) -> str:
    """Turn ``--core`` into a ROUTER URL: a URL as is, a state folder / ``core.json`` path, or
    ``mdns:NAME``, a core advertised on the LAN (:mod:`robo_comp.discovery`)."""
    if "://" in core:
        return core
    if core.startswith("mdns:"):
        from robo_comp.discovery import resolve

        return resolve(core[len("mdns:"):])
    path = Path(core)
    if path.is_dir():
        path = path / "core.json"
    if not path.is_file():
        raise FieldError(f"--core {core!r} is neither a URL like tcp://HOST:PORT nor a core state folder")
    try:
        return json.loads(path.read_text())["router"]
    except (ValueError, KeyError):
        raise FieldError(f"{path} is not a core.json written by 'robo-comp core'") from None


def read_token(token: str | None, token_file: str | None) -> str:
    """The token given directly or read from a token file."""
    if token:
        return token.strip()
    if token_file:
        try:
            return Path(token_file).read_text().strip()
        except OSError as e:
            raise FieldError(f"cannot read the token file {token_file}: {e.strerror}") from None
    raise FieldError("give a token with --token T or --token-file PATH")


def pub_url(router_url: str, pub_port: int) -> str:
    """The PUB URL on the same host as the ROUTER URL the client used."""
    host = urlparse(router_url).hostname or "127.0.0.1"
    if ":" in host:
        host = f"[{host}]"
    return f"tcp://{host}:{pub_port}"



#: The socket class of a context: a plain one's, or an asyncio one's (the consoles').
SocketT = TypeVar("SocketT", bound=zmq.Socket)


def open_dealer(ctx: zmq.Context[SocketT], url: str, curve: Any = None, token: str | None = None, *,
                connect: bool = True, **options: int) -> SocketT:
    """A DEALER socket connected to the core at ``url`` with a fresh random routing id (see
    :func:`robo_comp.protocol.new_routing_id`), its credential for the transport (CurveZMQ keys
    when given, else ``token`` as the PLAIN password: the core lets in no connection without
    one), and ``options`` (socket option -> value); what every client of the project connects with.
    With ``connect=False`` the caller connects it (after setting up a monitor, say)."""
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.ROUTING_ID, P.new_routing_id())
    for opt, value in options.items():
        sock.setsockopt(getattr(zmq, opt), value)
    if curve is not None:
        secure_client(sock, curve)
    else:
        secure_plain_client(sock, token)
    if connect:
        sock.connect(url)
    return sock



class Client:
    """A DEALER connection to the core that has said hello with a token.

    For a core run with ``--curve``, ``curve_cert`` is this client's secret certificate and
    ``core_key`` the core's public one (see :func:`robo_comp.protocol.curve.client_keys` for the
    defaults: ``$ROBO_COMP_CURVE_CERT``/``$ROBO_COMP_CORE_KEY``, or the state folder's keys).
    """

    def __init__(self, core: str, token: str, *, client: str = "client", timeout: float = 5.0,
                 ctx: zmq.Context | None = None, curve_cert: str | Path | None = None,
                 core_key: str | Path | None = None) -> None:
        self.url = resolve_core(core)
        #: CurveZMQ keys of every socket this client opens (None: plain TCP).
        self.curve = client_keys(core, token, curve_cert, core_key)
        self.token = token
        self.client_name = client
        self.timeout = timeout
        self.ctx = ctx or zmq.Context.instance()
        self.sock: zmq.Socket | None = None
        #: The session with the core (protocol/session.py): hello, the secret, heartbeats.
        self.s = ClientSession(token, client)
        self.events: deque[dict[str, Any]] = deque(maxlen=10_000)
        self._asked: dict[int, dict[str, Any] | None] = {}  # request id sent with ask() -> its reply
        self._watching = False
        self.connect()

    @property
    def info(self) -> dict[str, Any]:
        """The core's hello reply (role, team, heartbeat, the match, ...)."""
        return self.s.info

    @property
    def session(self) -> str | None:
        """The session secret the core gave at hello; every later message carries it."""
        return self.s.secret

    # ------------------------------------------------------------------ connection
    def connect(self) -> dict[str, Any]:
        """(Re)open the socket and say hello; returns the core's hello reply."""
        if self.sock is not None:
            self.sock.close(0)
        self._asked = {}  # what was asked on the old socket is not answered on the new one
        self.sock = open_dealer(self.ctx, self.url, self.curve, self.token, connect=False)
        try:
            self._handshake()
            self.s.opened(self._call("hello", *self.s.hello(time.monotonic())))
        except TimeoutError_ as e:  # a refused CurveZMQ handshake looks the same: say so
            hint = ("If it runs with --curve, give --curve-cert and --core-key." if self.curve is None else
                    "With CurveZMQ, check that --curve-cert is the secret certificate the organiser gave "
                    "you and --core-key is this core's core.key.")
            raise TimeoutError_(f"{e.message} {hint}") from None
        if self._watching:
            self.request("watch", on=True)
        return self.info

    def _handshake(self) -> None:
        """Connect the new socket and wait (up to the timeout) for the transport's handshake: a
        refused token or key raises :class:`AuthError` at once instead of a silent timeout."""
        assert self.sock is not None
        mon = self.sock.get_monitor_socket(HANDSHAKE_EVENTS)
        try:
            self.sock.connect(self.url)
            deadline = time.monotonic() + self.timeout
            while (left := deadline - time.monotonic()) > 0 and mon.poll(int(left * 1000)):
                err = handshake_error(mon.recv_multipart(), self.curve is not None)
                if err is not None:
                    self.sock.close(0)
                    self.sock = None
                    raise err
                return  # in: the hello follows
            raise TimeoutError_(f"the core at {self.url} did not complete a connection within "
                                f"{self.timeout:.1f} s; is it running?")
        finally:
            if self.sock is not None:
                self.sock.disable_monitor()
            mon.close(0)

    def close(self) -> None:
        """Say bye (best effort) and close the socket."""
        if self.sock is not None:
            try:
                self.sock.send(self.s.bye(), zmq.NOBLOCK)
            except zmq.ZMQError:
                pass
            self.sock.close(0)
            self.sock = None

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def role(self) -> str:
        """``team`` or ``referee``."""
        return self.info.get("role", "")

    @property
    def team(self) -> str | None:
        """The team this client speaks for (None for the referee)."""
        return self.info.get("team")

    # ------------------------------------------------------------------ requests
    def request(self, type_: str, **body: Any) -> dict[str, Any]:
        """Send one request and wait for its reply; raise the matching error on an error reply."""
        return self._call(type_, *self.s.frame(type_, body, time.monotonic()))

    def _call(self, type_: str, rid: int, frame: bytes) -> dict[str, Any]:
        """Send request ``rid`` (``frame``) and wait for its reply."""
        assert self.sock is not None, "client is closed"
        self.sock.send(frame)
        deadline = time.monotonic() + self.timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not self.sock.poll(int(left * 1000)):
                raise TimeoutError_(
                    f"the core at {self.url} did not answer {type_!r} within {self.timeout:.1f} s; is it running?")
            msg = P.unpack(self.sock.recv())
            if msg.get("type") == "reply" and msg.get("id") in (rid, 0):
                return reply_body(msg)
            self._keep(msg)

    def _keep(self, msg: dict[str, Any]) -> None:
        if msg.get("type") == "event":
            self.events.append(msg.get("body") or {})
        elif msg.get("type") == "reply" and msg.get("id") in self._asked:
            self._asked[msg["id"]] = msg

    def ask(self, type_: str, **body: Any) -> int:
        """Send a request without waiting (for loops that must not block, like the wall's
        frames); return its id for :meth:`answer`."""
        assert self.sock is not None, "client is closed"
        rid, frame = self.s.frame(type_, body, time.monotonic())
        self.sock.send(frame)
        self._asked[rid] = None
        return rid

    def answer(self, rid: int) -> dict[str, Any] | None:
        """The reply body of request ``rid`` sent with :meth:`ask` if it has come (raising the
        matching error on an error reply), else None. Never waits."""
        assert self.sock is not None, "client is closed"
        while self._asked.get(rid) is None and self.sock.poll(0):
            self._keep(P.unpack(self.sock.recv()))
        msg = self._asked.get(rid)
        if msg is None:
            return None
        del self._asked[rid]
        return reply_body(msg)

    def forget(self, rid: int) -> None:
        """Stop waiting for request ``rid`` (a late reply is dropped)."""
        self._asked.pop(rid, None)

    def robots(self) -> list[dict[str, Any]]:
        """The robots this client may see (its team's; all for the referee)."""
        return self.request("robots")["robots"]

    def monitor(self, tag: int) -> dict[str, Any]:
        """All monitor data of robot ``tag``."""
        return self.request("monitor", tag=tag)

    def tasks(self, tag: int) -> dict[str, Any]:
        """Advertised, current, queued and done tasks of robot ``tag``."""
        return self.request("tasks", tag=tag)

    def give(self, tag: int, task: str, args: list[Any] | None = None, queue: bool = False) -> dict[str, Any]:
        """Give a task now (interrupting the current one at its next movement boundary) or queue it."""
        return self.request("give", tag=tag, task=task, args=list(args or []), queue=queue)

    def stop(self, tag: int) -> dict[str, Any]:
        """Halt robot ``tag`` at once; its current and queued tasks are cancelled; it stays usable."""
        return self.request("stop", tag=tag)

    def upload(self, tags: list[int], filename: str, source: str, run: bool = False) -> dict[str, Any]:
        """Send a module to robots ``tags``: checked and loaded there (``results`` per robot), or an
        ``UploadError`` naming file, line and rule when every robot refused it."""
        return self.request("upload", tags=list(tags), filename=filename, source=source, run=run)

    def extensions(self, tag: int) -> list[dict[str, Any]]:
        """The uploaded modules robot ``tag`` has (name, version, kind, file, sha256, tasks)."""
        return self.request("extensions", tag=tag)["modules"]

    def unload(self, tags: list[int], name: str) -> dict[str, Any]:
        """Take the module ``name`` away from robots ``tags``."""
        return self.request("unload", tags=list(tags), name=name)

    def sandbox_reset(self, tags: list[int]) -> dict[str, Any]:
        """Referee: restart the team-code sandbox on these robots' hosts now (ends a cool-down
        after too many limit kills); ``results`` says per robot whether it was resting."""
        return self.request("sandbox.reset", tags=list(tags))

    def match(self, action: str, seconds: float | None = None, rule: str | None = None) -> dict[str, Any]:
        """Referee: ``start``, ``pause``, ``resume``, ``finish`` or ``extend`` (by ``seconds``);
        ``outage`` with ``rule`` ``pause`` or ``count``: what a core outage does to the clock."""
        body: dict[str, Any] = {"action": action}
        if seconds is not None:
            body["seconds"] = seconds
        if rule is not None:
            body["rule"] = rule
        return self.request("match", **body)

    def score(self) -> dict[str, Any]:
        """The scoreboard, the phase and the clock; the score lines this client may see."""
        return self.request("score")

    def snapshot(self) -> dict[str, Any]:
        """Arena, teams and visible robots in one reply (walls and consoles start from this)."""
        return self.request("snapshot")

    def arena(self) -> dict[str, Any]:
        """The arena payload (walls: :func:`robo_comp.protocol.unpack_walls`)."""
        return self.request("arena")

    # ------------------------------------------------------------------ events
    def watch(self, on: bool = True) -> None:
        """Ask the core to push this client's events (its team's, or all for the referee)."""
        self.request("watch", on=on)
        self._watching = on

    def next_event(self, timeout: float = 1.0) -> dict[str, Any] | None:
        """The next pushed event (``{"topic", "team", "data"}``), or None after ``timeout`` seconds."""
        assert self.sock is not None, "client is closed"
        deadline = time.monotonic() + timeout
        while not self.events:
            now = time.monotonic()
            if self.s.beat_due(now):
                self.sock.send(self.s.frame("heartbeat", {}, now, rid=0)[1])
            left = deadline - now
            if left <= 0:
                return None
            if self.sock.poll(int(min(left, self.s.heartbeat) * 1000)):
                self._keep(P.unpack(self.sock.recv()))
        return self.events.popleft()

    def subscribe(self, *topics: str) -> zmq.Socket:
        """A SUB socket on the core's public event feed (all topics if none are given)."""
        sub = self.ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        secure_client(sub, self.curve)
        sub.connect(pub_url(self.url, self.info["pub_port"]))
        for t in topics or ("",):
            sub.setsockopt(zmq.SUBSCRIBE, t.encode())
        return sub


def recv_event(sub: zmq.Socket) -> tuple[str, dict[str, Any]]:
    """Read one ``(topic, payload)`` from a SUB socket made by :meth:`Client.subscribe`."""
    topic, payload = sub.recv_multipart()
    return topic.decode(), P.unpack(payload)


def add_connection_args(p: argparse.ArgumentParser, required: bool = True) -> None:
    """``--core``, ``--token``/``--token-file`` and the CurveZMQ ``--curve-cert``/``--core-key``,
    shared by every client command (``required=False`` where another source may replace the core,
    as the wall's ``--replay``)."""
    from robo_comp.protocol.curve import add_curve_args

    p.add_argument("--core", required=required,
                   help="ROUTER URL (tcp://HOST:PORT), the core's state folder, or mdns:NAME (a core started "
                        "with --advertise NAME on this LAN)")
    tok = p.add_mutually_exclusive_group(required=required)
    tok.add_argument("--token", help="team or referee token")
    tok.add_argument("--token-file", help="file holding the token")
    add_curve_args(p)



__all__ = ["Client", "ConnectionLostError", "open_dealer", "read_token", "recv_event", "resolve_core"]
