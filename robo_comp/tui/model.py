"""What a console knows about the match, kept up to date from replies and pushed events.

Widgets never talk to the core: they draw from a :class:`ConsoleModel`, which the app fills
from the ``snapshot`` reply and then from every event. Plain data and no Textual here, so
the model is easy to test and to feed with canned data (the snapshot tests do).
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robo_comp.protocol import unpack_walls
from robo_comp.protocol.clock import HeardClock
from robo_comp.protocol.topics import readable

#: Events kept for the log pane and the monitor's "recent events".
MAX_EVENTS = 2000
#: Topics too chatty for the event log.
QUIET_TOPICS = frozenset({"robot.positions"})
#: Topics about one robot that change its row (when the model knows the robot).
ROW_TOPICS = frozenset({"robot.lost", "robot.left", "robot.stopped", "task.given", "task.started", "task.done"})


@dataclass
class LogEntry:
    """One line of the event log."""

    t: float
    topic: str
    team: str | None
    data: dict[str, Any]

    @property
    def tag(self) -> int | None:
        """The robot the event is about, if any."""
        tag = self.data.get("tag", self.data.get("from"))
        return tag if isinstance(tag, int) else None


@dataclass
class ConsoleModel:
    """Robots, match, scores, finds and events as one console sees them."""

    role: str = ""
    team: str | None = None
    robots: dict[int, dict[str, Any]] = field(default_factory=dict)
    details: dict[int, dict[str, Any]] = field(default_factory=dict)
    match: HeardClock = field(default_factory=lambda: HeardClock("?"))
    scores: list[dict[str, Any]] = field(default_factory=list)
    teams: list[str] = field(default_factory=list)
    finds: list[dict[str, Any]] = field(default_factory=list)
    walls: np.ndarray | None = None
    arena_name: str = ""
    events: deque[LogEntry] = field(default_factory=lambda: deque(maxlen=MAX_EVENTS))
    pending_uploads: dict[Any, dict[str, Any]] = field(default_factory=dict)
    broadcasts: list[str] = field(default_factory=list)
    queued_ids: dict[int, set[Any]] = field(default_factory=dict)
    #: What a core outage does to the match clock (``pause``/``count``; None: the core did not say).
    outage: str | None = None
    #: What the core recovered from its event log when it started (the ``recovered`` part of
    #: ``stats``, or a ``core.recovered`` event): None for a core that started on an empty folder
    #: (or before the referee console asked).
    recovered: dict[str, Any] | None = None
    #: True once the core said what it recovered (``stats`` answered, or ``core.recovered`` came).
    recovery_known: bool = False
    clock: Callable[[], float] = time.monotonic
    wall_clock: Callable[[], float] = time.time
    version: int = 0

    # ------------------------------------------------------------------ loading
    def load_snapshot(self, snap: dict[str, Any]) -> None:
        """Replace everything with a ``snapshot`` reply."""
        arena = snap.get("arena") or {}
        if arena.get("walls") is not None:
            try:
                self.walls = unpack_walls(arena)
            except Exception:
                self.walls = None
        self.arena_name = arena.get("name", "")
        self.teams = list(snap.get("teams") or [])
        self.set_robots(snap.get("robots") or [])
        self.details = {t: d for t, d in self.details.items() if t in self.robots}
        self.set_match(snap.get("match") or {})
        self.set_scores(snap.get("score") or [])
        self.finds = list(snap.get("finds") or [])
        self.touch()

    def set_robots(self, rows: list[dict[str, Any]]) -> None:
        """Take a ``robots`` listing (the truth: it corrects anything events missed)."""
        self.robots = {r["tag"]: dict(r) for r in rows}
        self.queued_ids = {t: ids for t, ids in self.queued_ids.items() if t in self.robots}
        self.touch()

    def touch(self) -> None:
        """Mark the model changed (widgets redraw on their next refresh)."""
        self.version += 1

    def set_match(self, m: dict[str, Any]) -> None:
        """Take a phase/clock report (``match`` reply, ``match.phase`` or ``score`` event)."""
        if m.get("outage") in ("pause", "count"):
            self.outage = m["outage"]
        if "phase" not in m:
            return
        self.match = HeardClock(m.get("phase", "?"), float(m.get("elapsed") or 0.0),
                               None if m.get("remaining") is None else float(m["remaining"]), self.clock())
        self.touch()

    def set_scores(self, rows: list[dict[str, Any]]) -> None:
        """Take a score table."""
        self.scores = sorted((dict(r) for r in rows), key=lambda r: r.get("rank", 0))
        self.touch()

    def set_recovery(self, recovered: dict[str, Any] | None) -> None:
        """Take what the core recovered from its log (None: it started on an empty folder)."""
        self.recovered = dict(recovered) if recovered else None
        self.recovery_known = True
        self.touch()

    def set_detail(self, tag: int, monitor: dict[str, Any]) -> None:
        """Take a ``monitor`` reply for robot ``tag``."""
        self.details[tag] = monitor
        row = self.robots.setdefault(tag, {"tag": tag})
        for k in ("team", "robot_id", "status", "x", "y", "heading", "moving", "task", "queue"):
            if k in monitor:
                row[k] = monitor[k]
        self.touch()

    # ------------------------------------------------------------------ queries
    def my_score(self) -> dict[str, Any] | None:
        """This team's score row (None for the referee or before any score arrived)."""
        return next((r for r in self.scores if r.get("team") == self.team), None)

    def recent(self, tag: int, n: int = 8) -> list[LogEntry]:
        """The last ``n`` logged events about robot ``tag``, newest last."""
        out = [e for e in reversed(self.events) if e.tag == tag]
        return list(reversed(out[:n]))

    # ------------------------------------------------------------------ events
    def apply(self, topic: str, team: str | None, data: dict[str, Any]) -> LogEntry | None:
        """Fold one pushed event into the model; return the log entry (None for quiet topics, and
        for an event that lacks what protocol/topics.py's table says it carries: not folded)."""
        if not readable(topic, data):
            return None
        tag = data.get("tag")
        if topic in ("robot.registered", "robot.returned"):
            if isinstance(tag, int):  # what the core sends; an event without one names no robot
                row = self.robots.setdefault(tag, {"tag": tag, "team": data.get("team", team), "task": None,
                                                   "queue": 0, "heading": 0.0})
                row.update({k: data[k] for k in ("x", "y", "heading", "robot_id") if k in data})
                row["status"] = "connected"
                if "tasks" in data and tag in self.details:
                    self.details[tag]["advertised"] = data["tasks"]
        elif topic == "robot.positions":
            cols = [(k, data[k]) for k in ("x", "y", "heading", "moving", "sigma") if k in data]  # once a batch
            for i, t in enumerate(data.get("tags") or ()):
                pose = self.robots.get(t)
                if pose is not None:
                    for k, col in cols:
                        pose[k] = col[i]
        elif topic in ROW_TOPICS and isinstance(tag, int) and tag in self.robots:
            self._apply_to_row(topic, tag, self.robots[tag], data)
        elif topic == "match.phase":
            self.set_match(data)
        elif topic == "score":
            self.set_scores(data.get("teams") or [])
            self.set_match(data)
        elif topic == "find.reported":
            self.finds.append(dict(data))
        elif topic == "disqualified":
            for t in data.get("tags") or []:
                if t in self.robots:
                    self.robots[t]["status"] = "disqualified"
        elif topic == "upload.pending":
            self.pending_uploads[data.get("upload_id")] = dict(data)
        elif topic == "upload.done" and data.get("upload_id") in self.pending_uploads:
            self.pending_uploads.pop(data.get("upload_id"), None)
        elif topic == "broadcast":
            self.broadcasts.append(str(data.get("message", "")))
        elif topic == "core.recovered":
            self.set_recovery(data)
        # keep the monitor detail in step
        if isinstance(tag, int) and tag in self.details and topic.startswith("task."):
            self._detail_task(tag, topic, data)
        self.touch()
        if topic in QUIET_TOPICS:
            return None
        entry = LogEntry(self.wall_clock(), topic, team, data)
        self.events.append(entry)
        return entry

    def _apply_to_row(self, topic: str, tag: int, row: dict[str, Any], data: dict[str, Any]) -> None:
        """Fold an event of :data:`ROW_TOPICS` about robot ``tag`` into its row."""
        if topic == "robot.lost":
            row.update(status="lost", moving=False)
        elif topic == "robot.left":
            row.update(status="left", moving=False)
        elif topic == "robot.stopped":
            self.queued_ids.pop(tag, None)
            row.update(moving=False, task=None, queue=0)
            row.update({k: data[k] for k in ("x", "y") if k in data})
        elif topic == "task.given" and data.get("mode") == "queue":
            self.queued_ids.setdefault(tag, set()).add(data.get("task_id"))
            row["queue"] = int(row.get("queue") or 0) + 1
        elif topic == "task.started":
            if data.get("task_id") in self.queued_ids.get(tag, ()):
                self.queued_ids[tag].discard(data.get("task_id"))
                row["queue"] = max(0, int(row.get("queue") or 0) - 1)
            row["task"] = {"task_id": data.get("task_id"), "name": data.get("name"), "args": data.get("args"),
                           "state": "running"}
        elif topic == "task.done":
            cur = row.get("task")
            if cur and cur.get("task_id") == data.get("task_id"):
                row["task"] = None
            if data.get("task_id") in self.queued_ids.get(tag, ()):  # cancelled while queued
                self.queued_ids[tag].discard(data.get("task_id"))
                row["queue"] = max(0, int(row.get("queue") or 0) - 1)

    def _detail_task(self, tag: int, topic: str, data: dict[str, Any]) -> None:
        d = self.details[tag]
        queued = d.setdefault("queued", [])
        if topic == "task.given" and data.get("mode") == "queue":
            queued.append({"task_id": data.get("task_id"), "name": data.get("name"), "args": data.get("args"),
                           "state": "queued"})
        elif topic == "task.started":
            d["queued"] = [q for q in queued if q.get("task_id") != data.get("task_id")]
            d["task"] = {"task_id": data.get("task_id"), "name": data.get("name"), "args": data.get("args"),
                         "state": "running"}
        elif topic == "task.done":
            d["queued"] = [q for q in queued if q.get("task_id") != data.get("task_id")]
            if (d.get("task") or {}).get("task_id") == data.get("task_id"):
                d["task"] = None
            done = d.setdefault("done", [])
            done.append({"task_id": data.get("task_id"), "name": data.get("name"), "ok": data.get("ok"),
                         "state": data.get("state"), "status": data.get("status"), "result": data.get("result")})
            del done[:-50]


