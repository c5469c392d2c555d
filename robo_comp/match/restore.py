"""A match rebuilt from its event log: the write side's fold, used by recovery and replays.

The log holds every change of a match (see ``docs/protocol.md``, "Event log"). Folding its
records into a freshly made :class:`~robo_comp.match.model.Match` restores its robots and tags,
advertised tasks, current/pending/queued/done tasks, the phase and the clock, score changes,
disqualifications, pictures (evidence) and finds, the teams' reallocation settings, the
obstacles their robots reported and the videos they filmed; no event is emitted (the log has them all).
Robots come back ``lost`` until their hosts register again (see :meth:`Restorer.hosts_gone`).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from robo_comp.errors import RoboCompError
from robo_comp.match.clock import outage_seconds
from robo_comp.match.lifecycle import Lifecycle
from robo_comp.match.model import Match
from robo_comp.match.registry import RobotRecord
from robo_comp.match.tasks import TaskMachine, TaskRecord
from robo_comp.protocol.states import Phase, RobotStatus, TaskMode, TaskState
from robo_comp.protocol.taskspec import check_specs
from robo_comp.scoring.board import ScoreLine

Handler = Callable[[str | None, dict[str, Any], float], None]


class Restorer:
    """Applies logged events to a freshly made match, then :meth:`finish` sets its clock."""

    def __init__(self, match: Match) -> None:
        self.match = match
        self.tasks: dict[int, TaskRecord] = {}
        # the match's own transitions, without its events (they are in the log already)
        self.machine = TaskMachine(on_finish=match.registry.finished, now=match.wall)
        self.phase: tuple[str, float, float | None, float] | None = None
        #: The last ``match.clock`` record's data since the last phase change (None: none yet, as in
        #: a log of format 1, which had no such records).
        self.clock_mark: dict[str, Any] | None = None
        self.outage_rule = "pause"
        #: How the clock was set (part of the recovery report).
        self.clock_note = ""
        self.last_t = 0.0
        self.handlers: dict[str, Handler] = {
            "robot.registered": self._registered, "robot.returned": self._returned,
            "robot.positions": self._positions, "robot.left": self._status(RobotStatus.LEFT),
            "robot.lost": self._status(RobotStatus.LOST), "robot.tasks": self._tasks,
            "task.given": self._given, "task.started": self._started,
            "task.done": self._done, "match.phase": self._phase, "match.clock": self._clock, "score.change": self._score,
            "disqualified": self._disqualified, "picture": self._picture, "find.reported": self._find,
            "teamwork": self._teamwork, "map.obstacle": self._obstacle, "video": self._video,
        }

    def apply(self, topic: str, team: str | None, data: dict[str, Any], t: float) -> None:
        """Apply one event (topics that change nothing are skipped)."""
        self.last_t = t
        h = self.handlers.get(topic)
        if h is not None:
            h(team, data, t)

    # teamwork ----------------------------------------------------------
    def _teamwork(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.match.teamwork.reallocate[d["team"]] = bool(d["reallocate"])

    def _video(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.match.videos.restore(d)

    def _obstacle(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.match.teamwork.obstacles.setdefault(d["team"], {})[(d["x"], d["y"])] = d["tag"]

    # robots ------------------------------------------------------------
    def _robot(self, tag: int) -> RobotRecord | None:
        return self.match.registry.robots.get(tag)

    def _registered(self, team: str | None, d: dict[str, Any], t: float) -> None:
        reg = self.match.registry
        r = RobotRecord(tag=d["tag"], team=d["team"], robot_id=d["robot_id"], x=d["x"], y=d["y"],
                        heading=d["heading"], registered_at=t)
        self._advertised(r, d)
        reg.robots[r.tag] = r
        reg.by_key[(r.team, r.robot_id)] = r.tag
        reg.next_tag = max(reg.next_tag, r.tag + 1)

    @staticmethod
    def _advertised(r: RobotRecord, d: dict[str, Any]) -> None:
        if "tasks" in d:
            try:
                r.tasks = check_specs(d["tasks"])
            except RoboCompError:
                pass

    def _tasks(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        if r is not None:
            self._advertised(r, d)

    def _returned(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        if r is not None:
            Lifecycle.restore(r, RobotStatus.CONNECTED)
            self._advertised(r, d)

    def _positions(self, team: str | None, d: dict[str, Any], t: float) -> None:
        robots = self.match.registry.robots
        for tag, x, y, h in zip(d["tags"], d["x"], d["y"], d["heading"]):
            r = robots.get(tag)
            if r is not None:
                r.x, r.y, r.heading = x, y, h

    def _status(self, status: RobotStatus) -> Handler:
        def apply(team: str | None, d: dict[str, Any], t: float) -> None:
            r = self._robot(d["tag"])
            if r is not None:
                Lifecycle.restore(r, status)
        return apply

    # tasks -------------------------------------------------------------
    def _given(self, team: str | None, d: dict[str, Any], t: float) -> None:
        r = self._robot(d["tag"])
        if r is None:
            return
        mode = TaskMode.QUEUE if d["mode"] == TaskMode.QUEUE else TaskMode.NOW
        task = TaskRecord(d["task_id"], r.tag, d["name"], d["args"], mode, d.get("by", "?"), given_at=t)
        self.tasks[task.id] = task
        self.match.next_task_id = max(self.match.next_task_id, task.id + 1)
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

    # the contest ---------------------------------------------------------
    def _phase(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.phase = (d["phase"], d["elapsed"], d.get("duration"), t)
        self.outage_rule = d.get("outage", self.outage_rule)
        self.clock_mark = None

    def _clock(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self._phase(team, d, t)
        self.clock_mark = dict(d, t=t)

    def _score(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.match.contest.board.restore_line(
            ScoreLine(d["team"], d["points"], d["kind"], d["reason"], d["t"], d.get("victim")))

    def _disqualified(self, team: str | None, d: dict[str, Any], t: float) -> None:
        c = self.match.contest
        if d.get("team"):
            c.board.disqualified.add(d["team"])
        for tag in d.get("tags", []):
            c.disqualified_robots[tag] = d.get("reason", "")
            r = self._robot(tag)
            if r is not None:
                Lifecycle.restore(r, RobotStatus.DISQUALIFIED)

    def _picture(self, team: str | None, d: dict[str, Any], t: float) -> None:
        if "victims" not in d:  # the public copy carries no evidence facts
            return
        self.match.contest.judge.restore_picture(d)

    def _find(self, team: str | None, d: dict[str, Any], t: float) -> None:
        self.match.contest.judge.finds.append(dict(d))

    # the end -------------------------------------------------------------
    def hosts_gone(self) -> None:
        """The hosts of the logged match are not connected to this one: every connected robot is
        lost until its host registers again (with its robot id, so its tag)."""
        for r in self.match.registry.robots.values():
            if r.status is RobotStatus.CONNECTED:
                Lifecycle.restore(r, RobotStatus.LOST)
            r.session = None

    def finish(self, outage: bool = False) -> None:
        """Set the match clock from the match time last recorded (``match.phase``,
        ``match.clock``), never from differences of wall-clock stamps. ``outage``: the core was
        down since the log's end; under the ``count`` rule a running clock adds that time."""
        clock = self.match.contest.clock
        clock.outage = self.outage_rule
        if self.phase is None:
            return
        phase, elapsed, duration, t = self.phase
        self.clock_note = f"the clock is match time as recorded: {elapsed:.1f} s"
        running = phase == Phase.RUNNING
        if running and self.clock_mark is None and self.last_t > t:
            # a log of format 1 records no clock between phase changes: count to its last event
            elapsed += self.last_t - t
            self.clock_note = (f"{elapsed:.1f} s: the log records no match clock (format 1), so the time "
                               "to its last event counts")
        if outage and running and self.outage_rule == "count":
            down, how = outage_seconds(self.clock_mark or {}, self.last_t)
            elapsed += down
            self.clock_note += f"; the outage rule is 'count': the {down:.1f} s the core was down (by {how}) count"
        elif outage and running:
            self.clock_note += "; the outage rule is 'pause': the time the core was down does not count"
        clock.restore(phase, elapsed, duration, self.match.mono())


__all__ = ["Restorer"]
