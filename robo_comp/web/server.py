"""The web gateway: a Starlette app serving the page, its ES modules and one WebSocket per browser.

A browser opens ``/ws`` and sends ``{"op": "join"}`` (the public view), ``{"op": "join",
"token": T}`` (the view of that token, as the core shows it to that token) or ``{"op": "join",
"view": NAME, "key": K}`` (a private view whose token the server was given; ``K`` is that view's
key, :func:`view_key`, which the gateway prints in the view's link). Then it may ask
``monitor``/``find``/``picture`` questions (``{"op", "req", ...}`` answered by ``{"type": "reply",
"req", "ok", "body" | "error"}``) and, for a replay, ``play``, ``pause``, ``speed`` and ``seek``.
The server sends ``state`` (everything, when joining or after falling behind), ``ev`` (a batch
of events) and, for replays, ``clock``.

Against other sites (docs/security.md, "The web gateway"): ``/ws`` refuses a browser whose
``Origin`` is neither the page's own host nor one the organiser allowed (``--allow-origin``), so
a page on another site cannot ride on a visitor's network position; no private view opens
without a secret (a token or a view key); every response carries a Content-Security-Policy,
``Referrer-Policy: no-referrer`` and ``X-Frame-Options: DENY``; and a message the gateway cannot
read (not JSON, nested too deep, not an object) gets an error reply, never a logged traceback.
"""
from __future__ import annotations

import asyncio
import base64
import contextlib
import hashlib
import hmac
import ipaddress
import json
import logging
import socket
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from starlette.applications import Starlette
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from robo_comp.errors import FieldError, RoboCompError
from robo_comp.web.hub import JOIN_TIMEOUT, Hub, PublicHub, Subscriber, TeamHub, dumps, whole
from robo_comp.web.replay import Playback, Recording
from robo_comp.web.wire import AsgiWire, wire_of

log = logging.getLogger("robo_comp.web")
STATIC = Path(__file__).parent / "static"
#: Seconds a private view stays connected to the core after its last browser left.
IDLE_CLOSE = 30.0
#: Headers on every HTTP response: the page loads only its own scripts and styles, talks only
#: to its own host, cannot be framed, and sends no Referer (a view key in a link stays private).
SECURITY_HEADERS = {
    "content-security-policy": "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; media-src data:; "
                               "connect-src 'self'; base-uri 'none'; frame-ancestors 'none'",
    "referrer-policy": "no-referrer",
    "x-frame-options": "DENY",
    "x-content-type-options": "nosniff",
    "cross-origin-opener-policy": "same-origin",
    "cross-origin-resource-policy": "same-origin",
}
#: Distinct refused origins logged (each once); the rest are refused without a word.
ORIGINS_LOGGED = 50


def view_key(token: str) -> str:
    """The key of the private view offered with ``token`` (``--view-token-file``): a keyed hash of
    the token, so the link that opens the view does not hold the token itself, and the same on
    every start of the gateway."""
    mac = hmac.new(token.encode(), b"robo_comp.web.view/1", hashlib.sha256).digest()
    return base64.urlsafe_b64encode(mac[:18]).decode()


def _local_names() -> set[str]:
    names = {"localhost"}
    with contextlib.suppress(OSError):
        names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
    return names


