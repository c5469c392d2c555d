"""The words for states that travel on the wire and stand in the event log, as enums.

Every process reads them (the core and the bench write them; consoles, walls, the web page and
replays read them), so they live in the protocol, which every process may import. Each is a
``StrEnum``: its value is the very word on the wire, so ``RobotStatus.LOST == "lost"``.
"""
from __future__ import annotations

import enum


class RobotStatus(enum.StrEnum):
    """Where a robot stands with the match."""

    CONNECTED = "connected"  # its host reports and takes tasks
    LOST = "lost"  # its host went silent; it comes back when the host speaks again
    LEFT = "left"  # its host took it out of the arena
    DISQUALIFIED = "disqualified"  # the referee took it out of the match


class TaskState(enum.StrEnum):
    """Where a task stands."""

    QUEUED = "queued"
    PENDING = "pending"
    RUNNING = "running"
    DONE = "done"
    CANCELLED = "cancelled"


class TaskMode(enum.StrEnum):
    """How a task was given: interrupting the current one, or behind the queue."""

    NOW = "now"
    QUEUE = "queue"


class Phase(enum.StrEnum):
    """The match's phase: setup → running ⇄ paused → finished (only the referee moves it, and
    the clock, which finishes a match whose time is up)."""

    SETUP = "setup"
    RUNNING = "running"
    PAUSED = "paused"
    FINISHED = "finished"


__all__ = ["Phase", "RobotStatus", "TaskMode", "TaskState"]
