"""Event topics and what of an event the public may see."""
from __future__ import annotations

from typing import Any

#: Keys left out of the PUB (public) view of an event: they stay with the owner and referee.
PRIVATE_KEYS = frozenset({"status", "result", "data", "args", "message", "cancelled", "code", "robot_id",
                          "tasks", "evidence"})
#: The ``team`` of an event meant for every watching session (a broadcast).
EVERYONE = "*"

#: Event topics; the PUB socket uses them as the first frame.
TOPICS = (
    "robot.registered", "robot.positions", "robot.lost", "robot.returned", "robot.left",
    "task.given", "task.started", "task.done", "robot.stopped", "radio", "refused", "core.started", "core.recovered", "core.storage",
    "match.clock",
    "match.phase", "score", "score.change", "penalty", "disqualified", "broadcast", "find.reported",
    "picture", "robot.bump", "robot.tasks", "robot.log", "upload.pending", "upload.sent", "upload.done",
    "upload.unloaded", "sandbox.reset",
)


def public_view(data: dict[str, Any]) -> dict[str, Any]:
    """The public (PUB socket) view of an event's data: without the :data:`PRIVATE_KEYS`."""
    if PRIVATE_KEYS & data.keys():
        return {k: v for k, v in data.items() if k not in PRIVATE_KEYS}
    return data
