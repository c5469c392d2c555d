"""Recovery: rebuild the core's state from its event log after a crash (even ``kill -9``).

The log holds every state change (see ``docs/protocol.md``, "Event log"), so replaying it
restores robots and their tags, advertised tasks, current/pending/queued/done tasks, the match
phase and clock, score changes, disqualifications, pictures (evidence) and finds. Robots come
back as ``lost`` until their hosts re-register (with the same robot ids, so the same tags).
A damaged tail is reported and cut off; everything before it recovers.
"""
from __future__ import annotations

import logging
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from robo_comp.protocol.logfile import LogReader
from robo_comp.core.registry import Registry, RobotRecord, RobotStatus
from robo_comp.core.tasks import TaskMachine, TaskMode, TaskRecord, TaskState
from robo_comp.protocol.taskspec import check_specs
from robo_comp.errors import RoboCompError
from robo_comp.scoring.board import ScoreLine

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

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (the ``core.recovered`` event)."""
        return {"events": self.events, "seq": self.seq, "seconds": round(self.seconds, 4),
                "damage": self.damage, "damaged_copy": self.damaged_copy}


class Replayer:
    """Applies logged events to a freshly constructed core."""

    def __init__(self, core: Recoverable) -> None:
        self.core = core
        self.tasks: dict[int, TaskRecord] = {}
        # the core's own transitions, without its events (they are in the log already)
        self.machine = TaskMachine(on_finish=core.registry.finished)
        self.phase: tuple[str, float, float | None, float] | None = None
        self.last_t = 0.0
        self.handlers: dict[str, Callable[[str | None, dict[str, Any], float], None]] = {
            "robot.registered": self._registered, "robot.returned": self._returned,
            "robot.positions": self._positions, "robot.left": self._status(RobotStatus.LEFT),
            "robot.lost": self._status(RobotStatus.LOST), "task.given": self._given, "task.started": self._started,
            "task.done": self._done, "match.phase": self._phase, "score.change": self._score,
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

    def finish(self) -> None:
        """Set the match clock: a running match counts the time up to the last logged event
        (the core's downtime is not match time)."""
        if self.phase is not None:
            phase, elapsed, duration, t = self.phase
            if phase == "running":
                elapsed += max(0.0, self.last_t - t)
            self.core.competition.clock.restore(phase, elapsed, duration, time.monotonic())

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
    """Replay ``path`` into ``core``; cut off and keep a copy of a damaged tail."""
    t0 = time.perf_counter()
    reader = LogReader(path)
    rep = Replayer(core)
    n = 0
    for rec in reader:
        rep.apply(rec.topic, rec.team, rec.data, rec.t)
        n += 1
    rep.finish()
    for r in core.registry.robots.values():
        if r.status == RobotStatus.CONNECTED:
            r.status = RobotStatus.LOST  # until its host re-registers
        r.session = None
    report = RecoveryReport(n, reader.last_seq, reader.good_end, time.perf_counter() - t0)
    if reader.damage is not None:
        copy = path.with_name(f"{path.name}.damaged-{int(time.time())}")
        shutil.copyfile(path, copy)
        report.damage = f"{reader.damage}; {path.stat().st_size - reader.good_end} bytes after it were cut off"
        report.damaged_copy = str(copy)
        log.warning("event log: %s (a copy of the damaged log is in %s)", report.damage, copy)
    return report
