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

Every browser of a view gets the same bytes for an event: each batch the core's feed has ready
is serialised and framed once (a :class:`Frame`) and written to every browser's socket in one
pass, without a task or a queue per browser (:mod:`robo_comp.web.wire`); then it is applied to the
hub's :class:`MatchView` (for browsers that join later). A browser that cannot keep up is never
waited for: while its socket is full its frames wait, and a waiting frame of poses is dropped
once later ones place all its robots (conflation: it gets the newest poses, not every step); one
that stays behind past :data:`HELD_FRAMES` frames or :data:`HELD_BYTES` gets a fresh ``state``
instead.
"""
from __future__ import annotations

import asyncio
import contextlib
import copy
import json
import logging
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import zmq
import zmq.asyncio

from robo_comp.client import pub_url
from robo_comp import protocol as P
from robo_comp.protocol.curve import client_keys, secure_client
from robo_comp.errors import FieldError, RoboCompError
from robo_comp.link import CoreLink, LinkState
from robo_comp.view.model import MatchView
from robo_comp.web.state import TaskNames, jsonable, map_png, public_snapshot, state_json
from robo_comp.view.story import Story
from robo_comp.web.wire import Wire, frame_text
from robo_comp.world.mapservice import unpack_costs

log = logging.getLogger("robo_comp.web")

#: Frames held for a browser whose socket is full, at most, after conflation (past that, or
#: :data:`HELD_BYTES`, it gets one fresh state instead of the frames it missed).
HELD_FRAMES = 64
HELD_BYTES = 4 << 20
#: Events read from the PUB socket in one batch at most.
BATCH = 2000
#: Seconds: an event that follows the last one of a batch this soon joins it (the core publishes
#: a pose period's batches, one per team, within a millisecond or so: one frame, not two or four),
#: for at most one animation frame (:data:`BATCH_SPAN`) after the batch's first event; a batch
#: with a pose batch of every team of the last period does not wait.
BATCH_GAP = 0.001
BATCH_SPAN = 1 / 60
#: Seconds between the public view's keep-alive requests.
PING = 0.5
#: How long a join waits for the view's first snapshot.
JOIN_TIMEOUT = 10.0
#: Seconds a view's ``state`` message is reused for browsers that join meanwhile, unless an event
#: changes the view first (a thousand browsers that open the page together cost one state).
STATE_REUSE = 0.1
#: The fields of a ``robot.positions`` event the page draws (``sigma`` stays in the hub's model).
PAGE_POSES = ("team", "tags", "x", "y", "heading", "moving")


def dumps(msg: dict[str, Any]) -> str:
    """Compact JSON; bytes and numpy values are converted only when a message holds them."""
    try:
        return json.dumps(msg, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError):
        return json.dumps(jsonable(msg), separators=(",", ":"))


def compact(topic: str, d: dict[str, Any]) -> dict[str, Any]:
    """A position batch as the page gets it: the fields it draws, poses rounded (1/100 cell, 1/10
    degree): a third of the bytes of the core's batch."""
    if topic != "robot.positions":
        return d
    out = {k: d[k] for k in PAGE_POSES if k in d}
    for k, n in (("x", 2), ("y", 2), ("heading", 1)):
        v = d.get(k)
        if isinstance(v, list):
            try:
                out[k] = np.round(np.asarray(v, dtype=np.float64), n).tolist()
            except (TypeError, ValueError):  # not numbers: the page is told what the core said
                out[k] = v
    return out


@dataclass(eq=False)
class Frame:
    """One message of a view, serialised and framed once for every browser of the view.

    ``poses``: for a frame that holds only ``robot.positions`` events, the robots it places
    (later such frames that place them all make this one redundant for a browser still waiting
    for it); ``None`` for every other frame, which is never dropped."""

    text: str
    poses: frozenset[int] | None = None
    data: bytes = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.data = frame_text(self.text.encode())


