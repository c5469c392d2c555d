"""Live views: one core connection per view, shared by every browser watching that view.

* :class:`PublicHub` is the spectators' view. It says hello with the gateway's own token only
  to learn the PUB port and take a starting snapshot, turns the core's pushed events off, and
  then follows the core's **public PUB feed**, the same feed a display wall shows the audience.
  The snapshot is cut down to the fields that feed carries (:func:`state.public_snapshot`);
  monitor data and find details come from that public model, and pictures are refused (they
  belong to the team that took them).
* :class:`TeamHub` is a team's private view, opened with a token a browser entered (or the
  server was given). It opens a core session with that token and forwards only what the core
  sends that session: its snapshot, its pushed events, its answers to ``monitor`` and
  ``picture.get``. What the token may see is the core's decision, never the gateway's.

Every browser of a view gets the same text for an event: each batch is applied to the hub's
:class:`MatchView` (for browsers that join later) and serialised once. A browser that cannot
keep up is never waited for: its queue is dropped and it gets a fresh ``state`` instead.
"""
from __future__ import annotations

import asyncio
import contextlib
import copy
import json
import logging
import time
from typing import Any

import zmq
import zmq.asyncio

from robo_comp.client import pub_url
from robo_comp import protocol as P
from robo_comp.protocol.curve import client_keys, secure_client
from robo_comp.errors import FieldError, RoboCompError
from robo_comp.link import CoreLink, LinkState
from robo_comp.view.model import MatchView
from robo_comp.web.state import TaskNames, jsonable, map_png, public_snapshot, state_json
from robo_comp.web.story import Story
from robo_comp.world.mapservice import unpack_costs

log = logging.getLogger("robo_comp.web")

#: Messages queued for one browser before it counts as behind (it then gets a fresh state).
QUEUE_LIMIT = 200
#: Events read from the PUB socket in one batch at most.
BATCH = 2000
#: Seconds between the public view's keep-alive requests.
PING = 0.5
#: How long a join waits for the view's first snapshot.
JOIN_TIMEOUT = 10.0


def dumps(msg: dict[str, Any]) -> str:
    """Compact JSON; bytes and numpy values are converted only when a message holds them."""
    try:
        return json.dumps(msg, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError):
        return json.dumps(jsonable(msg), separators=(",", ":"))


def compact(topic: str, d: dict[str, Any]) -> dict[str, Any]:
    """Poses rounded for the page (1/100 cell, 1/10 degree): half the bytes of a position batch."""
    if topic != "robot.positions":
        return d
    out = dict(d)
    for k, n in (("x", 2), ("y", 2), ("heading", 1)):
        v = d.get(k)
        if isinstance(v, list):
            out[k] = [round(float(a), n) for a in v]
    return out


class Subscriber:
    """One browser's WebSocket: a bounded queue of messages and the task that sends them."""

    def __init__(self, send: Any, limit: int = QUEUE_LIMIT) -> None:
        self.send = send  # async callable(text)
        self.queue: asyncio.Queue[str] = asyncio.Queue(limit)
        self.behind = False
        self.hub: Any = None
        self.task: asyncio.Task[None] | None = None

    def offer(self, text: str) -> None:
        """Queue a message; a full queue marks the browser as behind (it is resynchronised)."""
        if self.behind:
            return
        try:
            self.queue.put_nowait(text)
        except asyncio.QueueFull:
            self.behind = True
            while not self.queue.empty():
                self.queue.get_nowait()
            self.queue.put_nowait("")  # wake the sender

    async def run(self) -> None:
        """Send queued messages until cancelled or the browser is gone; a browser that fell
        behind gets a fresh state."""
        try:
            await self._run()
        except Exception as e:  # the socket closed under us: the connection's reader ends it
            log.debug("sending to a browser stopped: %s", e)

    async def _run(self) -> None:
        while True:
            text = await self.queue.get()
            if self.behind:
                self.behind = False
                while not self.queue.empty():
                    self.queue.get_nowait()
                if self.hub is not None:
                    text = self.hub.state_text()
            if text:
                await self.send(text)