#: What each outage rule does to the match clock, in words (the referee console's line).
OUTAGE_WORDS = {"pause": "pauses the clock", "count": "counts as match time"}


def lost_events(recovered: dict[str, Any] | None) -> list[tuple[int, str | None]]:
    """``(seq, topic or None)`` of every event a recovery report says was lost, in order."""
    out: list[tuple[int, str | None]] = []
    for d in (recovered or {}).get("damages") or []:
        out += [(int(x["seq"]), x.get("topic")) for x in d.get("lost") or [] if isinstance(x, dict) and "seq" in x]
    seen = {s for s, _ in out}
    out += [(int(s), None) for s in (recovered or {}).get("lost") or [] if isinstance(s, int) and s not in seen]
    return sorted(out)


def fmt_clock(seconds: float | None) -> str:
    """``mm:ss`` (or ``h:mm:ss``); ``--:--`` for no limit."""
    if seconds is None:
        return "--:--"
    s = int(seconds)
    h, rest = divmod(s, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60:02d}:{rest % 60:02d}"


def task_label(task: dict[str, Any] | None) -> str:
    """``goTo(3, 4) #7`` or ``-``."""
    if not task:
        return "-"
    args = ", ".join(_short(a) for a in task.get("args") or [])
    return f"{task.get('name')}({args}) #{task.get('task_id')}"


