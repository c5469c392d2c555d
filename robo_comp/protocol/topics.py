"""Event topics: the one table that names every topic, its fields and who may see it.

:data:`TABLE` holds a :class:`Topic` per event topic: the fields its data may carry (and those it
always carries), the fields the public may see (none: the topic reaches only the event's team and
the referee) and what it says. Everything takes visibility and parsing from here:

* every public feed takes what it carries from :func:`public_event`: the core's live PUB socket
  (``Core.emit``), a replay core's PUB socket (``robo-comp replay``), the public view of a web
  replay (``robo-comp web --replay``) and a public MCAP export (``robo-comp export mcap``): a
  recorded match shown to the public shows exactly what the live public feed showed, never more;
* :class:`EventView` is what a recorded match's views (public, a team's, the referee's) see;
* :func:`check_event` says what is wrong with an event (an unknown topic, a missing or unknown
  field): the tests check every event a core logs and every event the engine logs with it;
* :func:`readable` is what the viewers' fold (:class:`robo_comp.view.model.MatchView`, which the
  wall and the web gateway share, and the consoles' model) asks before it folds an event: one
  that lacks what the table says it carries (a damaged or hostile log, say) is skipped.

A topic missing from the table is never public and fails :func:`check_event`: a new topic is
added here first, with its fields and its public ones.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

#: The ``team`` of an event meant for every watching session (a broadcast).
EVERYONE = "*"


@dataclass(frozen=True)
class Topic:
    """One event topic: ``fields`` its data may carry, ``required`` those it always carries,
    ``public`` those a public feed carries (empty: never public; the event's team and the referee
    get it whole), ``about`` what it says."""

    name: str
    fields: frozenset[str]
    required: frozenset[str]
    public: tuple[str, ...]
    about: str

    @property
    def private(self) -> bool:
        """Whether the topic never reaches a public feed."""
        return not self.public


def _topic(name: str, required: str, optional: str = "", public: str | None = None, *, about: str) -> Topic:
    """A table row from space-separated field names; ``public`` None: every field is public, ""
    (or "-"): none is."""
    req = frozenset(required.split())
    fields = req | frozenset(optional.split())
    shown = tuple(f for f in (required + " " + optional).split()) if public is None else tuple(
        f for f in public.split() if f != "-")
    assert set(shown) <= fields, (name, set(shown) - fields)
    return Topic(name, fields, req, shown, about)


_CLOCK = "phase elapsed remaining duration outage"
_POSE = "tag x y"

#: Every event topic (see the module docstring); the PUB socket uses the name as the first frame.
TABLE: dict[str, Topic] = {t.name: t for t in (
    # the core
    _topic("core.started", "router teams", "arena debug_replay",
           about="a core started (the arena's public payload; who sees debug drawing in replays: DEBUG_REPLAY)"),
    _topic("core.recovered", "events seq seconds", "damage damaged_copy damages lost legacy_records clock",
           about="what a restarted core recovered from its log, and any damage"),
    _topic("core.storage", "ok", "message errno seconds", public="ok errno seconds",
           about="the event log cannot be written (ok false, not logged), or can again"),
    _topic("refused", "by type code message", "count address", public="",
           about="a request the core refused (folded per sender a beat for notifications and strangers)"),
    # robots
    _topic("robot.registered", "tag team robot_id x y heading", "tasks", public="tag team x y heading",
           about="a new robot, with the tag it keeps"),
    _topic("robot.positions", "tags x y heading", "team moving sigma",
           about="poses (live: a team's conflated batch; logged: a sample of the robots that moved)"),
    _topic("robot.lost", _POSE, "message", public=_POSE, about="a robot's host went silent or let it go"),
    _topic("robot.returned", _POSE, "was tasks", public=_POSE + " was", about="a lost robot is back"),
    _topic("robot.left", _POSE, about="a robot's host took it out of the arena"),
    _topic("robot.stopped", _POSE, "cancelled ms", public=_POSE + " ms", about="a robot confirmed a stop"),
    _topic("robot.bump", _POSE, "team with", about="a robot bumped into something (``with``: the robot it hit)"),
    _topic("robot.tasks", "tag tasks", public="tag", about="what a robot advertises after an upload or unload"),
    _topic("robot.log", "tag stream text", public="", about="what team code printed"),
    _topic("robot.handover", "tag by from", public="", about="the referee handed a robot to its next host"),
    _topic("integrity", "kind tag team count x y message", public="",
           about="claims about the world the match did not believe (referee; one per robot and kind a beat)"),
    _topic("radio", "from to data delivered", public="", about="a robot's message to its teammates"),
    # tasks
    _topic("task.given", "tag task_id name args mode by", "from", public="tag task_id name mode by",
           about="a task given to a robot (now, or queued)"),
    _topic("task.started", "tag task_id name args", public="tag task_id name", about="a robot started a task"),
    _topic("task.done", "tag task_id name ok state status result", public="tag task_id name ok state",
           about="a task ended (done: with its outcome; cancelled)"),
    # the contest
    _topic("match.phase", _CLOCK, "action by was victims scores forfeit",
           about="a phase change (the finish reveals the victims and the final scores)"),
    _topic("match.clock", _CLOCK, "boot boot_id", public=_CLOCK,
           about="the running clock as the log records it (log only)"),
    _topic("score", "teams", _CLOCK, about="the scoreboard"),
    _topic("score.change", "team points kind reason t", "victim", about="one change of a team's score"),
    _topic("penalty", "team points reason", about="the referee's penalty"),
    _topic("disqualified", "tags reason", "team", about="the referee took a team or a robot out of the match"),
    _topic("broadcast", "message by", about="the referee's message to everyone"),
    _topic("find.reported", "id team tag x y kind state", "evidence message", public="id team tag x y kind state",
           about="a find a team reported, as judged"),
    _topic("picture", "id tag team x y heading t", "victims sha256 label", public="id tag team x y heading t",
           about="a picture a robot took (the team's: what it shows)"),
    # team code
    _topic("upload.pending", "upload_id team tags filename sha256 by", public="",
           about="an upload waits for the referee's approval"),
    _topic("upload.sent", "tags filename sha256 by", "upload_id", public="", about="an upload went to the robots' hosts"),
    _topic("upload.done", "upload_id team tags ok", "filename sha256 by module version message", public="",
           about="how an upload went"),
    _topic("upload.unloaded", "tags name", public="", about="a module taken away from robots"),
    _topic("sandbox.reset", "tags by results", public="", about="the referee restarted a team's sandbox"),
    # teamwork (issue 33)
    _topic("task.offered", "tag team reallocate tasks", "message", public="tag team reallocate",
           about="a lost or departed robot's running and queued tasks offered to its team (each task's 'to': the "
                 "teammate it moves to, or nil)"),
    _topic("teamwork", "team reallocate by", public="", about="a team turned reallocation of a lost robot's tasks on "
                                                              "or off"),
    _topic("map.obstacle", "tag team x y", public="", about="a cell a robot reported blocked: on its team's map"),
    _topic("video", "id tag team x y heading t", "seconds frames label sha256",
           public="id tag team x y heading t seconds", about="a video a robot filmed (examineArea; the team's: the film)"),
    _topic("debug.draw", "tags frames", "team", public="",
           about="team code's debug drawing: each robot's new frame (robo_comp/protocol/drawing.py); the team's "
                 "own live, in replays as the match's debug_replay says (AFTER_MATCH_TOPICS)"),
)}

#: The topic names.
TOPICS: tuple[str, ...] = tuple(TABLE)
#: Topics the public feeds carry, with the fields they carry of each.
PUBLIC_TOPICS: dict[str, tuple[str, ...]] = {t.name: t.public for t in TABLE.values() if not t.private}
#: Topics that reach only the event's team and the referee, live and replayed.
PRIVATE_TOPICS = frozenset(t.name for t in TABLE.values() if t.private)
#: Private topics a replay may show everyone, after the match, when the organiser chose so: the
#: match's ``debug_replay`` option (:data:`DEBUG_REPLAY`), recorded in the log's ``core.started``.
#: Never on a live public feed.
AFTER_MATCH_TOPICS = frozenset({"debug.draw"})
#: The ``debug_replay`` choices: a team's debug drawing is replayed to that team (and the
#: referee) only, or to everyone.
DEBUG_REPLAY = ("team", "everyone")
assert AFTER_MATCH_TOPICS <= PRIVATE_TOPICS
#: Fields some topic keeps from the public (for tests that fill them with markers).
PRIVATE_FIELDS = frozenset(f for t in TABLE.values() for f in t.fields - set(t.public))


def public_event(topic: str, data: dict[str, Any]) -> dict[str, Any] | None:
    """What a public feed carries of this event (``None``: nothing, the topic is never public)."""
    fields = PUBLIC_TOPICS.get(topic)
    if fields is None:
        return None
    return {k: data[k] for k in fields if k in data}


def replay_public_event(topic: str, data: dict[str, Any], debug_replay: str = "team") -> dict[str, Any] | None:
    """What a replay shows the public of this event: :func:`public_event`, and the
    :data:`AFTER_MATCH_TOPICS` too when the match's ``debug_replay`` is ``"everyone"``."""
    if topic in AFTER_MATCH_TOPICS:
        return data if debug_replay == "everyone" else None
    return public_event(topic, data)


