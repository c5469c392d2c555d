"""Recorded matches in the browser: views of an event log with keyframes, played per browser.

A :class:`Recording` reads a core's ``STATE/events.log`` once. Each view of it (the public view,
or a team's or the referee's when a browser gives a token of the recorded match, found beside
the log) is a :class:`RecordingView`: the events that view may see, each serialised once, and a
**keyframe** (the whole state, as the page's ``state`` message holds it) every
:data:`KEYFRAME_EVERY` seconds of the recording. A seek takes the keyframe at or before the time
and the events from there to the time: it never replays from the start, whatever the length
of the match. Every browser has its own :class:`Playback` (play, pause, speed, position).
"""
from __future__ import annotations

import asyncio
import bisect
import contextlib
import hmac
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robo_comp import protocol as P
from robo_comp.errors import AuthError, FieldError
from robo_comp.protocol.logfile import read_recording
from robo_comp.view.model import MatchView
from robo_comp.view.score import ScoreFold
from robo_comp.web.state import TaskNames, jsonable, map_png, state_json
from robo_comp.view.story import Story

#: Seconds of recording between two keyframes.
KEYFRAME_EVERY = 10.0
#: Replay speeds a page may choose.
SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
#: Seconds between two sends of a playing replay.
TICK = 0.05


def _dump(obj: Any) -> str:
    try:
        return json.dumps(obj, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError):
        return json.dumps(jsonable(obj), separators=(",", ":"))


@dataclass
class RecordingView:
    """One view of a recording: its events (JSON fragments) and keyframes."""

    name: str
    kind: str
    times: list[float] = field(default_factory=list)
    frags: list[str] = field(default_factory=list)
    key_times: list[float] = field(default_factory=list)
    key_index: list[int] = field(default_factory=list)  # events applied before each keyframe
    key_json: list[str] = field(default_factory=list)
    pictures: dict[int, str | None] = field(default_factory=dict)  # picture id -> its team
    videos: dict[int, str | None] = field(default_factory=dict)  # video id -> its team
    story_json: str = "{}"  # the view's whole story (ticker, markers, score over time)

    def seek_text(self, at: float, duration: float) -> str:
        """The ``state`` message of the moment ``at``: the keyframe before it plus the events after."""
        at = min(max(0.0, at), duration)
        k = max(0, bisect.bisect_right(self.key_times, at) - 1)
        i = self.key_index[k]
        j = bisect.bisect_right(self.times, at)
        info = _dump({"name": self.name, "kind": self.kind})
        return (f'{{"type":"state","live":false,"view":{info},"t":{at:.3f},"duration":{duration:.3f},'
                f'"state":{self.key_json[k]},"after":[{",".join(self.frags[i:j])}]}}')

    def between(self, a: float, b: float) -> str:
        """The events in ``(a, b]`` as a JSON list's inside."""
        i = bisect.bisect_right(self.times, a)
        j = bisect.bisect_right(self.times, b)
        return ",".join(self.frags[i:j])