class Subscriber:
    """One browser of a view, and what waits for it while its socket is full (see the module
    docstring): :meth:`offer` writes a frame at once when the wire takes it, else holds it.

    A held frame of poses is dropped once the frames of poses held after it place every robot it
    places (the page would draw those robots where the later frames put them anyway); every
    other frame is kept, in order."""

    def __init__(self, wire: Wire, limit: int = HELD_FRAMES) -> None:
        self.wire = wire
        self.limit = limit
        self.held: list[Frame] = []
        self._unplaced: list[set[int] | None] = []  # per held frame of poses: robots no later frame places
        self.held_bytes = 0
        self.behind = False
        self.hub: Hub | None = None
        self.task: asyncio.Task[None] | None = None
        self.conflated = 0  # frames of poses dropped for newer ones
        self.resyncs = 0  # fresh states sent instead of the frames missed

    def offer(self, frame: Frame) -> None:
        """Send ``frame`` now, or hold it (conflated) until the browser takes more."""
        if not self.held and not self.behind and not self.wire.full:
            self.wire.write(frame.data, frame.text)
            return
        if self.behind:
            return
        if frame.poses is not None and self.held:
            self._conflate(frame.poses)
        self.held.append(frame)
        self._unplaced.append(None if frame.poses is None else set(frame.poses))
        self.held_bytes += len(frame.data)
        if len(self.held) > self.limit or self.held_bytes > HELD_BYTES:
            self.behind = True
            self._clear()
        if self.task is None or self.task.done():
            self.task = asyncio.get_running_loop().create_task(self._drain())

    def _conflate(self, poses: frozenset[int]) -> None:
        """Drop the held frames of poses whose every robot ``poses`` places anew."""
        drop = False
        for left in self._unplaced:
            if left is not None:
                left -= poses
                drop |= not left
        if drop:
            keep = [i for i, left in enumerate(self._unplaced) if left is None or left]
            self.conflated += len(self.held) - len(keep)
            self.held = [self.held[i] for i in keep]
            self._unplaced = [self._unplaced[i] for i in keep]
            self.held_bytes = sum(len(f.data) for f in self.held)

    def _clear(self) -> None:
        self.held.clear()
        self._unplaced.clear()
        self.held_bytes = 0

    def resync(self, frame: Frame) -> None:
        """A fresh state replaces whatever waits."""
        self._clear()
        self.behind = False
        self.offer(frame)

    async def _drain(self) -> None:
        """Write what waits as the browser takes it (a fresh state for one that fell behind)."""
        w = self.wire
        while (self.held or self.behind) and not w.closed:
            await w.drained()
            if w.closed:
                break
            if self.behind:
                self.behind = False
                if self.hub is not None:
                    self.resyncs += 1
                    f = self.hub.state_frame()
                    w.write(f.data, f.text)
                continue
            while self.held and not w.full:
                f = self.held.pop(0)
                self._unplaced.pop(0)
                self.held_bytes -= len(f.data)
                w.write(f.data, f.text)
        self._clear()

    def close(self) -> None:
        """The browser left: nothing more is written."""
        if self.task is not None:
            self.task.cancel()
        self._clear()
        close = getattr(self.wire, "close", None)
        if close is not None:
            close()


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
        self._state: tuple[float, Frame] | None = None  # (made at, the state message) for joins
        self.frames_out = 0  # frames made (each written to every browser of the view)

    # ------------------------------------------------------------------ browsers
    def view_info(self) -> dict[str, Any]:
        """What the page shows about this view (its name and whether it is private)."""
        return {"name": self.name, "kind": self.kind}

    def state_frame(self) -> Frame:
        """The ``state`` message for a browser that joins (or fell behind); reused for
        :data:`STATE_REUSE` seconds unless the view changes first."""
        now = time.monotonic()
        if self._state is not None and now - self._state[0] < STATE_REUSE:
            return self._state[1]
        av = self.model.arena_version
        if self._map[0] != av and self.model.arena is not None:
            self._map = (av, map_png(self.model))
        body = state_json(self.model, self.model.clock(), map_url=self._map[1], tasks=self.tasks.names)
        body["story"] = self.story.to_json()
        body["now"] = round(now - self.t0, 3)
        frame = Frame(dumps({"type": "state", "view": self.view_info(), "live": True, "state": body}))
        self._state = (now, frame)
        return frame

    def state_text(self) -> str:
        """The text of :meth:`state_frame`."""
        return self.state_frame().text

    def adopt_story(self, other: Hub) -> None:
        """Start this view's story from another view's (a team view opened mid-match starts
        with what the public view told so far, on the same timeline)."""
        self.story = copy.deepcopy(other.story)
        self.t0 = other.t0
        self._state = None

    def attach(self, sub: Subscriber) -> None:
        """Start sending this view to ``sub`` (its state first, then every event)."""
        sub.hub = self
        self.subs.add(sub)
        self.empty_since = None
        sub.offer(self.state_frame())

    def detach(self, sub: Subscriber) -> None:
        """Stop sending to ``sub``."""
        self.subs.discard(sub)
        if sub.hub is self:
            sub.hub = None
        if not self.subs:
            self.empty_since = time.monotonic()

    def publish(self, events: list[tuple[str, dict[str, Any]]]) -> None:
        """Send a batch of events, serialised and framed once, to every browser, and apply it to
        the model. A batch of poses only goes out first (the model is for browsers that join
        later); any other batch is applied first, since the story it tells goes with it."""
        self._state = None
        self.events_in += len(events)
        if all(t == "robot.positions" for t, _ in events):
            if not self.subs:  # nobody watches: the model only
                for topic, data in events:
                    self.model.apply(topic, data)
                return
            poses: set[int] = set()
            for _, d in events:
                tags = d.get("tags")
                if isinstance(tags, list):
                    poses.update(t for t in tags if isinstance(t, int))
            self.fan_out(Frame(dumps({"type": "ev", "e": [[t, compact(t, d)] for t, d in events]}), frozenset(poses)))
            for topic, data in events:
                self.model.apply(topic, data)
            return
        resync = False
        told: dict[int, dict[str, Any]] = {}
        samples = len(self.story.scores)
        now = time.monotonic() - self.t0
        for topic, data in events:
            self.model.apply(topic, data)
            self.tasks.apply(topic, data)
            for it in self.story.follow(self.model, topic, data, now):
                told[it.id] = it.to_dict()
            resync |= topic == "core.started"
        if resync:  # a new arena: everyone starts again from a state
            self.resync_all()
            return
        msg: dict[str, Any] = {"type": "ev", "e": [[t, compact(t, d)] for t, d in events]}
        if told:
            msg["s"] = list(told.values())
        if len(self.story.scores) != samples and self.story.scores:
            t, c, board = self.story.scores[-1]
            msg["k"] = [round(t, 3), None if c is None else round(c, 2), board]
        if any(t == "match.phase" for t, _ in events):
            msg["v"] = self.story.victims
        self.fan_out(Frame(dumps(msg)))

    def fan_out(self, frame: Frame) -> None:
        """Write ``frame`` to every browser of the view (held for those whose socket is full)."""
        self.frames_out += 1
        for s in list(self.subs):
            s.offer(frame)

    def resync_all(self) -> None:
        """Send every browser a fresh state (after a reconnect to the core, or a new arena)."""
        self._state = None
        frame = self.state_frame()
        for s in list(self.subs):
            s.resync(frame)

    def load(self, snap: dict[str, Any], costs: Any = None) -> None:
        """Start the model from a snapshot (and the map service's cell costs, when given)."""
        model = MatchView()
        model.load_snapshot(snap)
        if costs is not None:
            model.set_costs(costs)
        self.model = model
        self._state = None
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
        self._core_id: Any = None  # the core process whose snapshot the view was loaded from

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
        """After each (re)connection: the feed, a snapshot and a fresh state for every browser; but
        when the session comes back to the same core process, whose feed this view kept reading
        (the session only timed out: a loaded machine, a core stopped for a while), the view is
        whole and the browsers keep their frames (with a thousand browsers, a fresh state each is
        a few hundred MiB to send)."""
        try:
            await self.link.request("watch", on=False)  # the public view needs no pushed events
            url = pub_url(self.link.url, int(self.link.info["pub_port"]))
            core_id = self.link.info.get("core_id")
            if self.loaded and core_id is not None and core_id == self._core_id and url == self._pub \
                    and self.sub is not None:
                buffered, self._buffer = self._buffer, None
                if buffered:
                    self.publish(buffered)
                self.ready.set()
                return
            if url != self._pub or self.sub is None:
                self._open_sub(url)
                await asyncio.sleep(0.2)  # let the subscription reach the PUB socket (slow joiner)
            self._core_id = core_id
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
        """Read the feed in batches (see :data:`BATCH_GAP`) and publish each as one frame. A batch
        that already holds a pose batch of every team of the last pose period goes at once."""
        gap = max(1, round(BATCH_GAP * 1000))  # ms
        teams: set[Any] = set()  # the teams whose poses the last batch carried
        while True:
            try:
                frames = await sub.recv_multipart()
                first = time.monotonic()
                batch = [_event(frames)]
                posed = _posed(batch[0], set())
                while len(batch) < BATCH:
                    if not await sub.poll(0):
                        left = BATCH_SPAN - (time.monotonic() - first)
                        if (teams and posed >= teams) or left <= 0 \
                                or not await sub.poll(max(1, min(gap, int(left * 1000)))):
                            break
                    batch.append(_event(await sub.recv_multipart()))
                    posed = _posed(batch[-1], posed)
            except zmq.ZMQError:
                return
            if posed:
                teams = posed
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


def _posed(event: tuple[str, dict[str, Any]] | None, teams: set[Any]) -> set[Any]:
    """``teams``, and the team of ``event`` when it is a pose batch."""
    if event is not None and event[0] == "robot.positions":
        teams.add(event[1].get("team"))
    return teams


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