class OriginCheck:
    """Which browser pages may open ``/ws``: pages served by this gateway under a name it can
    trust (an IP address, ``localhost`` or this machine's name: a name of another site that
    resolves here, DNS rebinding, is refused), and the origins the organiser listed
    (``--allow-origin https://match.example.org``). A client that sends no ``Origin`` is not a
    browser page (a script of the organiser's) and is let in: it holds no visitor's session."""

    def __init__(self, allowed: list[str] | None = None) -> None:
        self.allowed = {self.normalise(o) for o in allowed or []}
        self.names = _local_names()
        self.refused: set[str] = set()

    @staticmethod
    def normalise(origin: str) -> str:
        """``scheme://host[:port]`` in lower case, without a default port or a trailing slash."""
        u = urlsplit(origin.strip().lower())
        if not u.scheme or not u.hostname:
            raise FieldError(f"an origin looks like https://host[:port], not {origin!r}")
        port = u.port
        default = {"http": 80, "https": 443}.get(u.scheme)
        host = f"[{u.hostname}]" if ":" in u.hostname else u.hostname
        return f"{u.scheme}://{host}" + (f":{port}" if port and port != default else "")

    def _trusted_name(self, host: str) -> bool:
        try:
            ipaddress.ip_address(host.strip("[]"))
            return True
        except ValueError:
            return host in self.names

    def allows(self, origin: str | None, host: str | None) -> bool:
        """Whether a WebSocket with this ``Origin`` and ``Host`` header may open."""
        if origin is None:
            return True
        try:
            o = self.normalise(origin)
        except FieldError:
            return False
        if o in self.allowed:
            return True
        u = urlsplit(o)
        own = (host or "").strip().lower()
        return bool(own) and u.netloc == own.removesuffix(":80" if u.scheme == "http" else ":443") \
            and self._trusted_name(u.hostname or "")

    def note_refused(self, origin: str | None) -> None:
        """Log a refused origin the first times it comes (a flood is not logged line by line)."""
        o = str(origin)[:200]
        if o not in self.refused and len(self.refused) < ORIGINS_LOGGED:
            self.refused.add(o)
            log.warning("web: refused a WebSocket from the page origin %r (not this gateway's; "
                        "--allow-origin lets one in)", o)


class SecurityHeaders:
    """ASGI middleware: :data:`SECURITY_HEADERS` on every HTTP response."""

    def __init__(self, app: Any) -> None:
        self.app = app
        self.headers = [(k.encode(), v.encode()) for k, v in SECURITY_HEADERS.items()]

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Any) -> None:
            if message["type"] == "http.response.start":
                message = dict(message)
                message["headers"] = [*message.get("headers", []), *self.headers]
            await send(message)

        await self.app(scope, receive, send_with_headers)


class LiveGateway:
    """The hubs of a live core: the public one, and one per private token in use."""

    mode = "live"

    def __init__(self, core: str, token: str, *, private_tokens: dict[str, str] | None = None,
                 curve_cert: str | None = None, core_key: str | None = None) -> None:
        self.core = core
        self.token = token
        self.keys = {"curve_cert": curve_cert, "core_key": core_key}
        self.private_tokens = dict(private_tokens or {})  # view name -> token (given to the server)
        self.view_keys = {name: view_key(tok) for name, tok in self.private_tokens.items()}
        self.public: PublicHub | None = None
        self.private: dict[str, TeamHub] = {}
        self._reaper: asyncio.Task[None] | None = None

    async def start(self) -> None:
        """Join the core (in the background: the page says when the core is not there yet)."""
        self.public = PublicHub(self.core, self.token, **self.keys)
        self.public.start()
        self._reaper = asyncio.get_running_loop().create_task(self._reap())

    def info(self) -> dict[str, Any]:
        """What the page needs to know before joining."""
        return {"mode": self.mode, "views": sorted(self.private_tokens)}

    async def hub(self, msg: dict[str, Any]) -> Hub:
        """The hub for a ``join`` message (waiting for its first snapshot)."""
        token = msg.get("token")
        view = msg.get("view")
        if view and view != "public":
            if not isinstance(view, str) or view not in self.private_tokens:
                raise FieldError(f"this server offers no view {str(view)[:40]!r}; enter the team's token instead")
            key = msg.get("key")
            if not isinstance(key, str) or not hmac.compare_digest(key.encode(), self.view_keys[view].encode()):
                raise FieldError(f"the view {view!r} opens with its link (the gateway printed it when it started) "
                                 "or with the team's token")
            token = self.private_tokens[view]
        if token is not None and not isinstance(token, str):
            raise FieldError("'token' must be text")
        hub: Hub
        if not token:
            assert self.public is not None, "start() makes the public hub before the server takes a page"
            hub = self.public
        else:
            token = token.strip()
            known = self.private.get(token)
            if known is None:
                th = TeamHub("private", self.core, token, **self.keys)
                if self.public is not None:  # the story so far (public events: every team saw them)
                    th.adopt_story(self.public)
                self.private[token] = th
                th.start()
                known = th
            hub = known
        try:
            await asyncio.wait_for(hub.ready.wait(), JOIN_TIMEOUT)
        except asyncio.TimeoutError:
            raise RoboCompError(f"the core at {self.core} does not answer yet; the page retries") from None
        if hub.error:
            if isinstance(hub, TeamHub):
                self.private.pop(hub.token, None)
                await hub.close()
            raise RoboCompError(hub.error)
        return hub

    async def _reap(self) -> None:
        while True:
            await asyncio.sleep(5.0)
            now = time.monotonic()
            for tok, hub in list(self.private.items()):
                if hub.empty_since is not None and now - hub.empty_since > IDLE_CLOSE:
                    self.private.pop(tok, None)
                    await hub.close()

    async def close(self) -> None:
        """Leave the core."""
        if self._reaper is not None:
            self._reaper.cancel()
        for hub in [self.public, *self.private.values()]:
            if hub is not None:
                await hub.close()


