"""How a view's messages reach the browsers: each message framed once, the same bytes for all.

A WebSocket message from server to browser is never masked, so the frame (a header of 2 to 10
bytes, then the UTF-8 text) is the same for every browser of a view: :class:`Frame` builds it
once and every browser's :class:`Wire` writes those bytes to its socket. Over the ASGI interface a
server would frame the text again for every browser (and the gateway would need a task per
browser to await each send): with 1,000 browsers that was most of the gateway's time.

* :class:`WireProtocol` is uvicorn's WebSocket protocol (the ``websockets`` sans-I/O one) that
  also offers the app an ASGI extension, ``robo_comp.wire`` in the connection's scope: a
  :class:`TransportWire` that writes whole frames straight to the connection's transport, and
  says when that transport's buffer is full (the browser does not read as fast as the match goes).
* :class:`AsgiWire` is the same interface over the plain ASGI ``send`` (one message at a time),
  for a server without the extension.
* :func:`config` is the uvicorn configuration of the gateway (and of the bench's peer).

What a browser that cannot keep up gets is decided above this module
(:class:`robo_comp.web.hub.Subscriber`): a wire only writes, and says whether it is full.
"""
from __future__ import annotations

import asyncio
import contextlib
import socket
import struct
from collections.abc import Awaitable, Callable, Mapping
from typing import Any, Protocol

from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

#: The ASGI scope extension under which :class:`WireProtocol` offers a connection's wire.
EXTENSION = "robo_comp.wire"
#: A connection's transport buffer (bytes not yet taken by the kernel) above which its browser
#: counts as full: the messages after that wait, conflated, until it drains below a quarter.
HIGH_WATER = 256 * 1024
#: The kernel's send buffer of a connection (``SO_SNDBUF``; Linux doubles it): without it the
#: kernel grows it up to 4 MiB for a browser that does not read, every frame of it stale by the
#: time the browser gets to it. Half a MiB is seconds of a 1,000-robot match, and a state.
SEND_BUFFER = 256 * 1024


def frame_text(payload: bytes) -> bytes:
    """A whole (FIN) unmasked WebSocket text frame holding ``payload`` (UTF-8)."""
    n = len(payload)
    if n < 126:
        head = struct.pack("!BB", 0x81, n)
    elif n < 1 << 16:
        head = struct.pack("!BBH", 0x81, 126, n)
    else:
        head = struct.pack("!BBQ", 0x81, 127, n)
    return head + payload


class Wire(Protocol):
    """One browser's way out: whole frames written in order, and whether it is full."""

    def write(self, frame: bytes, text: str) -> None:
        """Send one message: its whole ``frame`` (:func:`frame_text`), or its ``text`` for a wire
        that frames it itself. Called only while :attr:`full` is false."""

    @property
    def full(self) -> bool:
        """True while the browser has not taken what was written (write nothing more)."""

    @property
    def closed(self) -> bool:
        """True once the connection is gone or closing (writes are dropped)."""

    async def drained(self) -> None:
        """Return once the wire is no longer full (or closed)."""


class TransportWire:
    """Frames written straight to a uvicorn WebSocket connection's transport."""

    def __init__(self, proto: WireProtocol) -> None:
        self.proto = proto
        self.transport = proto.transport
        self.transport.set_write_buffer_limits(high=HIGH_WATER)  # low: a quarter (asyncio's rule)
        sock = self.transport.get_extra_info("socket")
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER)
        self._writable = proto.writable  # cleared by pause_writing, set by resume_writing

    def write(self, frame: bytes, text: str) -> None:
        """Write ``frame`` to the transport (dropped once the connection closes)."""
        if not self.closed:
            self.transport.write(frame)

    @property
    def full(self) -> bool:
        """The transport paused its protocol: its buffer went over :data:`HIGH_WATER`."""
        return not self._writable.is_set()

    @property
    def closed(self) -> bool:
        """The browser left, or the app sent its close frame."""
        p = self.proto
        return p.disconnected or p.close_sent or self.transport.is_closing()

    async def drained(self) -> None:
        """Wait for the transport to resume writing (uvicorn sets the event on a lost connection too)."""
        await self._writable.wait()


class AsgiWire:
    """The wire over the plain ASGI ``send`` (``send(text)``): one message in flight at a time,
    full while it is."""

    def __init__(self, send: Callable[[str], Awaitable[None]]) -> None:
        self.send = send
        self._idle = asyncio.Event()
        self._idle.set()
        self._task: asyncio.Task[None] | None = None
        self._closed = False

    def write(self, frame: bytes, text: str) -> None:
        """Start sending ``text``; the wire is full until it is sent."""
        if self._closed:
            return
        self._idle.clear()
        self._task = asyncio.get_running_loop().create_task(self._send(text))

    async def _send(self, text: str) -> None:
        try:
            await self.send(text)
        except Exception:  # the socket closed under us: the connection's reader ends it
            self._closed = True
        finally:
            self._idle.set()

    @property
    def full(self) -> bool:
        """A message is still being sent."""
        return not self._idle.is_set()

    @property
    def closed(self) -> bool:
        """A send failed (the connection is gone)."""
        return self._closed

    async def drained(self) -> None:
        """Wait for the message in flight."""
        await self._idle.wait()

    def close(self) -> None:
        """Stop a message in flight (the connection ended)."""
        self._closed = True
        if self._task is not None:
            self._task.cancel()


class WireProtocol(WebSocketsSansIOProtocol):
    """uvicorn's WebSocket protocol, offering a :class:`TransportWire` as the ASGI extension
    :data:`EXTENSION` of every connection it upgrades (what it does otherwise is uvicorn's)."""

    def handle_connect(self, event: Any) -> None:
        """Upgrade as uvicorn does, then put this connection's wire in its scope (the app's task
        is created but has not run yet)."""
        super().handle_connect(event)
        scope = getattr(self, "scope", None)
        if scope is not None and not self.close_sent:
            with contextlib.suppress(AttributeError, TypeError):
                scope["extensions"][EXTENSION] = TransportWire(self)


def wire_of(scope: Mapping[str, Any]) -> TransportWire | None:
    """The connection's :class:`TransportWire`, when its server offers one."""
    w = (scope.get("extensions") or {}).get(EXTENSION)
    return w if isinstance(w, TransportWire) else None


def config(app: Any, **kw: Any) -> Any:
    """The gateway's uvicorn configuration: :class:`WireProtocol`, no per-message compression
    (one text for all browsers: never compressed per browser), messages from a page up to 1 MiB."""
    import uvicorn

    return uvicorn.Config(app, log_level="warning", ws=WireProtocol, ws_max_size=1 << 20, lifespan="on",
                          ws_per_message_deflate=False, **kw)