class Recording:
    """A match's event log, its views (built on first use) and the tokens beside it."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.records, _ = read_recording(self.path)
        self.t0 = self.records[0].t if self.records else 0.0
        self.duration = self.records[-1].t - self.t0 if self.records else 0.0
        self.tokens = _tokens_beside(self.path)
        #: Who the match let see its debug drawing in replays (its ``core.started`` says; see protocol.topics).
        self.debug_replay = next((str(r.data.get("debug_replay") or "team") for r in self.records
                                  if r.topic == "core.started"), "team")
        self.start = self._start()
        self._views: dict[str, RecordingView] = {}
        self._lock = asyncio.Lock()

    def _start(self) -> float:
        """Where a replay opens without a time: when the match started running (or, without
        phases, when the first robot came), never on the empty arena of the log's first second."""
        first_robot = None
        for rec in self.records:
            if rec.topic == "match.phase" and rec.data.get("phase") == "running":
                return max(0.0, rec.t - self.t0)
            if first_robot is None and rec.topic in ("robot.registered", "robot.positions"):
                first_robot = rec.t - self.t0
        return min(self.duration, first_robot + 1.0) if first_robot is not None else 0.0

    def summary(self) -> dict[str, Any]:
        """What the page learns in ``hello``: the length and where to open."""
        return {"duration": self.duration, "start": round(self.start, 3)}

    def view_for_token(self, token: str) -> str:
        """The view a token of the recorded match opens (a team's name or ``referee``)."""
        for name, tok in self.tokens.items():
            if hmac.compare_digest(tok.encode(), token.strip().encode()):
                return name
        raise AuthError("this token is not one of the recorded match's (they are read from the teams/ folder "
                        "and referee.token beside the log)")

    async def view(self, name: str = "public") -> RecordingView:
        """The view ``name`` (``public``, a team or ``referee``), built once in a worker thread."""
        async with self._lock:
            v = self._views.get(name)
            if v is None:
                v = self._views[name] = await asyncio.to_thread(self.build, name)
            return v

    def build(self, name: str) -> RecordingView:
        """Filter the records for the view and make its keyframes."""
        kind = "public" if name == "public" else "private"
        v = RecordingView(name, kind)
        now = [0.0]
        model = MatchView(clock=lambda: now[0])
        model.replay = True
        tasks = TaskNames()
        fold = ScoreFold()  # the scores, read as the wall's replay reads them
        story = Story(limit=None)
        see = P.EventView(name)  # the one visibility table (protocol/topics.py)
        maps: dict[int, str] = {}
        next_key = 0.0
        for rec in self.records:
            t = rec.t - self.t0
            while t > next_key and model.arena is not None:
                self._keyframe(v, model, tasks, maps, next_key, now)
                next_key += KEYFRAME_EVERY
            if rec.topic in ("picture", "video") and isinstance(rec.data.get("id"), int):
                (v.pictures if rec.topic == "picture" else v.videos)[rec.data["id"]] = rec.data.get("team") or rec.team
            table = fold.feed(rec.topic, rec.data)  # every view: the core publishes its table to everyone
            data = see(rec.topic, rec.team, rec.data)
            now[0] = t
            if data is not None:
                model.apply(rec.topic, data)
                tasks.apply(rec.topic, data)
                story.follow(model, rec.topic, data, t)
                if rec.topic != "core.started":  # the page gets the arena from a keyframe
                    v.times.append(t)
                    v.frags.append(_dump([rec.topic, data, round(t, 3)]))
            if table is not None:
                model.apply("score", table)
                story.follow(model, "score", table, t)
                v.times.append(t)
                v.frags.append(_dump(["score", table, round(t, 3)]))
        while model.arena is not None and (not v.key_times or next_key <= self.duration):
            self._keyframe(v, model, tasks, maps, next_key, now)
            next_key += KEYFRAME_EVERY
        if not v.key_times:
            raise FieldError(f"{self.path}: the log holds no arena to show")
        v.story_json = _dump(dict(story.to_json(), end_clock=model.match.now(self.duration)[0]
                                  if model.match.phase else None))
        return v

    def _keyframe(self, v: RecordingView, model: MatchView, tasks: TaskNames, maps: dict[int, str],
                  at: float, now: list[float]) -> None:
        if model.arena_version not in maps:
            maps[model.arena_version] = map_png(model)
        keep = now[0]
        now[0] = at
        v.key_times.append(at)
        v.key_index.append(len(v.frags))
        v.key_json.append(_dump(state_json(model, at, map_url=maps[model.arena_version], tasks=tasks.names)))
        now[0] = keep

    def picture(self, view: RecordingView, pid: int) -> str:
        """Picture ``pid`` as a data URL, if the view may see it and it is beside the log."""
        if view.kind == "public" or (view.name != "referee" and view.pictures.get(pid) != view.name):
            raise FieldError("pictures belong to the team that took them: enter that team's token to see them")
        p = self.path.parent / "pictures" / f"{int(pid)}.png"
        if not p.is_file():
            raise FieldError(f"picture {pid} is not beside this log (pictures/{pid}.png)")
        import base64

        return "data:image/png;base64," + base64.b64encode(p.read_bytes()).decode()


    def video(self, view: RecordingView, vid: int) -> str:
        """Video ``vid`` as a data URL, if the view may see it and it is beside the log."""
        if view.kind == "public" or (view.name != "referee" and view.videos.get(vid) != view.name):
            raise FieldError("videos belong to the team that filmed them: enter that team's token to see them")
        p = self.path.parent / "videos" / f"{int(vid)}.webm"
        if not p.is_file():
            raise FieldError(f"video {vid} is not beside this log (videos/{vid}.webm)")
        import base64

        return "data:video/webm;base64," + base64.b64encode(p.read_bytes()).decode()


