"""Recovery: rebuild the core's state from its event log after a crash (even ``kill -9``).

The log holds every state change (see ``docs/protocol.md``, "Event log"), so replaying it
restores robots and their tags, advertised tasks, current/pending/queued/done tasks, the match
phase and clock, score changes, disqualifications, pictures (evidence) and finds. Robots come
back as ``lost`` until their hosts re-register (with the same robot ids, so the same tags).
Every record carries a checksum: a damaged record costs that record only. Recovery skips it,
keeps every good record after it, and reports exactly which sequence numbers were lost (with
their topics where the damaged bytes still say them) in the ``core.recovered`` event. Damaged
bytes at the very end (an unfinished write) are cut off, with a copy kept; the sequence numbers
they could have held are never used again. A log of format 1 (without checksums) is read and
said so.
"""
from __future__ import annotations

import logging
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from robo_comp.protocol.logfile import FORMAT_VERSION, LEGACY_VERSION, Damage, LogReader
from robo_comp.match.registry import Registry, RobotRecord
from robo_comp.protocol.states import RobotStatus, TaskMode, TaskState
from robo_comp.match.tasks import TaskMachine, TaskRecord
from robo_comp.protocol.taskspec import check_specs
from robo_comp.errors import RoboCompError
from robo_comp.scoring.board import ScoreLine
from robo_comp.match.clock import outage_seconds

if TYPE_CHECKING:
    from robo_comp.core.competition import Competition


class Recoverable(Protocol):
    """What recovery rebuilds: a freshly constructed core's registry, match and task counter."""

    registry: Registry
    competition: Competition
    next_task_id: int

log = logging.getLogger("robo_comp.core")