class Hub:
    """A view of the match: a model, the browsers watching it and a way to answer their questions."""

    kind = "public"

    def __init__(self, name: str) -> None:
        self.name = name
        self.model = MatchView()
        self.tasks = TaskNames()
        self.subs: set[Subscriber] = set()
        self.ready = asyncio.Event()
        self.error: str | None = None
        self.loaded = False
        self.empty_since: float | None = time.monotonic()
        self._map: tuple[int, str] = (-1, "")
        self.events_in = 0
        self.story = Story()
        self.t0 = time.monotonic()  # the live timeline's zero (the story's ``t``)

    # ------------------------------------------------------------------ browsers
    def view_info(self) -> dict[str, Any]:
        """What the page shows about this view (its name and whether it is private)."""
        return {"name": self.name, "kind": self.kind}

    def state_text(self) -> str:
        """The ``state`` message for a browser that joins (or fell behind)."""
        av = self.model.arena_version
        if self._map[0] != av and self.model.arena is not None:
            self._map = (av, map_png(self.model))
        body = state_json(self.model, self.model.clock(), map_url=self._map[1], tasks=self.tasks.names)
        body["story"] = self.story.to_json()
        body["now"] = round(time.monotonic() - self.t0, 3)
        return dumps({"type": "state", "view": self.view_info(), "live": True, "state": body})

    def _match_clock(self) -> float | None:
        """The match clock now (None while the core reports no phases)."""
        m = self.model.match
        return m.now(self.model.clock())[0] if m.phase else None

    def adopt_story(self, other: Hub) -> None:
        """Start this view's story from another view's (a team view opened mid-match starts
        with what the public view told so far, on the same timeline)."""
        self.story = copy.deepcopy(other.story)
        self.t0 = other.t0

    def attach(self, sub: Subscriber) -> None:
        """Start sending this view to ``sub`` (its state first, then every event)."""
        sub.hub = self
        self.subs.add(sub)
        self.empty_since = None
        sub.offer(self.state_text())

    def detach(self, sub: Subscriber) -> None:
        """Stop sending to ``sub``."""
        self.subs.discard(sub)
        if sub.hub is self:
            sub.hub = None
        if not self.subs:
            self.empty_since = time.monotonic()

    def publish(self, events: list[tuple[str, dict[str, Any]]]) -> None:
        """Apply a batch of events to the model and send it, serialised once, to every browser."""
        resync = False
        told: dict[int, dict[str, Any]] = {}
        samples = len(self.story.scores)
        now = time.monotonic() - self.t0
        for topic, data in events:
            self.model.apply(topic, data)
            self.tasks.apply(topic, data)
            if topic != "robot.positions":
                for it in self.story.apply(topic, data, now, self._match_clock()):
                    told[it.id] = it.to_dict()
            resync |= topic == "core.started"
        self.events_in += len(events)
        if resync:  # a new arena: everyone starts again from a state
            text = self.state_text()
        else:
            msg: dict[str, Any] = {"type": "ev", "e": [[t, compact(t, d)] for t, d in events]}
            if told:
                msg["s"] = list(told.values())
            if len(self.story.scores) != samples and self.story.scores:
                t, c, board = self.story.scores[-1]
                msg["k"] = [round(t, 3), None if c is None else round(c, 2), board]
            if any(t == "match.phase" for t, _ in events):
                msg["v"] = self.story.victims
            text = dumps(msg)
        for s in list(self.subs):
            s.offer(text)

    def resync_all(self) -> None:
        """Send every browser a fresh state (after a reconnect to the core)."""
        text = self.state_text()
        for s in list(self.subs):
            s.behind = False
            with contextlib.suppress(asyncio.QueueFull):
                s.queue.put_nowait(text)

    def load(self, snap: dict[str, Any], costs: Any = None) -> None:
        """Start the model from a snapshot (and the map service's cell costs, when given)."""
        model = MatchView()
        model.load_snapshot(snap)
        if costs is not None:
            model.set_costs(costs)
        self.model = model
        self.tasks = TaskNames()
        for r in snap.get("robots") or []:
            t = r.get("task")
            if isinstance(t, dict) and t.get("name"):
                self.tasks.names[r["tag"]] = str(t["name"])
        self.loaded = True

    # ------------------------------------------------------------------ questions
    async def ask(self, op: str, body: dict[str, Any]) -> dict[str, Any]:
        """Answer a browser's ``monitor``/``find``/``picture`` question (the public view's answers)."""
        if op == "monitor":
            tag = _int(body, "tag")
            r = self.model.robots.get(tag)
            if r is None:
                raise FieldError(f"robot {tag} is not in this view")
            return {"tag": r.tag, "team": r.team, "status": r.status, "x": r.x, "y": r.y, "heading": r.heading,
                    "moving": r.moving, "task": self.tasks.names.get(tag),
                    "note": "public view: a team sees its own robots' sensors, tasks and results with its token"}
        if op == "find":
            key = f"find:{body.get('id')}"
            t = self.model.things.get(key)
            if t is None:
                raise FieldError(f"no find {body.get('id')!r} in this view")
            return {"kind": t.kind, "id": t.id, "team": t.team, "state": t.state, "x": t.x, "y": t.y, "info": t.info}
        if op == "picture":
            raise FieldError("pictures belong to the team that took them: enter that team's token to see them")
        if op == "video":
            raise FieldError("videos belong to the team that filmed them: enter that team's token to see them")
        raise FieldError(f"unknown request {op!r}")

    async def close(self) -> None:
        """Leave the core."""


