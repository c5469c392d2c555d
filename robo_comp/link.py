"""The consoles' link to the core: one asyncio DEALER socket, many requests in flight.

The public :class:`robo_comp.client.Client` waits for each reply, which a console cannot do:
its screen must keep drawing and STOP must leave at once while an upload or another request is
still waiting for its answer. :class:`CoreLink` therefore keeps one ``zmq.asyncio`` DEALER
socket, numbers its requests, parks a future per request id and lets a single reader task
hand replies to their futures and pushed events to the console. Nothing ever waits behind
anything else: :meth:`CoreLink.request` sends at once and awaits only its own reply.

The link watches the core's heartbeats. When the core goes silent (it crashed or restarted)
or forgets the session (``E_AUTH``), the link says so, opens a fresh socket (re-reading
``core.json`` when ``--core`` named a state folder, so a new port is found), says hello again,
asks for events again and says it is back. The console shows each change of
:class:`LinkState`.
"""
from __future__ import annotations

import asyncio
import contextlib
import enum
import logging
import time
from collections.abc import Callable
from typing import Any

import zmq
import zmq.asyncio

from robo_comp.client import open_dealer, resolve_core
from robo_comp import protocol as P
from robo_comp.protocol.curve import HANDSHAKE_EVENTS, client_keys, handshake_error
from robo_comp.protocol.replies import reply_body, reply_error
from robo_comp.protocol.session import ClientSession
from robo_comp.errors import (
    ConnectionLostError,
    RoboCompError,
    TimeoutError_,
)

log = logging.getLogger("robo_comp.tui")

#: How long a request waits for its reply before it fails with ``E_TIMEOUT``.
REQUEST_TIMEOUT = 5.0
#: How long a hello may take before the core counts as unreachable.
HELLO_TIMEOUT = 1.5
#: Silence (in heartbeats, and at least this many seconds) after which the core counts as lost.
SILENT_BEATS = 5
MIN_SILENCE = 2.0


class LinkState(enum.Enum):
    """Where the link stands; every change is reported to the console."""

    CONNECTING = "connecting"
    CONNECTED = "connected"
    RECONNECTING = "reconnecting"
    CLOSED = "closed"


EventSink = Callable[[str, "str | None", dict[str, Any]], None]
StateSink = Callable[[LinkState, str, dict[str, Any]], None]