@dataclass
class RecoveryReport:
    """What recovery found: how many events, how long it took, and any damage."""

    events: int
    seq: int
    good_end: int
    seconds: float
    damage: str | None = None
    damaged_copy: str | None = None
    #: Every damaged stretch of the log (empty for a clean log).
    damages: list[Damage] = field(default_factory=list)
    #: Records read in format 1 (no checksums); 0 for a format-2 log.
    legacy: int = 0
    #: The log's last header is of format 1: what is appended needs a format-2 header first.
    legacy_tail: bool = False
    #: How the match clock was set (match time as recorded; the outage rule).
    clock: str = ""

    @property
    def lost(self) -> list[int]:
        """Sequence numbers of the events the damage cost."""
        return [s for d in self.damages for s in d.lost]

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (the ``core.recovered`` event)."""
        return {"events": self.events, "seq": self.seq, "seconds": round(self.seconds, 4),
                "damage": self.damage, "damaged_copy": self.damaged_copy,
                "damages": [d.to_dict() for d in self.damages], "lost": self.lost,
                "legacy_records": self.legacy, "clock": self.clock}


class Replayer:
    """Applies logged events to a freshly constructed core."""

    def __init__(self, core: Recoverable) -> None:
        self.core = core
        self.tasks: dict[int, TaskRecord] = {}
        # the core's own transitions, without its events (they are in the log already)
        self.machine = TaskMachine(on_finish=core.registry.finished)
        self.phase: tuple[str, float, float | None, float] | None = None
        #: The last ``match.clock`` record's data since the last phase change (None: none yet, as in
        #: a log of format 1, which had no such records).
        self.clock_mark: dict[str, Any] | None = None
        self.outage_rule = "pause"
        #: How recovery set the clock (part of the report).
        self.clock_note = ""
        self.last_t = 0.0
        self.handlers: dict[str, Callable[[str | None, dict[str, Any], float], None]] = {
            "robot.registered": self._registered, "robot.returned": self._returned,
            "robot.positions": self._positions, "robot.left": self._status(RobotStatus.LEFT),
            "robot.lost": self._status(RobotStatus.LOST), "task.given": self._given, "task.started": self._started,
            "task.done": self._done, "match.phase": self._phase, "match.clock": self._clock, "score.change": self._score,
            "disqualified": self._disqualified, "picture": self._picture, "find.reported": self._find,
        }

    def apply(self, topic: str, team: str | None, data: dict[str, Any], t: float) -> None:
        """Apply one event (unknown topics are informational and skipped)."""
        self.last_t = t
        h = self.handlers.get(topic)
        if h is not None:
            h(team, data, t)

    # robots ------------------------------------------------------------
    def _robot(self, tag: int) -> RobotRecord | None:
        return self.core.registry.robots.get(tag)

    def _registered(self, team: str | None, d: dict[str, Any], t: float) -> None:
        reg = self.core.registry
        r = RobotRecord(tag=d["tag"], team=d["team"], robot_id=d["robot_id"], x=d["x"], y=d["y"],
                        heading=d["heading"], registered_at=t)
        self._advertised(r, d)
        reg.robots[r.tag] = r
        reg.by_key[(r.team, r.robot_id)] = r.tag
        reg.next_tag = max(reg.next_tag, r.tag + 1)

    def _advertised(self, r: RobotRecord, d: dict[str, Any]) -> None:
        if "tasks" in d:
            try:
                r.tasks = check_specs(d["tasks"])
            except RoboCompError:
                pass

    def _returned(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        if r is not None:
            r.status = RobotStatus.CONNECTED
            self._advertised(r, d)

    def _positions(self, team: str | None, d: dict[str, Any], t: float) -> None:
        robots = self.core.registry.robots
        for tag, x, y, h in zip(d["tags"], d["x"], d["y"], d["heading"]):
            r = robots.get(tag)
            if r is not None:
                r.x, r.y, r.heading = x, y, h

    def _status(self, status: RobotStatus) -> Callable[[str | None, dict[str, Any], float], None]:
        def apply(team: str | None, d: dict[str, Any], t: float) -> None:
            r = self._robot(d["tag"])
            if r is not None:
                r.status = status
        return apply

    # tasks -------------------------------------------------------------
    def _given(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        if r is None:
            return
        mode = TaskMode.QUEUE if d["mode"] == TaskMode.QUEUE else TaskMode.NOW
        task = TaskRecord(d["task_id"], r.tag, d["name"], d["args"], mode, d.get("by", "?"), given_at=t)
        self.tasks[task.id] = task
        self.core.next_task_id = max(self.core.next_task_id, task.id + 1)
        self.machine.restore_given(r, task)

    def _started(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        task = self.tasks.get(d["task_id"])
        if r is None or task is None:
            return
        self.machine.start(r, task, at=t)

    def _done(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        task = self.tasks.pop(d["task_id"], None)
        if r is None or task is None:
            return
        state = TaskState.CANCELLED if d["state"] == TaskState.CANCELLED else TaskState.DONE
        self.machine.finish(r, task, d["ok"], d.get("status", ""), d.get("result"), state=state, at=t)

    # the match ----------------------------------------------------------
    def _phase(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.phase = (d["phase"], d["elapsed"], d.get("duration"), t)
        self.outage_rule = d.get("outage", self.outage_rule)
        self.clock_mark = None

    def _clock(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self._phase(team, d, t)
        self.clock_mark = dict(d, t=t)

    def finish(self, outage: bool = False) -> None:
        """Set the match clock from the match time last recorded (``match.phase``,
        ``match.clock``), never from differences of wall-clock stamps. ``outage``: the core was
        down since the log's end; under the ``count`` rule a running clock adds that time."""
        clock = self.core.competition.clock
        clock.outage = self.outage_rule
        if self.phase is None:
            return
        phase, elapsed, duration, t = self.phase
        self.clock_note = f"the clock is match time as recorded: {elapsed:.1f} s"
        if phase == "running" and self.clock_mark is None and self.last_t > t:
            # a log of format 1 records no clock between phase changes: count to its last event
            elapsed += self.last_t - t
            self.clock_note = (f"{elapsed:.1f} s: the log records no match clock (format 1), so the time "
                               "to its last event counts")
        if outage and phase == "running" and self.outage_rule == "count":
            down, how = outage_seconds(self.clock_mark or {}, self.last_t)
            elapsed += down
            self.clock_note += f"; the outage rule is 'count': the {down:.1f} s the core was down (by {how}) count"
        elif outage and phase == "running":
            self.clock_note += "; the outage rule is 'pause': the time the core was down does not count"
        clock.restore(phase, elapsed, duration, time.monotonic())

    def _score(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.core.competition.board.restore_line(
            ScoreLine(d["team"], d["points"], d["kind"], d["reason"], d["t"], d.get("victim")))

    def _disqualified(self, team: str | None, d: dict[str, Any], t: float) -> None:
        comp = self.core.competition
        if d.get("team"):
            comp.board.disqualified.add(d["team"])
        for tag in d.get("tags", []):
            comp.disqualified_robots[tag] = d.get("reason", "")
            r = self._robot(tag)
            if r is not None:
                r.status = RobotStatus.DISQUALIFIED

    def _picture(self, team: str | None, d: dict[str, Any], t: float) -> None:
        if "victims" not in d:  # the public copy carries no evidence facts
            return
        self.core.competition.judge.restore_picture(d)

    def _find(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.core.competition.judge.finds.append(dict(d))


def recover(core: Recoverable, path: Path) -> RecoveryReport:
    """Replay ``path`` into ``core``: every good record, skipping damaged ones (see the module
    docstring). ``seq`` of the report is the last sequence number that may have been used (the
    next event gets ``seq + 1``); ``good_end`` where damaged bytes at the end begin."""
    t0 = time.perf_counter()
    reader = LogReader(path)
    rep = Replayer(core)
    n = 0
    for rec in reader:
        rep.apply(rec.topic, rec.team, rec.data, rec.t)
        n += 1
    rep.finish(outage=True)
    for r in core.registry.robots.values():
        if r.status == RobotStatus.CONNECTED:
            r.status = RobotStatus.LOST  # until its host re-registers
        r.session = None
    report = RecoveryReport(n, reader.next_seq - 1, reader.good_end, time.perf_counter() - t0,
                            damages=reader.damages, legacy=reader.legacy,
                            legacy_tail=reader.version == LEGACY_VERSION, clock=rep.clock_note)
    if reader.legacy:
        log.warning("event log: %d records are of the previous format (1, without checksums); they were "
                    "read without a check, and new records are written in format %d after them",
                    reader.legacy, FORMAT_VERSION)
    if reader.damages:
        said = [d.describe() for d in reader.damages]
        cut = path.stat().st_size - reader.good_end
        if cut > 0:
            copy = path.with_name(f"{path.name}.damaged-{int(time.time())}")
            try:
                shutil.copyfile(path, copy)
                report.damaged_copy = str(copy)
                kept = f"a copy of the log is in {copy}"
            except OSError as e:  # a full disk: the damaged bytes are cut all the same (nothing good is in them)
                copy.unlink(missing_ok=True)
                kept = f"no copy could be kept: {e.strerror}"
            said.append(f"the {cut} damaged bytes at the end were cut off ({kept})")
        lost = report.lost
        report.damage = (f"the event log is damaged in {len(reader.damages)} place"
                         f"{'s' if len(reader.damages) > 1 else ''}; {len(lost)} event"
                         f"{'s' if len(lost) != 1 else ''} lost, every other record recovered: " + "; ".join(said))
        log.warning("event log: %s", report.damage)
    return report