def whole(body: dict[str, Any], key: str) -> int:
    """``body[key]`` as a whole number, or a :class:`FieldError` naming the field."""
    return _int(body, key)


def _int(body: dict[str, Any], key: str) -> int:
    v = body.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or int(v) != v:
        raise FieldError(f"'{key}' must be a whole number")
    return int(v)


class LinkedHub(Hub):
    """A hub with a core session (:class:`CoreLink`) that reloads its state whenever it connects."""

    def __init__(self, name: str, core: str, token: str, *, curve_cert: str | None = None,
                 core_key: str | None = None) -> None:
        super().__init__(name)
        self.core = core
        self.token = token
        self.curve_cert = curve_cert
        self.core_key = core_key
        self.link = CoreLink(core, token, client=f"web:{name}", on_event=self._on_event, on_state=self._on_state,
                             curve_cert=curve_cert, core_key=core_key)
        self._sync: asyncio.Task[None] | None = None
        self._buffer: list[tuple[str, dict[str, Any]]] | None = None

    def start(self) -> None:
        """Connect in the background."""
        self.link.start()

    def _on_state(self, state: LinkState, detail: str, info: dict[str, Any]) -> None:
        if state is LinkState.CONNECTED:
            if self._sync is not None:
                self._sync.cancel()
            self._buffer = []  # events that come before the snapshot's reply wait for it
            self._sync = asyncio.get_running_loop().create_task(self._resync())
        elif state is LinkState.CLOSED and detail != "closed" and not self.ready.is_set():
            self.error = f"the core refused this token: {detail}"
            self.ready.set()

    def _on_event(self, topic: str, team: str | None, data: dict[str, Any]) -> None:
        """Pushed events (a private view's feed)."""

    async def _snapshot(self) -> tuple[dict[str, Any], Any]:
        snap = await self.link.request("snapshot")
        costs = None
        with contextlib.suppress(RoboCompError, KeyError, TypeError, ValueError):
            costs = unpack_costs((await self.link.request("map"))["costs"])
        return snap, costs

    async def _resync(self) -> None:
        raise NotImplementedError

    async def close(self) -> None:
        """Leave the core (the match goes on)."""
        if self._sync is not None:
            self._sync.cancel()
        await self.link.close()


