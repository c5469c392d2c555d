"""``robo-comp replay LOG``: serve a recorded match as if it were live, at any speed.

A :class:`ReplayCore` is a core that takes its events from a match's event log instead of
from robots: it rebuilds the state record by record with the same code that recovers a core
after a crash (:class:`robo_comp.match.restore.Restorer`), publishes each event on its PUB
socket and pushes it to watching consoles, and answers every *reading* request (``robots``,
``monitor``, ``tasks``, ``snapshot``, ``score``, ``map``, ``picture.get`` ...) exactly as a
live core would. So walls and consoles consume a replay like a live match: point their
``--core`` at the replay's state folder or URL. Everything that would change the match
(``give``, ``stop``, ``match``, uploads, registration) is refused with ``E_FORBIDDEN``.

The team and referee tokens are copied from the recorded match's state folder when they are
beside the log, so each team sees what it saw during the match (and the referee all of it);
otherwise new tokens are written into the replay's state folder. Positions were logged once
per heartbeat, so replayed robots move in those steps.
"""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

from robo_comp import protocol as P
from robo_comp.protocol.curve import keys_dir
from robo_comp.protocol.logfile import LogRecord, read_recording
from robo_comp.core.server import Core
from robo_comp.errors import FieldError, ForbiddenError
from robo_comp.match.restore import Restorer
from robo_comp.world.public import scenario_from_payload

#: Requests a replay answers; everything else would change the match and is refused.
READ_ONLY = frozenset({"hello", "heartbeat", "bye", "watch", "robots", "monitor", "tasks", "arena",
                       "snapshot", "stats", "score", "map", "map.delta", "picture.get"})
#: How often the replay plays what is due (seconds of wall-clock time); also its heartbeat.
STEP = 0.1


class ReplayCore(Core):
    """A read-only core that plays ``log`` at ``speed`` × real time (see the module docstring)."""

    def __init__(self, log: Path, state_dir: Path, *, speed: float = 1.0, start_at: float = 0.0,
                 host: str = "127.0.0.1", port: int = 0, exit_at_end: bool = False, curve: bool = False) -> None:
        if not 0 < speed < float("inf"):
            raise FieldError(f"the replay speed must be a number above 0, not {speed!r}")
        log = Path(log)
        self.records, started = read_recording(log)
        state_dir = Path(state_dir)
        state_dir.mkdir(parents=True, exist_ok=True)
        if (state_dir / "events.log").exists():
            raise FieldError(f"{state_dir} holds a match of its own; give the replay an empty --state folder")
        _copy_tokens(log.parent, state_dir)
        if curve:
            _copy_keys(log.parent, state_dir)
        if (log.parent / "pictures").is_dir() and not (state_dir / "pictures").exists():
            shutil.copytree(log.parent / "pictures", state_dir / "pictures")
        scenario = scenario_from_payload(started["arena"])
        super().__init__(state_dir, scenario, list(started.get("teams") or []) or None, host=host, port=port,
                         heartbeat=STEP, curve=curve,
                         practice=not any(r.topic == "match.phase" for r in self.records))  # no phases: practice
        self.log_path = log
        self.speed = speed
        self.exit_at_end = exit_at_end
        self.replayer = Restorer(self.match)
        self.t0 = self.records[0].t if self.records else 0.0
        self.next = 0
        self.at = 0.0  # seconds of the recording played so far
        self.started_at: float | None = None
        self.start_at = max(0.0, start_at)
        self._handlers = {name: (h if name in READ_ONLY else _refuse) for name, h in self._handlers.items()}

    @property
    def duration(self) -> float:
        """Seconds from the first record to the last."""
        return self.records[-1].t - self.t0 if self.records else 0.0

    def _tick(self, now: float) -> None:
        """Play what is due, then heartbeats to watchers (a replay has no robots to lose and no
        clock of its own to run)."""
        self.advance()
        self.access.tell_refused()
        hb = P.request("heartbeat", 0, {"t": time.time(), "core_id": self.core_id})
        for ident, s in list(self.sessions.items()):
            if s.watching or s.tags:
                self.send(ident, hb)

    def run(self) -> None:
        """Serve while playing the recording; then keep serving the final state (or stop)."""
        if self.router is None:
            self.bind()
        self.play(self.start_at, publish=False)  # jump ahead without flooding the feed
        self.started_at = time.monotonic()
        super().run()

    def _drain(self, budget: int = 2000) -> None:
        super()._drain(budget)
        self.advance()

    def advance(self) -> int:
        """Play the records that are due by now; return how many."""
        if self.started_at is None:
            return 0
        at = self.start_at + (time.monotonic() - self.started_at) * self.speed
        n = self.play(at)
        if self.next >= len(self.records) and self.exit_at_end:
            self.stop()
        return n

    def play(self, at: float, publish: bool = True) -> int:
        """Apply (and publish) every record up to ``at`` seconds into the recording."""
        n = 0
        recs = self.records
        while self.next < len(recs) and recs[self.next].t - self.t0 <= at:
            rec = recs[self.next]
            self.next += 1
            n += 1
            self.replayer.apply(rec.topic, rec.team, rec.data, rec.t)
            if rec.topic == "match.phase":
                self.replayer.finish()
            if publish:
                self._publish(rec)
        self.at = max(self.at, at)
        return n

    def _publish(self, rec: LogRecord) -> None:
        if rec.topic == "robot.positions":  # the log's batch of all teams → the feed's batch per team
            d = rec.data
            robots = self.match.registry.robots
            for tag, x, y, h in zip(d["tags"], d["x"], d["y"], d["heading"]):
                r = robots.get(tag)
                if r is not None:
                    self.match.posed.setdefault(r.team, set()).add(tag)
            self.feed.publish_now()
        elif rec.topic not in ("core.started", "core.recovered"):
            self.emit(rec.topic, rec.team, rec.data, log_it=False)


def _refuse(ident: bytes, msg: P.Message) -> None:
    raise ForbiddenError(f"this is a replay of a recorded match: it is read-only ({msg.type!r} is refused)")


def _copy_keys(src: Path, dst: Path) -> None:
    """The recorded match's CurveZMQ keys (``STATE/keys`` beside its log), unless the replay's
    state folder has keys of its own: the same certificates then work for the replay."""
    if keys_dir(src).is_dir() and not keys_dir(dst).exists():
        shutil.copytree(keys_dir(src), keys_dir(dst))
        os.chmod(keys_dir(dst), 0o700)


def _copy_tokens(src: Path, dst: Path) -> None:
    """The recorded match's tokens (when they are beside its log), so the same tokens work."""
    if (src / "referee.token").is_file() and not (dst / "referee.token").exists():
        shutil.copy2(src / "referee.token", dst / "referee.token")
    if (src / "teams").is_dir():
        (dst / "teams").mkdir(parents=True, exist_ok=True)
        for tok in (src / "teams").glob("*.token"):
            if not (dst / "teams" / tok.name).exists():
                shutil.copy2(tok, dst / "teams" / tok.name)
