"""The tasks of each robot: records, their states, and the one state machine that moves them.

A robot has at most one *running* task, at most one *pending* task (given "now" while another
runs: it waits for the running task's next movement boundary, where the host interrupts it), a
FIFO of *queued* tasks, and its kept finished ones. Every transition goes through
:class:`TaskMachine`, which the match (:class:`robo_comp.match.model.Match`) drives from commands,
live and on the engine, and its restore drives from the log.
What a robot may advertise and how calls are checked is the protocol's
(:mod:`robo_comp.protocol.taskspec`).

States::

    queued --start--> running --finish--> done | cancelled
    pending --start--> running             (pending|queued) --cancel--> cancelled
"""
from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from robo_comp.protocol.states import TaskMode, TaskState



@dataclass(slots=True)
class TaskRecord:
    """One task given to a robot, from queueing to its result."""

    id: int
    tag: int
    name: str
    args: list[Any]
    mode: TaskMode
    given_by: str
    state: TaskState = TaskState.QUEUED
    given_at: float = field(default_factory=time.time)
    started_at: float | None = None
    finished_at: float | None = None
    ok: bool | None = None
    status: str = ""
    result: Any = None

    def wire(self) -> dict[str, Any]:
        """The task as sent to a robot host."""
        return {"tag": self.tag, "task_id": self.id, "name": self.name, "args": self.args}

    def summary(self) -> dict[str, Any]:
        """The task as shown to consoles."""
        return {"task_id": self.id, "name": self.name, "args": self.args, "mode": self.mode,
                "state": self.state, "given_at": self.given_at, "started_at": self.started_at,
                "finished_at": self.finished_at, "ok": self.ok, "status": self.status,
                "result": self.result}


class TaskHolder(Protocol):
    """A robot as the task machine sees it (a :class:`~robo_comp.match.registry.RobotRecord`)."""

    tag: int
    current: TaskRecord | None
    pending: TaskRecord | None
    queue: deque[TaskRecord]


class TaskMachine:
    """Every transition of every robot's tasks, in one place.

    ``on_start(robot, task)`` and ``on_finish(robot, task)`` are called after a task started
    or ended (the core logs and publishes them, and keeps the finished task); recovery runs the
    machine with no callbacks to rebuild the same state from the log.
    """

    def __init__(self, on_start: Callable[[Any, TaskRecord], None] | None = None,
                 on_finish: Callable[[Any, TaskRecord], None] | None = None,
                 now: Callable[[], float] = time.time) -> None:
        self.on_start = on_start
        self.on_finish = on_finish
        #: The clock transitions are stamped with (wall-clock seconds live, simulated on the engine).
        self.now = now

    # ------------------------------------------------------------------ transitions
    def start(self, r: TaskHolder, t: TaskRecord, at: float | None = None) -> TaskRecord:
        """Make ``t`` the running task of ``r`` (taking it out of the pending place or the queue)."""
        if r.pending is t:
            r.pending = None
        elif t in r.queue:
            r.queue.remove(t)
        t.state = TaskState.RUNNING
        t.started_at = self.now() if at is None else at
        r.current = t
        if self.on_start is not None:
            self.on_start(r, t)
        return t

    def finish(self, r: TaskHolder, t: TaskRecord, ok: bool, status: str, result: Any = None,
               state: TaskState = TaskState.DONE, at: float | None = None) -> None:
        """End task ``t`` of ``r`` (running, pending or queued) as ``state``."""
        t.state = state
        t.ok = ok
        t.status = status
        t.result = result
        t.finished_at = self.now() if at is None else at
        if r.current is t:
            r.current = None
        elif r.pending is t:
            r.pending = None
        elif t in r.queue:
            r.queue.remove(t)
        if self.on_finish is not None:
            self.on_finish(r, t)

    def advance(self, r: TaskHolder) -> TaskRecord | None:
        """An idle robot starts its pending task, else its next queued one; returns the task it
        started (None: it was busy or has nothing to do)."""
        if r.current is not None:
            return None
        if r.pending is not None:
            return self.start(r, r.pending)
        if r.queue:
            return self.start(r, r.queue[0])
        return None

    def give(self, r: TaskHolder, t: TaskRecord, idle_ok: bool) -> TaskRecord | None:
        """Take a new task. Queued: behind the others (started at once if ``r`` is idle and
        ``idle_ok``). Now: started at once if ``r`` is idle, else pending (replacing an older
        pending task, which is cancelled), for the host to interrupt at its next movement
        boundary. Returns the task that started now, if any."""
        if t.mode == TaskMode.QUEUE:
            t.state = TaskState.QUEUED
            r.queue.append(t)
            if idle_ok and r.current is None and r.pending is None:
                return self.start(r, r.queue[0])
            return None
        if r.current is None:
            return self.start(r, t)
        if r.pending is not None:
            self.finish(r, r.pending, False, f"replaced by task {t.id} before it started",
                        state=TaskState.CANCELLED)
        t.state = TaskState.PENDING
        r.pending = t
        return None

    def complete(self, r: TaskHolder, ok: bool, status: str, result: Any = None) -> TaskRecord | None:
        """The running task ended on the robot; returns the task that starts next, if any."""
        assert r.current is not None
        self.finish(r, r.current, ok, status, result)
        return self.advance(r)

    def cancel_all(self, r: TaskHolder, why_current: str, why_waiting: str) -> list[int]:
        """Cancel the running, pending and queued tasks of ``r``; returns their ids, running first."""
        ids = []
        for t in [r.current, r.pending, *r.queue]:
            if t is not None:
                ids.append(t.id)
                self.finish(r, t, False, why_current if t is r.current else why_waiting,
                            state=TaskState.CANCELLED)
        return ids

    # ------------------------------------------------------------------ recovery (from the log)
    def restore_given(self, r: TaskHolder, t: TaskRecord) -> None:
        """A logged ``task.given``: the task waits in the queue or (given now) in the pending place
        until its logged ``task.started`` or ``task.done``."""
        if t.mode == TaskMode.QUEUE:
            r.queue.append(t)
        elif r.current is not None:
            t.state = TaskState.PENDING
            r.pending = t