def check_event(topic: str, data: Any) -> str | None:
    """What is wrong with an event of ``topic`` carrying ``data`` (None: nothing): a topic not in
    the table, data that is not a map, a field the topic always carries missing, a field it never
    carries."""
    t = TABLE.get(topic)
    if t is None:
        return f"{topic!r} is not a topic of protocol/topics.py"
    if not isinstance(data, dict):
        return f"{topic}: the data is {type(data).__name__}, not a map"
    missing = t.required - data.keys()
    if missing:
        return f"{topic}: without {', '.join(sorted(missing))}"
    unknown = data.keys() - t.fields
    if unknown:
        return f"{topic}: fields not in the table: {', '.join(sorted(map(str, unknown)))}"
    return None


#: The fields that say what an event is about (its robot, task, upload, team, phase): a viewer
#: folds an event only with them (the others it takes as they come: an older core's event, or a
#: public view, may lack some, and a newer one may carry more).
KEY_FIELDS = frozenset({"tag", "tags", "id", "task_id", "upload_id", "team", "teams", "phase", "topic"})


def readable(topic: str, data: Any) -> bool:
    """Whether a viewer may fold this event: a map that carries what the table says the event is
    about (its :data:`KEY_FIELDS` among those it always carries; for a public topic, those the
    public view keeps), a robot's ``tag`` an integer; a topic not in the table is the viewer's
    own business (it ignores what it does not know)."""
    t = TABLE.get(topic)
    if t is None:
        return True
    if not isinstance(data, dict):
        return False
    need = t.required & KEY_FIELDS
    if not t.private and not need <= data.keys():
        need = need & set(t.public)
    if not need <= data.keys():
        return False
    return "tag" not in need or type(data["tag"]) is int