class ReplayGateway:
    """A recorded match: views built on first use, one :class:`Playback` per browser."""

    mode = "replay"

    def __init__(self, log_path: str | Path) -> None:
        self.recording = Recording(log_path)

    async def start(self) -> None:
        """Build the public view now (the first page then opens at once)."""
        await self.recording.view("public")

    def info(self) -> dict[str, Any]:
        """What the page needs to know before joining."""
        return {"mode": self.mode, **self.recording.summary(), "views": []}

    async def close(self) -> None:
        """Nothing to leave."""


class Connection:
    """One browser's WebSocket session."""

    def __init__(self, gw: LiveGateway | ReplayGateway, ws: WebSocket, origins: OriginCheck | None = None) -> None:
        self.gw = gw
        self.ws = ws
        self.origins = origins or OriginCheck()
        # a live view's frames go straight to the socket where the server offers it (uvicorn with
        # robo_comp.web.wire.WireProtocol), else one at a time through ASGI
        self.sub = Subscriber(wire_of(ws.scope) or AsgiWire(self._send))
        self.playback: Playback | None = None
        self._send_lock = asyncio.Lock()

    async def _send(self, text: str) -> None:
        async with self._send_lock:
            await self.ws.send_text(text)

    async def run(self) -> None:
        """Serve the browser until it leaves (a page of another site is refused before anything)."""
        origin = self.ws.headers.get("origin")
        if not self.origins.allows(origin, self.ws.headers.get("host")):
            self.origins.note_refused(origin)
            await self.ws.close(code=1008)  # before accept: the browser gets HTTP 403
            return
        await self.ws.accept()
        await self._send(dumps({"type": "hello", **self.gw.info()}))
        try:
            while True:
                try:
                    msg = json.loads(await self.ws.receive_text())
                except (ValueError, KeyError):  # not JSON, or a binary frame
                    await self._refuse("E_FIELD", "messages must be JSON objects as text")
                    continue
                except RecursionError:
                    await self._refuse("E_FIELD", "this message is nested too deeply to read; messages are "
                                                  "flat JSON objects such as {\"op\": \"join\"}")
                    continue
                if not isinstance(msg, dict):
                    await self._refuse("E_FIELD", "a message is a JSON object with an \"op\", such as "
                                                  "{\"op\": \"join\"}")
                    continue
                await self.handle(msg)
        except WebSocketDisconnect:
            pass
        finally:
            self.sub.close()
            if self.sub.hub is not None:
                self.sub.hub.detach(self.sub)
            if self.playback is not None:
                self.playback.close()

    async def _refuse(self, code: str, message: str) -> None:
        await self._send(dumps({"type": "error", "ok": False, "error": {"code": code, "message": message},
                                "message": message}))

    async def handle(self, msg: dict[str, Any]) -> None:
        """One message from the page."""
        op = msg.get("op")
        rid = msg.get("req")
        if not isinstance(op, str) or len(op) > 40:
            op = None if op is None else "?"
        if not isinstance(rid, (int, str)) or isinstance(rid, bool) or len(str(rid)) > 40:
            rid = None
        try:
            if op == "join":
                await self.join(msg)
                return
            body = await self.question(op, msg)
            if rid is not None:
                await self._send(dumps({"type": "reply", "req": rid, "ok": True, "body": body}))
        except RoboCompError as e:
            await self._send(dumps({"type": "reply" if rid is not None else "error", "req": rid, "ok": False,
                                    "op": op, "error": {"code": e.code, "message": e.message},
                                    "message": e.message}))
        except (WebSocketDisconnect, asyncio.CancelledError):
            raise
        except RecursionError:  # a message nested deep below its top level
            await self._send(dumps({"type": "reply" if rid is not None else "error", "req": rid, "ok": False,
                                    "op": op, "error": {"code": "E_FIELD", "message": "nested too deeply"},
                                    "message": "this message is nested too deeply to read"}))
        except Exception as e:  # a bug must not end the browser's connection: log it once, briefly, say so
            log.error("web: %r from a page failed: %s: %s", op, type(e).__name__, str(e)[:200])
            log.debug("web: the failure's traceback", exc_info=True)
            await self._send(dumps({"type": "reply" if rid is not None else "error", "req": rid, "ok": False, "op": op,
                                    "error": {"code": "E_INTERNAL", "message": f"the gateway failed on {op!r}"},
                                    "message": f"the gateway failed on {op!r}; it was logged"}))

    async def join(self, msg: dict[str, Any]) -> None:
        """Switch this browser to the view the message asks for."""
        if isinstance(self.gw, LiveGateway):
            hub = await self.gw.hub(msg)
            if self.sub.hub is not None:
                self.sub.hub.detach(self.sub)
            hub.attach(self.sub)
            return
        rec = self.gw.recording
        token = msg.get("token")
        name = rec.view_for_token(token) if isinstance(token, str) and token.strip() else "public"
        view = await rec.view(name)
        if self.playback is None:
            self.playback = Playback(rec, self._send)
        at = msg.get("t", self.playback.at)
        speed = msg.get("speed", self.playback.speed)
        await self.playback.open(view, at if isinstance(at, (int, float)) else 0.0,
                                 play=bool(msg.get("play", self.playback.playing)), speed=speed)

    async def question(self, op: Any, msg: dict[str, Any]) -> Any:
        """Answer a question or carry out a replay control."""
        if isinstance(self.gw, LiveGateway):
            if self.sub.hub is None:
                raise FieldError("join a view first")
            return await self.sub.hub.ask(str(op), msg)
        pb = self.playback
        if pb is None or pb.view is None:
            raise FieldError("join the replay first")
        if op == "play":
            await pb.play()
        elif op == "pause":
            await pb.pause()
        elif op == "speed":
            pb.set_speed(msg.get("value"))
            await pb._clock()
        elif op == "seek":
            return {"took_ms": round(await pb.seek(msg.get("t")) * 1000, 3)}
        elif op == "picture":
            return {"id": msg.get("id"), "png": self.gw.recording.picture(pb.view, whole(msg, "id"))}
        elif op == "video":
            return {"id": msg.get("id"), "webm": self.gw.recording.video(pb.view, whole(msg, "id"))}
        elif op in ("monitor", "find"):
            return {"note": "a replay's page answers from its own state"}
        else:
            raise FieldError(f"unknown request {op!r}")
        return {}


def make_app(gw: LiveGateway | ReplayGateway, *, allow_origins: list[str] | None = None) -> Starlette:
    """The Starlette application of a gateway (``allow_origins``: page origins besides its own
    that may open ``/ws``)."""
    from starlette.middleware import Middleware

    origins = OriginCheck(allow_origins)

    async def index(request: Any) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    async def info(request: Any) -> Response:
        return JSONResponse(gw.info())

    async def ws(websocket: WebSocket) -> None:
        await Connection(gw, websocket, origins).run()

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        await gw.start()
        yield
        await gw.close()

    async def favicon(request: Any) -> Response:
        return Response(status_code=204)

    return Starlette(routes=[Route("/", index), Route("/info", info), Route("/favicon.ico", favicon), WebSocketRoute("/ws", ws),
                             Mount("/static", StaticFiles(directory=STATIC), name="static")],
                     lifespan=lifespan, middleware=[Middleware(SecurityHeaders)])
