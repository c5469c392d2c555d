"""The wall's picture of the match as plain data: fed by a snapshot, then by events.

No pygame here: the same model serves the live wall, replays, tests and the benchmark.
Every topic the core publishes (or will publish) is applied by :meth:`MatchView.apply`;
unknown topics are ignored, so the wall keeps working when the core learns new events.
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robo_comp.protocol import unpack_walls
from robo_comp.protocol.clock import HeardClock
from robo_comp.protocol.topics import readable

#: Trail points kept per robot (the last N positions at least ``TRAIL_STEP`` cells apart).
TRAIL_LEN = 48
TRAIL_STEP = 0.5
#: Messages kept for the message bar.
MESSAGES_KEPT = 6
#: Seconds a message stays on the wall.
MESSAGE_SECONDS = 12.0
GREY = "#808080"


def find_state(f: dict[str, Any]) -> str:
    """A find's state (``confirmed``, ``rejected``, ``duplicate``, ``reported``), from its
    ``state`` or, in a snapshot's records, its verdict: the same in every view (wall, web)."""
    if f.get("state"):
        return str(f["state"])
    v = f.get("verdict") or {}
    return "confirmed" if v.get("valid") else ("duplicate" if v.get("duplicate") else ("rejected" if v else "reported"))


@dataclass
class Arena:
    """The static map: size in cells, walls ``[y, x]``, zones, known objects and teams."""

    name: str
    width: int
    height: int
    cell_cm: float
    walls: np.ndarray
    zones: list[dict[str, Any]] = field(default_factory=list)
    objects: list[dict[str, Any]] = field(default_factory=list)
    teams: list[dict[str, Any]] = field(default_factory=list)
    costs: np.ndarray | None = None  # cell costs [y, x] from the map service, when it sent them

    @classmethod
    def from_payload(cls, a: dict[str, Any]) -> Arena:
        """Build from the core's ``arena`` payload (walls np.packbits, row-major)."""
        return cls(str(a.get("name", "")), int(a["width"]), int(a["height"]), float(a.get("cell_cm", 25.0)),
                   unpack_walls(a), list(a.get("zones") or []), list(a.get("objects") or []),
                   list(a.get("teams") or []))

    def colour(self, team: str | None) -> str:
        """The team's ``#rrggbb`` display colour (grey for unknown teams)."""
        for t in self.teams:
            if t.get("name") == team:
                return str(t.get("colour") or GREY)
        return GREY


@dataclass(slots=True)
class Robot:
    """One robot as the wall knows it."""

    tag: int
    team: str | None
    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    status: str = "connected"  # connected, lost, left, disqualified
    moving: bool = False
    sigma: float = 0.0  # position uncertainty (cells): drawn as a ring when it grows
    robot_id: str = ""
    trail: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=TRAIL_LEN))
    trail_n: int = 0  # points ever appended (renderers convert only the new ones)

    def move(self, x: float, y: float, heading: float) -> None:
        """New position; extends the trail when the robot moved far enough."""
        if not self.trail or abs(self.trail[-1][0] - x) + abs(self.trail[-1][1] - y) >= TRAIL_STEP:
            self.trail.append((x, y))
            self.trail_n += 1
        self.x, self.y, self.heading = x, y, heading


@dataclass(slots=True)
class Thing:
    """Something on the map a user can click: a find, a discovery, a known object, a picture or a
    video."""

    kind: str  # "find", "discovery", "object", "picture", "video"
    id: Any
    x: float
    y: float
    team: str | None = None
    state: str = ""
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def key(self) -> str:
        """A stable identifier such as ``find:3``."""
        return f"{self.kind}:{self.id}"

    def pictures(self) -> list[int]:
        """Picture ids that belong to this thing (evidence of a find, or the picture itself)."""
        if self.kind == "picture":
            return [int(self.id)]
        return [int(p) for p in self.info.get("evidence") or [] if isinstance(p, int)]

    def videos(self) -> list[int]:
        """Video ids that belong to this thing (the video itself)."""
        return [int(self.id)] if self.kind == "video" else []


@dataclass(slots=True)
class Message:
    """A line on the wall's message bar (``level``: info, error, broadcast)."""

    text: str
    level: str
    t: float