def _short(v: Any) -> str:
    if isinstance(v, (list, tuple)):
        if v and all(isinstance(p, (list, tuple)) for p in v):
            return f"[{len(v)} pts]"
        return "(" + ", ".join(_short(x) for x in v) + ")"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def _teamwork_sentence(who: str, topic: str, d: dict[str, Any]) -> str:
    """A lost robot's tasks offered to its team, the team's reallocation setting, an obstacle."""
    if topic == "teamwork":
        return (f"reallocation of a lost robot's tasks turned {'ON' if d.get('reallocate') else 'off'} "
                f"by {d.get('by', '?')}")
    if topic == "map.obstacle":
        return f"{who} found an obstacle at ({d.get('x')}, {d.get('y')}): on the team's map"
    tasks = d.get("tasks") or []
    moved = [f"{task_label(t)} → robot {t['to']}" for t in tasks if t.get("to") is not None]
    waiting = [task_label(t) for t in tasks if t.get("to") is None]
    parts = []
    if moved:
        parts.append("moved " + ", ".join(moved))
    if waiting:
        parts.append(", ".join(waiting) + (" wait for it" if not d.get("reallocate") else " found no teammate")
                     + (" ('ctl teamwork on' moves them)" if not d.get("reallocate") else ""))
    return f"{who} {d.get('message', 'is gone')}: its task(s) offered to the team; " + "; ".join(parts)