class EventView:
    """What one view of a recorded match sees of each logged event: ``public`` (what the public feeds
    carried: :func:`public_event`), ``referee`` (everything) or a team's name (what that team's
    consoles were sent live: its own events whole, the events for everyone, the arena, its own
    robots' rows of the positions). Call it with the records in order: it learns the robots'
    teams from ``robot.registered`` and, from ``core.started``, whether the public view also shows
    the :data:`AFTER_MATCH_TOPICS` (``debug_replay: everyone``). Used by the web replay's views
    and the MCAP export."""

    def __init__(self, view: str) -> None:
        self.view = view
        self.team_of: dict[int, str | None] = {}  # robot tag -> its team, from robot.registered
        #: The match's choice for its debug drawing in replays (:data:`DEBUG_REPLAY`), from ``core.started``.
        self.debug_replay = "team"

    def __call__(self, topic: str, team: str | None, data: dict[str, Any]) -> dict[str, Any] | None:
        """The event's data as this view sees it (``None``: not at all)."""
        if topic == "robot.registered":
            tag = data.get("tag")
            if isinstance(tag, int):  # what the core logs; a record without one names no robot
                self.team_of[tag] = data.get("team")
        elif topic == "core.started":
            self.debug_replay = str(data.get("debug_replay") or "team")
        view = self.view
        if view == "public":  # what the public feeds carried, and after the match what the match chose
            return replay_public_event(topic, data, self.debug_replay)
        if view == "referee" or topic == "core.started":
            return data
        if topic == "robot.positions" and team is None:  # the log's batch holds every team's robots
            keep = [i for i, tag in enumerate(data.get("tags") or []) if self.team_of.get(tag) == view]
            if not keep:
                return None
            return {k: ([v[i] for i in keep] if isinstance(v, list) else v) for k, v in data.items()}
        return data if team in (view, EVERYONE) else None


__all__ = ["AFTER_MATCH_TOPICS", "DEBUG_REPLAY", "EVERYONE", "EventView", "PRIVATE_FIELDS", "PRIVATE_TOPICS", "PUBLIC_TOPICS", "TABLE", "TOPICS", "Topic",
           "check_event", "public_event", "replay_public_event"]