def _tokens_beside(log: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    with contextlib.suppress(OSError):
        if (log.parent / "referee.token").is_file():
            out["referee"] = (log.parent / "referee.token").read_text().strip()
        for p in sorted((log.parent / "teams").glob("*.token")):
            out[p.stem] = p.read_text().strip()
    return {k: v for k, v in out.items() if v}


class Playback:
    """One browser's replay: its view, position, speed and whether it plays."""

    def __init__(self, recording: Recording, send: Any) -> None:
        self.rec = recording
        self.send = send  # async callable(text)
        self.view: RecordingView | None = None
        self.at = 0.0
        self.speed = 1.0
        self.playing = False
        self._task: asyncio.Task[None] | None = None

    async def open(self, view: RecordingView, at: float, *, play: bool, speed: float) -> None:
        """Show ``view`` from ``at`` seconds (its story first, when the view changes)."""
        if view is not self.view:
            await self.send(f'{{"type":"story","view":{_dump(view.name)},"story":{view.story_json}}}')
        self.view = view
        self.set_speed(speed)
        await self.seek(at)
        if play:
            await self.play()

    def set_speed(self, speed: Any) -> None:
        """0.25× to 16× (other values are refused)."""
        if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not 0.25 <= speed <= 16:
            raise FieldError(f"the replay speed must be between 0.25 and 16, not {speed!r}")
        self.speed = float(speed)

    async def seek(self, at: Any) -> float:
        """Jump to ``at`` seconds; returns how long building the message took (seconds)."""
        if isinstance(at, bool) or not isinstance(at, (int, float)) or at != at:
            raise FieldError("'t' must be a number of seconds into the match")
        assert self.view is not None
        t = time.perf_counter()
        self.at = min(max(0.0, float(at)), self.rec.duration)
        if self.rec.duration - self.at < 0.0005:  # the page has the duration to the millisecond
            self.at = self.rec.duration  # (rounded down, its "the end" left out the last records)
        text = self.view.seek_text(self.at, self.rec.duration)
        took = time.perf_counter() - t
        await self.send(text)
        await self._clock()
        return took

    async def play(self) -> None:
        """Play from the current position (from the start when at the end)."""
        if self.at >= self.rec.duration:
            await self.seek(0.0)
        self.playing = True
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._run())
        await self._clock()

    async def pause(self) -> None:
        """Stop where it is."""
        self.playing = False
        await self._clock()

    async def _clock(self) -> None:
        await self.send(_dump({"type": "clock", "t": round(self.at, 3), "playing": self.playing,
                               "speed": self.speed, "duration": self.rec.duration}))

    async def _run(self) -> None:
        last = time.monotonic()
        while self.playing and self.view is not None:
            await asyncio.sleep(TICK)
            now = time.monotonic()
            new = min(self.rec.duration, self.at + (now - last) * self.speed)
            last = now
            if not self.playing:
                break
            chunk = self.view.between(self.at, new)
            self.at = new
            await self.send(f'{{"type":"ev","t":{new:.3f},"e":[{chunk}]}}')
            if new >= self.rec.duration:
                self.playing = False
                await self._clock()

    def close(self) -> None:
        """Stop playing."""
        self.playing = False
        if self._task is not None:
            self._task.cancel()