class CoreLink:
    """An asynchronous session with the core for a console.

    ``on_event(topic, team, data)`` is called for every pushed event and
    ``on_state(state, detail, hello_reply)`` for every change of :class:`LinkState`; both are
    called from the event loop (a Textual app passes functions that post messages).

    ``curve_cert``/``core_key`` are the CurveZMQ certificates for a core run with ``--curve``
    (defaults as in :func:`robo_comp.protocol.curve.client_keys`, read again at every reconnect).
    """

    def __init__(self, core: str, token: str, *, client: str = "console",
                 on_event: EventSink | None = None, on_state: StateSink | None = None,
                 ctx: zmq.asyncio.Context | None = None, curve_cert: str | None = None,
                 core_key: str | None = None) -> None:
        self.core = core
        self.token = token
        self.curve_cert = curve_cert
        self.core_key = core_key
        self.client_name = client
        self.on_event: EventSink = on_event or (lambda *_: None)
        self.on_state: StateSink = on_state or (lambda *_: None)
        self.ctx = ctx or zmq.asyncio.Context.instance()
        self.sock: zmq.asyncio.Socket | None = None
        self.url = ""
        #: The session with the core (protocol/session.py): hello, the secret, heartbeats.
        self.s = ClientSession(token, client)
        self.state = LinkState.CLOSED
        self.reconnects = 0
        self._pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self._task: asyncio.Task[None] | None = None
        self._lost = asyncio.Event()
        self._closing = False

    # ------------------------------------------------------------------ public
    @property
    def info(self) -> dict[str, Any]:
        """The core's hello reply (role, team, heartbeat, the match, ...)."""
        return self.s.info

    @property
    def session(self) -> str | None:
        """The session secret of the current connection (from the hello reply)."""
        return self.s.secret

    @property
    def connected(self) -> bool:
        """True while a session with the core is up."""
        return self.state is LinkState.CONNECTED

    @property
    def role(self) -> str:
        """``team`` or ``referee`` (empty before the first hello)."""
        return self.info.get("role", "")

    @property
    def team(self) -> str | None:
        """The team this console speaks for (None for the referee)."""
        return self.info.get("team")

    @property
    def heartbeat(self) -> float:
        """The core's heartbeat interval in seconds."""
        return self.s.heartbeat

    def start(self) -> None:
        """Start connecting in the background (call from inside the running event loop)."""
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._run(), name="core-link")

    async def close(self) -> None:
        """Say bye, stop the background task and close the socket."""
        self._closing = True
        if self.sock is not None and self.connected:
            with contextlib.suppress(zmq.ZMQError):
                await self.sock.send(self.s.bye(), zmq.NOBLOCK)
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
            self._task = None
        self._drop_socket(ConnectionLostError("the console closed its connection"))
        self._set_state(LinkState.CLOSED, "closed")

    async def request(self, type_: str, *, timeout: float = REQUEST_TIMEOUT, **body: Any) -> dict[str, Any]:
        """Send one request now and await its own reply; raise the matching error on refusal.

        Other requests may be in flight at the same time; this one is never queued behind them.
        """
        if self.sock is None or not self.connected:
            raise ConnectionLostError("not connected to the core; the console is reconnecting")
        rid, frame = self.s.frame(type_, body, time.monotonic())
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self._pending[rid] = fut
        try:
            await self.sock.send(frame)
            return await asyncio.wait_for(fut, timeout)
        except asyncio.TimeoutError:
            raise TimeoutError_(
                f"the core did not answer {type_!r} within {timeout:.0f} s") from None
        except zmq.ZMQError as e:
            log.debug("send of %r failed: %s", type_, e)
            raise ConnectionLostError(f"could not send {type_!r}: the connection to the core is down; "
                                      "the console reconnects on its own") from None
        finally:
            self._pending.pop(rid, None)

    async def available(self, type_: str) -> bool:
        """Feature detection: does this core know request ``type_``?

        Sends ``type_`` with an empty body: a core that knows the type refuses the missing
        fields (or answers); one that does not answers ``E_UNKNOWN_TYPE``.
        """
        try:
            await self.request(type_)
        except RoboCompError as e:
            return e.code != "E_UNKNOWN_TYPE"
        return True

    # ------------------------------------------------------------------ internals
    def _set_state(self, state: LinkState, detail: str) -> None:
        if state is self.state and state is not LinkState.CONNECTED:
            return
        self.state = state
        try:
            self.on_state(state, detail, dict(self.info))
        except Exception:  # a console's callback must never kill the link
            log.exception("state callback failed")

    def _drop_socket(self, err: RoboCompError) -> None:
        for fut in self._pending.values():
            if not fut.done():
                fut.set_exception(err)
        self._pending.clear()
        if self.sock is not None:
            self.sock.close(0)
            self.sock = None

    async def _hello(self) -> dict[str, Any]:
        """Open a fresh socket and say hello; raise when the core does not answer in time."""
        self._drop_socket(ConnectionLostError("the connection to the core was replaced"))
        self.url = resolve_core(self.core)
        keys = client_keys(self.core, self.token, self.curve_cert, self.core_key)
        sock = open_dealer(self.ctx, self.url, keys, self.token, connect=False)
        self.sock = sock
        await self._handshake(sock, keys is not None)
        rid, frame = self.s.hello(time.monotonic())  # a new connection opens a new session
        await sock.send(frame)
        t_end = time.monotonic() + HELLO_TIMEOUT
        while True:
            left = t_end - time.monotonic()
            if left <= 0 or not await sock.poll(left * 1000):
                raise TimeoutError_(f"the core at {self.url} does not answer")
            msg = P.unpack(await sock.recv())
            if msg.get("type") == "reply" and msg.get("id") in (rid, 0):
                body = reply_body(msg)
                self.s.opened(body)
                return body

    async def _handshake(self, sock: zmq.asyncio.Socket, curve: bool) -> None:
        """Connect ``sock`` and wait for the transport's handshake: a refused token or key raises
        :class:`AuthError` (shown, and retried slowly) instead of a silent timeout."""
        mon = sock.get_monitor_socket(HANDSHAKE_EVENTS)
        try:
            sock.connect(self.url)
            t_end = time.monotonic() + HELLO_TIMEOUT
            while (left := t_end - time.monotonic()) > 0 and await mon.poll(left * 1000):
                err = handshake_error(await mon.recv_multipart(), curve)
                if err is not None:
                    raise err
                return
            raise TimeoutError_(f"the core at {self.url} does not answer")
        finally:
            with contextlib.suppress(zmq.ZMQError):
                sock.disable_monitor()
            mon.close(0)

    async def _run(self) -> None:
        """Connect, serve, and reconnect whenever the core goes away; until :meth:`close`."""
        delay = 0.2
        first = True
        while not self._closing:
            self._set_state(LinkState.CONNECTING if first else LinkState.RECONNECTING,
                            "connecting to the core…" if first else "reconnecting to the core…")
            try:
                await self._hello()
            except (RoboCompError, zmq.ZMQError, OSError) as e:
                msg = e.message if isinstance(e, RoboCompError) else str(e)
                if isinstance(e, RoboCompError) and e.code in ("E_AUTH", "E_FORBIDDEN"):
                    # a wrong token will not get better by retrying fast
                    self._set_state(LinkState.CLOSED, msg)
                    delay = 5.0
                log.debug("hello failed: %s", msg)
                await asyncio.sleep(delay)
                delay = min(delay * 1.5, 2.0)
                continue
            delay = 0.2
            self._lost.clear()
            reader = asyncio.get_running_loop().create_task(self._read(), name="core-link-reader")
            self.state = LinkState.CONNECTING  # so that CONNECTED is always reported
            self._set_state(LinkState.CONNECTED, "connected" if first else "reconnected")
            try:
                await self.request("watch", on=True)
            except RoboCompError as e:
                log.debug("watch failed: %s", e.message)
                self._lost.set()
            if not first:
                self.reconnects += 1
            first = False
            try:
                await self._keepalive()
            finally:
                reader.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await reader
            if self._closing:
                break
            self._drop_socket(ConnectionLostError("lost the connection to the core; reconnecting"))

    async def _keepalive(self) -> None:
        """Send heartbeats and notice silence, until the session is lost."""
        while not self._closing:
            hb = self.heartbeat
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._lost.wait(), min(hb, 0.5))
            if self._lost.is_set():
                return
            now = time.monotonic()
            if self.s.silent(now, MIN_SILENCE, SILENT_BEATS):
                log.info("the core is silent for %.1f s", now - self.s.last_rx)
                return
            if self.s.beat_due(now) and self.sock is not None:
                try:
                    await self.sock.send(self.s.frame("heartbeat", {}, now, rid=0)[1], zmq.NOBLOCK)
                except zmq.ZMQError:
                    return

    async def _read(self) -> None:
        """Hand replies to their futures and events to the console."""
        sock = self.sock
        assert sock is not None
        while True:
            try:
                frame = await sock.recv()
            except zmq.ZMQError:
                self._lost.set()
                return
            try:
                msg = P.unpack(frame)
            except Exception:
                continue
            if not isinstance(msg, dict):
                continue
            if self.s.heard(msg, time.monotonic()) is not None:  # the core forgot us or restarted
                self._lost.set()
            kind = msg.get("type")
            if kind == "reply":
                self._on_reply(msg)
            elif kind == "event":
                body = msg.get("body") or {}
                topic = str(body.get("topic", ""))
                try:
                    self.on_event(topic, body.get("team"), body.get("data") or {})
                except Exception:
                    log.exception("event callback failed on %s", topic)
                if topic == "core.started":
                    self._lost.set()  # a new core process: our session is gone
                    return

    def _on_reply(self, msg: dict[str, Any]) -> None:
        rid = msg.get("id")
        fut = self._pending.get(rid) if isinstance(rid, int) else None
        exc = reply_error(msg)
        if exc is None:
            if fut is not None and not fut.done():
                fut.set_result(msg.get("body") or {})
            return
        if fut is not None and not fut.done():
            fut.set_exception(exc)


__all__ = ["CoreLink", "LinkState"]
