"""The registry: every robot of the match, with its tag, team, status and tasks."""
from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from robo_comp.match.tasks import TaskRecord
from robo_comp.match.plausibility import Track
from robo_comp.errors import NoSuchRobotError
from robo_comp.protocol.states import RobotStatus

FIRST_TAG = 101


#: Finished tasks kept per robot for ``tasks`` and ``monitor`` (the event log keeps them all).
MAX_DONE_KEPT = 20
#: Finished tasks kept in all: with 1,000 robots the core's memory stays flat however long
#: the match; the oldest finished task of the whole match is forgotten first.
MAX_DONE_TOTAL = 2_000


@dataclass(slots=True)
class RobotRecord:
    """What the core knows about one robot."""

    tag: int
    team: str
    robot_id: str
    status: RobotStatus = RobotStatus.CONNECTED
    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    moving: bool = False
    #: the host's uncertainty of the position, σ in cells (grows while no positioning fix comes)
    sigma: float = 0.0
    sensors: dict[str, Any] = field(default_factory=dict)
    tasks: dict[str, dict[str, Any]] = field(default_factory=dict)
    current: TaskRecord | None = None
    pending: TaskRecord | None = None  # given "now" while another task runs
    queue: deque[TaskRecord] = field(default_factory=deque)
    done: deque[TaskRecord] = field(default_factory=lambda: deque(maxlen=MAX_DONE_KEPT))
    session: bytes | None = None  # routing id of the host connection
    registered_at: float = field(default_factory=time.time)
    last_report: float = 0.0
    radio_allowance: float = 0.0
    radio_checked: float = 0.0
    #: Fair play: the robot's top speed, anchor and driving budget (robo_comp.match.plausibility).
    track: Track = field(default_factory=Track)

    def summary(self) -> dict[str, Any]:
        """One row of the ``robots`` listing."""
        return {"tag": self.tag, "team": self.team, "robot_id": self.robot_id, "status": self.status,
                "x": self.x, "y": self.y, "heading": self.heading, "moving": self.moving,
                "sigma": self.sigma, "task": self.current.summary() if self.current else None,
                "queue": len(self.queue)}

    def monitor(self) -> dict[str, Any]:
        """Everything known about the robot (the thesis's monitor data, fig 4.5)."""
        row = self.summary()
        row.update({
            "sensors": self.sensors, "last_report": self.last_report,
            "registered_at": self.registered_at,
            "advertised": list(self.tasks.values()),
            "queued": [t.summary() for t in self.queue],
            "done": [t.summary() for t in self.done],
        })
        return row


class Registry:
    """All robots by tag, and the (team, robot id) -> tag map that keeps tags across reconnects."""

    def __init__(self) -> None:
        self.robots: dict[int, RobotRecord] = {}
        self.by_key: dict[tuple[str, str], int] = {}
        self.next_tag = FIRST_TAG
        self._finished: deque[TaskRecord] = deque()  # every robot's kept finished tasks, oldest first

    def finished(self, r: RobotRecord, t: TaskRecord) -> None:
        """Keep finished task ``t`` in ``r.done``, forgetting the match's oldest beyond the limits."""
        r.done.append(t)  # the deque's maxlen drops the robot's own oldest
        kept = self._finished
        kept.append(t)
        while len(kept) > MAX_DONE_TOTAL:
            old = kept.popleft()
            owner = self.robots.get(old.tag)
            if owner is not None and owner.done and owner.done[0] is old:
                owner.done.popleft()

    def get(self, tag: int) -> RobotRecord:
        """The robot with ``tag`` or :class:`NoSuchRobotError`."""
        r = self.robots.get(tag)
        if r is None:
            raise NoSuchRobotError(f"there is no robot with tag {tag}; list your robots with 'robots'")
        return r

    def lookup(self, team: str, robot_id: str) -> RobotRecord | None:
        """The robot of ``team`` with ``robot_id``, if it registered before."""
        tag = self.by_key.get((team, robot_id))
        return None if tag is None else self.robots[tag]

    def add(self, team: str, robot_id: str) -> RobotRecord:
        """Create a robot with the next free tag."""
        tag = self.next_tag
        self.next_tag += 1
        r = RobotRecord(tag=tag, team=team, robot_id=robot_id)
        self.robots[tag] = r
        self.by_key[(team, robot_id)] = tag
        return r

    def of_team(self, team: str | None) -> list[RobotRecord]:
        """Robots of ``team`` (all robots when ``team`` is None), by tag."""
        return [r for r in self.robots.values() if team is None or r.team == team]
