"""The web gateway: a Starlette app serving the page, its ES modules and one WebSocket per browser.

A browser opens ``/ws`` and sends ``{"op": "join"}`` (the public view), ``{"op": "join",
"token": T}`` (the view of that token, as the core shows it to that token) or ``{"op": "join",
"view": NAME}`` (a private view whose token the server was given). Then it may ask
``monitor``/``find``/``picture`` questions (``{"op", "req", ...}`` answered by ``{"type": "reply",
"req", "ok", "body" | "error"}``) and, for a replay, ``play``, ``pause``, ``speed`` and ``seek``.
The server sends ``state`` (everything, when joining or after falling behind), ``ev`` (a batch
of events) and, for replays, ``clock``.
"""
from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from robo_comp.errors import FieldError, RoboCompError
from robo_comp.web.hub import JOIN_TIMEOUT, Hub, PublicHub, Subscriber, TeamHub, dumps, whole
from robo_comp.web.replay import Playback, Recording

log = logging.getLogger("robo_comp.web")
STATIC = Path(__file__).parent / "static"
#: Seconds a private view stays connected to the core after its last browser left.
IDLE_CLOSE = 30.0


class LiveGateway:
    """The hubs of a live core: the public one, and one per private token in use."""

    mode = "live"

    def __init__(self, core: str, token: str, *, private_tokens: dict[str, str] | None = None,
                 curve_cert: str | None = None, core_key: str | None = None) -> None:
        self.core = core
        self.token = token
        self.keys = {"curve_cert": curve_cert, "core_key": core_key}
        self.private_tokens = dict(private_tokens or {})  # view name -> token (given to the server)
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
            if view not in self.private_tokens:
                raise FieldError(f"this server offers no view {view!r}; enter the team's token instead")
            token = self.private_tokens[view]
        if token is not None and not isinstance(token, str):
            raise FieldError("'token' must be text")
        if not token:
            hub: Hub = self.public  # type: ignore[assignment]  -- both gateways' hubs answer the same calls
        else:
            token = token.strip()
            hub = self.private.get(token)  # type: ignore[assignment]  -- both gateways' hubs answer the same calls
            if hub is None:
                th = TeamHub("private", self.core, token, **self.keys)
                if self.public is not None:  # the story so far (public events: every team saw them)
                    th.adopt_story(self.public)
                self.private[token] = th
                th.start()
                hub = th
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

    def __init__(self, gw: LiveGateway | ReplayGateway, ws: WebSocket) -> None:
        self.gw = gw
        self.ws = ws
        self.sub = Subscriber(self._send)
        self.playback: Playback | None = None
        self._send_lock = asyncio.Lock()

    async def _send(self, text: str) -> None:
        async with self._send_lock:
            await self.ws.send_text(text)

    async def run(self) -> None:
        """Serve the browser until it leaves."""
        await self.ws.accept()
        await self._send(dumps({"type": "hello", **self.gw.info()}))
        self.sub.task = asyncio.get_running_loop().create_task(self.sub.run())
        try:
            while True:
                try:
                    msg = json.loads(await self.ws.receive_text())
                except (ValueError, KeyError):  # not JSON, or a binary frame
                    await self._send(dumps({"type": "error", "message": "messages must be JSON objects as text"}))
                    continue
                if not isinstance(msg, dict):
                    continue
                await self.handle(msg)
        except WebSocketDisconnect:
            pass
        finally:
            self.sub.task.cancel()
            if self.sub.hub is not None:
                self.sub.hub.detach(self.sub)
            if self.playback is not None:
                self.playback.close()

    async def handle(self, msg: dict[str, Any]) -> None:
        """One message from the page."""
        op = msg.get("op")
        rid = msg.get("req")
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
        except Exception:  # a bug must not end the browser's connection: log it, say so
            log.exception("web: %r from a page failed", op)
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
        elif op in ("monitor", "find"):
            return {"note": "a replay's page answers from its own state"}
        else:
            raise FieldError(f"unknown request {op!r}")
        return {}


def make_app(gw: LiveGateway | ReplayGateway) -> Starlette:
    """The Starlette application of a gateway."""

    async def index(request: Any) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    async def info(request: Any) -> Response:
        return JSONResponse(gw.info())

    async def ws(websocket: WebSocket) -> None:
        await Connection(gw, websocket).run()

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        await gw.start()
        yield
        await gw.close()

    async def favicon(request: Any) -> Response:
        return Response(status_code=204)

    return Starlette(routes=[Route("/", index), Route("/info", info), Route("/favicon.ico", favicon), WebSocketRoute("/ws", ws),
                             Mount("/static", StaticFiles(directory=STATIC), name="static")],
                     lifespan=lifespan)
