"""Event topics and what of an event the public may see: the one visibility table.

Every public feed takes what it carries from :func:`public_event`: the core's live PUB socket
(``Core.emit``), a replay core's PUB socket (``robo-comp replay``), the public view of a web
replay (``robo-comp web --replay``) and a public MCAP export (``robo-comp export mcap``). So a
recorded match shown to the public shows exactly what the live public feed showed, never more. A
topic missing from :data:`PUBLIC_TOPICS` is never public (a new topic is private until it is
listed here). :class:`EventView` is what a recorded match's views (public, a team's, the
referee's) see of each logged event, from this table.
"""
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
    # fair play: claims about the world the match did not believe, and robots handed between hosts
    # (both for the referee, and the team whose robot it is; never public)
    "integrity", "robot.handover",
    # teamwork (issue 33): a lost robot's tasks offered to its team (public without the tasks),
    # a team's reallocation setting and the obstacles its robots reported (the team's and the referee's)
    "task.offered", "teamwork", "map.obstacle",
    # a video a robot filmed (examineArea): the public sees that and where, the film is the team's
    "video",
)


#: Topics the public feeds carry: ``None`` = the event's data without the :data:`PRIVATE_KEYS`;
#: a tuple = only these fields of it.
PUBLIC_TOPICS: dict[str, tuple[str, ...] | None] = {
    "robot.registered": None, "robot.positions": None, "robot.lost": None, "robot.returned": None,
    "robot.left": None, "task.given": None, "task.started": None, "task.done": None, "robot.stopped": None,
    "core.started": None, "core.recovered": None, "core.storage": None, "match.phase": None, "score": None,
    "score.change": None, "penalty": None, "disqualified": None, "find.reported": None,
    "robot.bump": None, "robot.tasks": None, "task.offered": None,
    # the referee's message is for everyone ("message" is a private key elsewhere: a verdict's reason)
    "broadcast": ("message", "by"),
    # the logged record also names the victims in sight and the image's hash: the team's own
    "picture": ("id", "tag", "team", "x", "y", "heading", "t"),
    "video": ("id", "tag", "team", "x", "y", "heading", "t", "seconds"),
    # the running match clock as the log records it (a replay shows it; the machine's boot clock is not public)
    "match.clock": ("phase", "elapsed", "remaining", "duration", "outage"),
}
#: Topics that reach only the event's team and the referee, live and replayed.
PRIVATE_TOPICS = frozenset({"radio", "refused", "robot.log", "upload.pending", "upload.sent", "upload.done",
                            "upload.unloaded", "sandbox.reset", "integrity", "robot.handover", "teamwork",
                            "map.obstacle"})
assert set(TOPICS) == PUBLIC_TOPICS.keys() | PRIVATE_TOPICS and not PUBLIC_TOPICS.keys() & PRIVATE_TOPICS


def public_event(topic: str, data: dict[str, Any]) -> dict[str, Any] | None:
    """What a public feed carries of this event (``None``: nothing, the topic is never public)."""
    if topic not in PUBLIC_TOPICS:
        return None
    fields = PUBLIC_TOPICS[topic]
    if fields is not None:
        return {k: data[k] for k in fields if k in data}
    return public_view(data)


def public_view(data: dict[str, Any]) -> dict[str, Any]:
    """The public (PUB socket) view of an event's data: without the :data:`PRIVATE_KEYS`."""
    if PRIVATE_KEYS & data.keys():
        return {k: v for k, v in data.items() if k not in PRIVATE_KEYS}
    return data


class EventView:
    """What one view of a recorded match sees of each logged event: ``public`` (what the public feeds
    carried: :func:`public_event`), ``referee`` (everything) or a team's name (what that team's
    consoles were sent live: its own events whole, the events for everyone, the arena, its own
    robots' rows of the positions). Call it with the records in order: it learns the robots'
    teams from ``robot.registered``. Used by the web replay's views and the MCAP export."""

    def __init__(self, view: str) -> None:
        self.view = view
        self.team_of: dict[int, str | None] = {}  # robot tag -> its team, from robot.registered

    def __call__(self, topic: str, team: str | None, data: dict[str, Any]) -> dict[str, Any] | None:
        """The event's data as this view sees it (``None``: not at all)."""
        if topic == "robot.registered":
            tag = data.get("tag")
            if isinstance(tag, int):  # what the core logs; a record without one names no robot
                self.team_of[tag] = data.get("team")
        view = self.view
        if view == "public":
            return public_event(topic, data)
        if view == "referee" or topic == "core.started":
            return data
        if topic == "robot.positions" and team is None:  # the log's batch holds every team's robots
            keep = [i for i, tag in enumerate(data.get("tags") or []) if self.team_of.get(tag) == view]
            if not keep:
                return None
            return {k: ([v[i] for i in keep] if isinstance(v, list) else v) for k, v in data.items()}
        return data if team in (view, EVERYONE) else None