def describe_event(e: LogEntry) -> str:
    """One readable sentence for an event log line."""
    d = e.data
    tag = d.get("tag")
    who = f"robot {tag}" if tag is not None else (e.team or "core")
    t = e.topic
    if t == "robot.registered":
        return f"{who} registered ({d.get('robot_id', '?')}) at ({d.get('x', 0):.1f}, {d.get('y', 0):.1f})"
    if t == "robot.returned":
        return f"{who} is back"
    if t == "robot.lost":
        return f"{who} is LOST: {d.get('message', 'no reports')}"
    if t == "robot.left":
        return f"{who} left the arena"
    if t == "robot.stopped":
        return f"{who} STOPPED in {d.get('ms', 0):.0f} ms; cancelled {len(d.get('cancelled') or [])} task(s)"
    if t == "task.given":
        return f"{who} was given {task_label(d)} ({d.get('mode', 'now')}) by {d.get('by', '?')}"
    if t == "task.started":
        return f"{who} started {task_label(d)}"
    if t == "task.done":
        # ok or not is told in words, not only by the line's colour
        verdict = "done" if d.get("ok") else "FAILED" if d.get("state", "done") == "done" else d.get("state")
        return f"{who} {d.get('name')} #{d.get('task_id')} {verdict}: {d.get('status', '')}"
    if t == "match.phase" and d.get("action") == "outage":
        return f"a core outage now {OUTAGE_WORDS.get(str(d.get('outage')), '?')} (rule {d.get('outage')!r}, by {d.get('by', '?')})"
    if t == "match.phase":
        return f"match {d.get('phase', '?').upper()} ({d.get('action', '')} by {d.get('by', '?')})"
    if t == "score":
        return "scores: " + ", ".join(f"{r.get('team')} {r.get('score')}" for r in d.get("teams") or [])
    if t == "score.change":
        return f"{d.get('team', e.team)} {d.get('points', 0):+g}: {d.get('reason', d.get('rule', ''))}"
    if t == "penalty":
        return f"PENALTY {d.get('team')} {d.get('points')} points: {d.get('reason', '')}"
    if t == "disqualified":
        target = f"team {d['team']}" if d.get("team") else f"robot(s) {', '.join(map(str, d.get('tags') or []))}"
        return f"DISQUALIFIED {target}: {d.get('reason', '')}"
    if t == "broadcast":
        return f"REFEREE: {d.get('message', '')}"
    if t == "refused":
        return f"refused {d.get('type', '?')} from {d.get('by', '?')}: {d.get('message', '')}"
    if t == "radio":
        return f"radio {d.get('from')} → {d.get('to') or 'all'} ({d.get('delivered', 0)} delivered)"
    if t == "find.reported":
        return f"{who} reported a find at ({d.get('x')}, {d.get('y')}): {d.get('state')} {d.get('message', '')}"
    if t == "picture":
        return f"{who} took picture {d.get('id')}"
    if t == "robot.bump":
        return f"{who} bumped at ({d.get('x')}, {d.get('y')})"
    if t == "upload.pending":
        return f"upload {d.get('upload_id')} of {d.get('team')} ({d.get('filename')}) awaits approval"
    if t == "core.storage":
        return (f"STORAGE FAULT: {d.get('message', '')}" if not d.get("ok") else
                f"storage OK again: {d.get('message', '')}")
    if t == "core.recovered":
        return (f"core RECOVERED {d.get('events', 0)} events: ⚠ LOG DAMAGED: {d['damage']}" if d.get("damage") else
                f"core recovered {d.get('events', 0)} events in {d.get('seconds', 0):.2f} s")
    if t == "sandbox.reset":
        return f"the referee restarted the sandbox of robot(s) {', '.join(map(str, d.get('tags') or []))}"
    if t == "upload.done":
        return f"upload to {d.get('tags')}: {'ok' if d.get('ok') else 'FAILED'} {d.get('message', '')}"
    if t in ("task.offered", "teamwork", "map.obstacle"):
        return _teamwork_sentence(who, t, d)
    rest = ", ".join(f"{k}={v}" for k, v in d.items() if k not in ("tag", "team"))[:120]
    return f"{who} {rest}"


__all__ = ["ConsoleModel", "LogEntry", "OUTAGE_WORDS", "describe_event", "fmt_clock", "lost_events", "task_label"]