class PublicHub(LinkedHub):
    """The spectators' view: the core's public PUB feed (see the module docstring)."""

    def __init__(self, core: str, token: str, **kw: Any) -> None:
        super().__init__("public", core, token, **kw)
        self.sub: zmq.asyncio.Socket | None = None
        self._reader: asyncio.Task[None] | None = None
        self._pinger: asyncio.Task[None] | None = None
        self._pub: str = ""

    def start(self) -> None:
        """Connect in the background, and keep the session alive without pushed events."""
        super().start()
        self._pinger = asyncio.get_running_loop().create_task(self._ping())

    async def _ping(self) -> None:
        """With pushed events off the core sends this session no heartbeats, so the link would
        take the core for silent: a trivial request twice a second keeps it alive (and notices
        a core that went away)."""
        while True:
            await asyncio.sleep(PING)
            if self.link.connected:
                with contextlib.suppress(RoboCompError):
                    await self.link.request("watch", on=False, timeout=2.0)

    async def _resync(self) -> None:
        try:
            await self.link.request("watch", on=False)  # the public view needs no pushed events
            url = pub_url(self.link.url, int(self.link.info["pub_port"]))
            if url != self._pub or self.sub is None:
                self._open_sub(url)
                await asyncio.sleep(0.2)  # let the subscription reach the PUB socket (slow joiner)
            self._buffer = []
            snap, costs = await self._snapshot()
            self.load(public_snapshot(snap), costs)
            buffered, self._buffer = self._buffer, None
            if buffered:
                self.publish(buffered)
            self.ready.set()
            self.resync_all()
        except RoboCompError as e:
            log.warning("public view: %s", e.message)

    def _open_sub(self, url: str) -> None:
        if self._reader is not None:
            self._reader.cancel()
        if self.sub is not None:
            self.sub.close(0)
        sub = zmq.asyncio.Context.instance().socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        secure_client(sub, client_keys(self.core, self.token, self.curve_cert, self.core_key))
        sub.setsockopt(zmq.SUBSCRIBE, b"")
        sub.connect(url)
        self.sub, self._pub = sub, url
        self._reader = asyncio.get_running_loop().create_task(self._read(sub))

    async def _read(self, sub: zmq.asyncio.Socket) -> None:
        while True:
            try:
                frames = await sub.recv_multipart()
                batch = [_event(frames)]
                while len(batch) < BATCH and await sub.poll(0):
                    batch.append(_event(await sub.recv_multipart()))
            except zmq.ZMQError:
                return
            events = [e for e in batch if e is not None]
            if self._buffer is not None:
                self._buffer.extend(events)
            elif self.loaded and events:
                self.publish(events)

    async def close(self) -> None:
        """Close the feed and leave the core."""
        for t in (self._reader, self._pinger):
            if t is not None:
                t.cancel()
        if self.sub is not None:
            self.sub.close(0)
        await super().close()


def _event(frames: list[bytes]) -> tuple[str, dict[str, Any]] | None:
    try:
        data = P.unpack(frames[1])
    except Exception:
        return None
    return (frames[0].decode(errors="replace"), data) if isinstance(data, dict) else None


class TeamHub(LinkedHub):
    """A private view: exactly what the core sends a session holding this token."""

    kind = "private"

    def _on_event(self, topic: str, team: str | None, data: dict[str, Any]) -> None:
        if self._buffer is not None:
            self._buffer.append((topic, data))
        elif self.loaded:
            self.publish([(topic, data)])

    def view_info(self) -> dict[str, Any]:
        """A private view is named for the token's team (or the referee)."""
        return {"name": self.name, "kind": self.kind, "role": self.link.role}

    async def _resync(self) -> None:
        try:
            snap, costs = await self._snapshot()
            self.name = self.link.team or self.link.role or self.name
            self.load(snap, costs)
            buffered, self._buffer = self._buffer, None
            if buffered:
                self.publish(buffered)
            self.ready.set()
            self.resync_all()
        except RoboCompError as e:
            self._buffer = None
            log.warning("private view %s: %s", self.name, e.message)

    async def ask(self, op: str, body: dict[str, Any]) -> dict[str, Any]:
        """Ask the core, in this token's session: the core decides what this token may see."""
        if op == "monitor":
            return await self.link.request("monitor", tag=_int(body, "tag"))
        if op == "picture":
            reply = await self.link.request("picture.get", id=_int(body, "id"))
            return {"id": body.get("id"), "png": "data:image/png;base64," + jsonable(reply.get("png", b"")),
                    "label": reply.get("label", ""), "tag": reply.get("tag")}
        if op == "video":
            return await self._video(_int(body, "id"))
        return await super().ask(op, body)

    async def _video(self, vid: int) -> dict[str, Any]:
        """Video ``vid`` as a data URL the page's ``<video>`` plays (the core decides who may see it)."""
        reply = await self.link.request("video.get", id=vid)
        return {"id": vid, "webm": "data:video/webm;base64," + jsonable(reply.get("webm", b"")),
                "label": reply.get("label", ""), "tag": reply.get("tag"), "seconds": reply.get("seconds")}
