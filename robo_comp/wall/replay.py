"""Play a recorded match from the core's event log into a :class:`MatchView`, at any speed.

The log starts with ``core.started`` (which carries the arena), so a replay needs nothing but
the log; pictures are read from the ``pictures/`` folder beside it when it is there.
Positions are logged once a second per robot, so replayed robots move in 1 s steps. Scores
are folded from the log's ``score.change`` lines and final ``match.phase`` (:class:`ScoreFold`)
where it has no score tables of its own (a league match's log).

The story (ticker lines, the victims revealed at the finish) is told once, from the whole log,
when the replay opens (:class:`~robo_comp.view.story.Story`, as the web page's replay tells it);
the wall shows the lines up to the replay's position. Seeking back plays the log again from its
start into the model (:meth:`ReplaySource.jump`), so robots, trails, finds and the clock are
those of that moment.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from robo_comp.protocol.logfile import LogRecord, read_log
from robo_comp.errors import FieldError
from robo_comp.view.model import MatchView
from robo_comp.view.score import ScoreFold
from robo_comp.view.story import Story


class ReplaySource:
    """Feeds a model with a log's events as replay time passes (``speed`` × real time)."""

    def __init__(self, path: str | Path, speed: float = 1.0, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FieldError(f"--replay {path}: no such event log (it is STATE/events.log of a core)")
        try:
            self.records: list[LogRecord] = list(read_log(self.path, strict=False))
        except OSError as e:
            raise FieldError(f"cannot read the event log {path}: {e.strerror}") from None
        if speed <= 0:
            raise FieldError("--speed must be above 0")
        self.speed = speed
        self.clock = clock
        self.t0 = self.records[0].t if self.records else 0.0
        self.next = 0
        self.started: float | None = None
        self.offset = 0.0
        self.paused = False
        self.shown = 0.0  # the recording's time the model shows
        self.scores = ScoreFold()
        self.story = self.tell()

    def tell(self) -> Story:
        """The whole recording's story, on its timeline (seconds from the first record)."""
        story = Story(limit=None)
        now = [0.0]
        model = MatchView(clock=lambda: now[0])  # for the match clock only: no poses
        model.replay = True
        fold = ScoreFold()
        for rec in self.records:
            if rec.topic == "robot.positions":
                continue
            now[0] = t = rec.t - self.t0
            model.apply(rec.topic, rec.data)
            story.follow(model, rec.topic, rec.data, t)
            table = fold.feed(rec.topic, rec.data)
            if table is not None:
                model.apply("score", table)
                story.follow(model, "score", table, t)
        return story

    @property
    def duration(self) -> float:
        """Seconds from the first to the last record."""
        return self.records[-1].t - self.t0 if self.records else 0.0

    @property
    def done(self) -> bool:
        """True once every record was applied."""
        return self.next >= len(self.records)

    def replay_time(self) -> float:
        """Seconds of the recording shown so far (the model's clock during a replay); it stops
        at the recording's end, and while paused."""
        if self.started is None or self.paused:
            return min(self.offset, self.duration)
        return min(self.offset + (self.clock() - self.started) * self.speed, self.duration)

    def attach(self, model: MatchView) -> None:
        """Make the model's clock the replay's (so the match timer runs at replay speed)."""
        model.clock = self.replay_time
        model.replay = True

    def advance(self, model: MatchView) -> int:
        """Apply the records that are due; return how many."""
        if self.started is None:
            self.started = self.clock()
        return self.seek(model, self.replay_time())

    def seek(self, model: MatchView, at: float) -> int:
        """Show the recording at ``at`` seconds: apply every record up to there (from the start
        again, into a reset model, when ``at`` is before what the model shows); return how many."""
        n = 0
        recs = self.records
        if at < self.shown - 1e-9:
            model.reset()
            self.next = 0
            self.scores = ScoreFold()
        self.shown = at
        while self.next < len(recs) and recs[self.next].t - self.t0 <= at:
            rec = recs[self.next]
            model.apply(rec.topic, rec.data)
            table = self.scores.feed(rec.topic, rec.data)
            if table is not None:
                model.apply("score", table)
            self.next += 1
            n += 1
        if self.started is None:
            self.offset = at
        return n

    def jump(self, model: MatchView, at: float) -> float:
        """The user seeks: go on from ``at`` seconds (kept within the recording), playing or
        paused as before; returns where."""
        at = min(max(0.0, at), self.duration)
        self.seek(model, at)
        self.offset = at
        if self.started is not None:
            self.started = self.clock()
        return at

    def toggle_pause(self) -> bool:
        """Pause or play on; returns True when now paused."""
        if self.paused:
            self.paused = False
            self.started = self.clock()
        else:
            self.offset = self.replay_time()
            self.paused = True
        return self.paused

    def picture(self, pid: int) -> bytes:
        """A picture from the ``pictures/`` folder beside the log."""
        p = self.path.parent / "pictures" / f"{int(pid)}.png"
        if not p.is_file():
            raise FieldError(f"picture {pid} is not beside this log")
        return p.read_bytes()

    def video(self, vid: int) -> bytes:
        """A video from the ``videos/`` folder beside the log."""
        p = self.path.parent / "videos" / f"{int(vid)}.webm"
        if not p.is_file():
            raise FieldError(f"video {vid} is not beside this log")
        return p.read_bytes()