class MatchView:
    """Everything the wall draws. ``version`` changes whenever something visible changes."""

    def __init__(self, clock: Any = time.monotonic) -> None:
        self.clock = clock
        self.arena_version = 0
        self.version = 0
        self.panel_version = 0  # changes with everything but positions (the panel redraws on it)
        #: Changes when :meth:`reset` forgets the match (a viewer drops what it kept of it).
        self.generation = 0
        self.replay = False  # set by a replay source: the clock line then shows the recording's time
        self._forget()

    def _forget(self) -> None:
        self.arena: Arena | None = None
        self.robots: dict[int, Robot] = {}
        self.things: dict[str, Thing] = {}
        self.match = HeardClock()
        self.score: list[dict[str, Any]] = []
        self.messages: deque[Message] = deque(maxlen=MESSAGES_KEPT)
        self.events = 0
        #: Events not folded: they lacked what the topic table says they carry.
        self.skipped = 0
        #: The core's storage fault while it lasts (its event log cannot be written), else None.
        self.storage: str | None = None
        #: Team code's debug drawing: each robot's newest frame (robo_comp/protocol/drawing.py),
        #: only in views that may see it (the team's own; a replay as the match chose).
        self.debug: dict[int, list[list[Any]]] = {}

    def reset(self) -> None:
        """Forget the match (a replay seeking back plays its log again from the start); the
        clock, the replay flag and the version counters go on (every one changes)."""
        self._forget()
        self.arena_version += 1
        self.version += 1
        self.panel_version += 1
        self.generation += 1

    # ------------------------------------------------------------------ feeding
    def set_arena(self, payload: dict[str, Any]) -> None:
        """Replace the static map."""
        self.arena = Arena.from_payload(payload)
        self.arena_version += 1
        self.things = {k: t for k, t in self.things.items() if t.kind != "object"}
        for o in self.arena.objects:
            t = Thing("object", o.get("id"), float(o.get("x", 0)), float(o.get("y", 0)), info=dict(o))
            self.things[t.key] = t
        self.version += 1
        self.panel_version += 1

    def set_costs(self, costs: np.ndarray) -> None:
        """Cell costs from the map service (shaded on the map); ignored if the shape differs."""
        if self.arena is not None and costs.shape == self.arena.walls.shape:
            self.arena.costs = costs
            self.arena_version += 1
            self.version += 1

    def merge_find(self, record: dict[str, Any]) -> None:
        """Add what this token may know beyond the public event (evidence, verdict) to a find."""
        self._find(record)
        self.version += 1
        self.panel_version += 1

    def load_snapshot(self, snap: dict[str, Any]) -> None:
        """Start from a ``snapshot`` reply (arena, robots and, when present, match, score, finds,
        videos)."""
        self.set_arena(snap["arena"])
        self.robots.clear()
        for row in snap.get("robots") or []:
            r = self._robot(row["tag"], row.get("team"))
            r.status = row.get("status", "connected")
            r.robot_id = row.get("robot_id", "")
            r.moving = bool(row.get("moving", False))
            r.move(float(row.get("x", 0)), float(row.get("y", 0)), float(row.get("heading", 0)))
        if snap.get("match"):
            self._match(snap["match"])
        if snap.get("score") is not None:
            self.score = list(snap["score"])
        for f in snap.get("finds") or []:
            self._find(f)
        for v in snap.get("videos") or []:
            _on_video(self, v)
        self.version += 1
        self.panel_version += 1

    def apply(self, topic: str, d: dict[str, Any]) -> None:
        """Apply one event (public or full view); unknown topics are ignored, and so is an event
        that lacks what protocol/topics.py's table says it carries (counted in ``skipped``)."""
        self.events += 1
        if not readable(topic, d):
            self.skipped += 1
            return
        handler = _HANDLERS.get(topic)
        if handler is not None:
            handler(self, d)
            self.version += 1
            if topic != "robot.positions":
                self.panel_version += 1

    def note(self, text: str, level: str = "info") -> None:
        """Put a line on the message bar (refusals use ``level="error"``)."""
        self.messages.append(Message(text, level, self.clock()))
        self.version += 1

    def visible_messages(self, at: float | None) -> list[Message]:
        """Messages still on the bar at ``at`` (all kept ones when ``at`` is None)."""
        return [m for m in self.messages if at is None or at - m.t < MESSAGE_SECONDS]

    # ------------------------------------------------------------------ helpers
    def colour(self, team: str | None) -> str:
        """A team's display colour."""
        return self.arena.colour(team) if self.arena else GREY

    def teams(self) -> list[str]:
        """Team names in arena order."""
        return [t["name"] for t in self.arena.teams] if self.arena else []

    def _robot(self, tag: int, team: str | None = None) -> Robot:
        r = self.robots.get(tag)
        if r is None:
            r = self.robots[tag] = Robot(tag, team)
        elif team is not None and r.team is None:
            r.team = team
        return r

    def _match(self, m: dict[str, Any]) -> None:
        if m.get("phase"):
            self.match.phase = str(m["phase"])
        if m.get("elapsed") is not None:
            self.match.elapsed = float(m["elapsed"])
        if "remaining" in m:
            self.match.remaining = None if m["remaining"] is None else float(m["remaining"])
        self.match.heard_at = self.clock()

    def _find(self, f: dict[str, Any]) -> None:
        t = Thing("find", f.get("id"), float(f.get("x", 0)), float(f.get("y", 0)), f.get("team"), find_state(f),
                  {k: v for k, v in f.items() if k != "verdict"})
        if isinstance(f.get("verdict"), dict) and "message" not in t.info:
            t.info["message"] = f["verdict"].get("reason", "")
        self.things[t.key] = t


def _on_positions(m: MatchView, d: dict[str, Any]) -> None:
    """A batch of poses (the live feed's per team, or a log's for all teams). It moves robots
    but does not change their status: ``robot.returned`` says when a lost robot is back."""
    team = d.get("team")
    xs, ys, hs = d["x"], d["y"], d["heading"]
    moving = d.get("moving") or [True] * len(xs)
    sigma = d.get("sigma") or [0.0] * len(xs)
    for i, tag in enumerate(d["tags"]):
        r = m._robot(tag, team)
        r.move(float(xs[i]), float(ys[i]), float(hs[i]))
        r.moving = bool(moving[i])
        r.sigma = float(sigma[i])


def _on_registered(m: MatchView, d: dict[str, Any]) -> None:
    r = m._robot(d["tag"], d.get("team"))
    r.status = "connected"
    r.robot_id = d.get("robot_id", r.robot_id)
    r.move(float(d.get("x", r.x)), float(d.get("y", r.y)), float(d.get("heading", r.heading)))


def _status(status: str) -> Any:
    def apply(m: MatchView, d: dict[str, Any]) -> None:
        r = m._robot(d["tag"], d.get("team"))
        r.status = status
        r.moving = False
        if "x" in d and "y" in d:
            r.move(float(d["x"]), float(d["y"]), r.heading)
    return apply


def _on_disqualified(m: MatchView, d: dict[str, Any]) -> None:
    for tag in d.get("tags") or []:
        m._robot(tag).status = "disqualified"
    who = d.get("team") or ", ".join(str(t) for t in d.get("tags") or [])
    m.note(f"disqualified {who}: {d.get('reason', '')}", "error")


def _on_stopped(m: MatchView, d: dict[str, Any]) -> None:
    r = m._robot(d["tag"], d.get("team"))
    r.moving = False
    if "x" in d and "y" in d:
        r.move(float(d["x"]), float(d["y"]), r.heading)


def _on_core_started(m: MatchView, d: dict[str, Any]) -> None:
    if d.get("arena"):
        m.set_arena(d["arena"])


def _on_score(m: MatchView, d: dict[str, Any]) -> None:
    if d.get("teams") is not None:
        m.score = list(d["teams"])
    if d.get("phase"):
        m._match(d)


def _on_discovery(m: MatchView, d: dict[str, Any]) -> None:
    t = Thing("discovery", d.get("id"), float(d.get("x", 0)), float(d.get("y", 0)), d.get("team"),
              str(d.get("state", "discovered")), dict(d))
    m.things[t.key] = t


def _on_picture(m: MatchView, d: dict[str, Any]) -> None:
    t = Thing("picture", d.get("id"), float(d.get("x", 0)), float(d.get("y", 0)), d.get("team"), "", dict(d))
    m.things[t.key] = t


def _on_video(m: MatchView, d: dict[str, Any]) -> None:
    t = Thing("video", d.get("id"), float(d.get("x", 0)), float(d.get("y", 0)), d.get("team"), "", dict(d))
    m.things[t.key] = t


def _on_broadcast(m: MatchView, d: dict[str, Any]) -> None:
    m.note(str(d.get("message") or ""), "broadcast")


def _on_storage(m: MatchView, d: dict[str, Any]) -> None:
    """The core cannot write its event log (kept on the bar until it can), or can again."""
    if d.get("ok"):
        m.storage = None
        m.note(str(d.get("message") or "the core writes its event log again"), "info")
    else:
        m.storage = str(d.get("message") or "the core cannot write its event log")
        m.note(m.storage, "error")


def _on_debug(m: MatchView, d: dict[str, Any]) -> None:
    """Robots' new frames of debug drawing (an empty frame clears the robot's drawing)."""
    for tag, frame in zip(d.get("tags") or [], d.get("frames") or []):
        if not isinstance(tag, int):
            continue
        if frame:
            m.debug[tag] = list(frame)
        else:
            m.debug.pop(tag, None)


def _on_penalty(m: MatchView, d: dict[str, Any]) -> None:
    m.note(f"penalty {d.get('team')}: {d.get('points')} ({d.get('reason', '')})", "error")


_HANDLERS: dict[str, Any] = {
    "robot.positions": _on_positions,
    "robot.registered": _on_registered,
    "robot.returned": _status("connected"),
    "robot.lost": _status("lost"),
    "robot.left": _status("left"),
    "robot.stopped": _on_stopped,
    "disqualified": _on_disqualified,
    "core.started": _on_core_started,
    "match.phase": lambda m, d: m._match(d),
    "score": _on_score,
    "find.reported": lambda m, d: m._find(d),
    "map.discovery": _on_discovery,
    "picture": _on_picture,
    "video": _on_video,
    "broadcast": _on_broadcast,
    "penalty": _on_penalty,
    "core.storage": _on_storage,
    "debug.draw": _on_debug,
}
