"""The story of a match for spectators: the ticker's lines, the timeline's markers and the
score over time, made from the events a view sees.

One :class:`Story` per view (live hub or recording view) follows the same events as the view's
model. Each notable event becomes a :class:`StoryItem` (a find, a penalty, a bump, a lost robot,
a phase change, a referee broadcast, a disqualification); a ``score.change`` line that explains
an item is folded into it (its points), so "red −5" always says why. The scoreboard's totals are
sampled whenever they change, for the page's score-over-time chart.

Every item carries two times: ``t``, the view's timeline (seconds into the recording, or since
the gateway started following a live core), which a replay seeks to, and ``c``, the match clock
(the core's elapsed match time) shown beside it, the same clock the page's header shows.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

#: Items a live story keeps (a replay keeps every item of its recording).
LIVE_ITEMS = 500
#: Score samples kept; beyond that every other sample is let go (the chart keeps its shape).
SCORE_SAMPLES = 1200
#: A second bump of the same robot within this many seconds joins the first line.
BUMP_MERGE = 5.0
#: A score line joins the item it explains when it comes within this many seconds of it.
FOLD_WITHIN = 5.0

#: Which item a ``score.change`` line explains, by the line's ``kind``.
LINE_ITEM = {"victim": "find", "first_bonus": "find", "false_report": "find", "collision": "bump",
             "lost": "lost", "penalty": "penalty"}
PHASE_WORDS = {"start": "the match started", "pause": "the match paused", "resume": "the match resumed",
               "finish": "the match finished", "extend": "the match was extended", "reset": "the match was reset"}


@dataclass
class StoryItem:
    """One line of the ticker and one marker on the timeline."""

    id: int
    t: float
    c: float | None
    kind: str  # find, penalty, bump, lost, phase, broadcast, disqualified, score
    text: str
    team: str | None = None
    tag: int | None = None
    x: float | None = None
    y: float | None = None
    points: float = 0.0
    count: int = 1
    state: str = ""  # a find's state (confirmed, rejected, duplicate)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for the page (``None`` fields left out)."""
        d = {"id": self.id, "t": round(self.t, 3), "c": None if self.c is None else round(self.c, 2),
             "kind": self.kind, "text": self.text, "team": self.team, "tag": self.tag, "x": self.x, "y": self.y,
             "points": round(self.points, 3), "count": self.count, "state": self.state}
        return {k: v for k, v in d.items() if v is not None and v != "" and not (k == "count" and v == 1)}


@dataclass
class Story:
    """The ticker, markers and score samples of one view (see the module docstring)."""

    limit: int | None = LIVE_ITEMS
    items: deque[StoryItem] = field(default_factory=deque)
    scores: list[tuple[float, float | None, dict[str, float]]] = field(default_factory=list)
    next_id: int = 1
    victims: list[dict[str, Any]] = field(default_factory=list)  # revealed when the match finished
    _last: dict[tuple[str, str | None, int | None], StoryItem] = field(default_factory=dict)
    _board: dict[str, float] = field(default_factory=dict)

    def apply(self, topic: str, d: dict[str, Any], t: float, c: float | None) -> list[StoryItem]:
        """Follow one event at timeline time ``t`` and match clock ``c``; returns the items it
        added or changed (a changed item keeps its ``id``)."""
        team = d.get("team") if isinstance(d.get("team"), str) else None
        tag = d.get("tag") if isinstance(d.get("tag"), int) else None
        if topic == "find.reported":
            state = str(d.get("state") or "reported")
            kind = str(d.get("kind") or "victim")
            return [self._add("find", t, c, f"{team} robot {tag} reported {_a(kind)} at ({_n(d.get('x'))}, "
                                             f"{_n(d.get('y'))}): {state}", team, tag, d, state=state)]
        if topic == "robot.bump":
            last = self._last.get(("bump", team, tag))
            if last is not None and t - last.t <= BUMP_MERGE:
                last.count += 1
                last.text = f"{team} robot {tag} bumped into something (×{last.count})"
                return [last]
            return [self._add("bump", t, c, f"{team} robot {tag} bumped into something", team, tag, d)]
        if topic == "robot.lost":
            return [self._add("lost", t, c, f"{team or 'a'} robot {tag} was lost", team, tag, d)]
        if topic == "penalty":
            return [self._add("penalty", t, c, f"referee: penalty for {team}: {d.get('reason') or 'no reason given'}",
                              team, None, d)]
        if topic == "broadcast":
            return [self._add("broadcast", t, c, f"referee: {d.get('message') or ''}", None, None, d)]
        if topic == "disqualified":
            who = d.get("team") or ", ".join(str(x) for x in d.get("tags") or [])
            return [self._add("disqualified", t, c, f"referee disqualified {who}: {d.get('reason', '')}",
                              team, None, d)]
        if topic == "match.phase":
            if d.get("phase") != "finished":
                self.victims = []
            elif isinstance(d.get("victims"), list):
                self.victims = [v for v in d["victims"] if isinstance(v, dict)]
            action = str(d.get("action") or "")
            if d.get("phase") == d.get("was") and action not in ("extend", "reset"):
                return []
            words = PHASE_WORDS.get(action, f"the match is {d.get('phase', '')}")
            return [self._add("phase", t, c, words + (f" ({d['by']})" if d.get("by") else ""), None, None, d)]
        if topic == "score.change":
            return self._score_line(d, t, c, team)
        if topic == "score" and isinstance(d.get("teams"), list):
            board = {str(r.get("team")): float(r.get("score") or 0) for r in d["teams"] if isinstance(r, dict)}
            if board != self._board:
                self._board = board
                self.scores.append((t, c, board))
                if len(self.scores) > SCORE_SAMPLES:
                    self.scores = self.scores[::2]
        return []

    def _score_line(self, d: dict[str, Any], t: float, c: float | None, team: str | None) -> list[StoryItem]:
        points = float(d.get("points") or 0)
        item_kind = LINE_ITEM.get(str(d.get("kind")), "")
        for it in reversed(self.items):  # in time order: look back only FOLD_WITHIN seconds
            if t - it.t > FOLD_WITHIN:
                break
            if it.kind == item_kind and it.team == team:
                it.points += points
                return [it]
        sign = "+" if points >= 0 else "−"
        return [self._add("score", t, c, f"{team} {sign}{_n(abs(points))}: {d.get('reason', '')}", team, None, d,
                          points=points)]

    def _add(self, kind: str, t: float, c: float | None, text: str, team: str | None, tag: int | None,
             d: dict[str, Any], *, state: str = "", points: float = 0.0) -> StoryItem:
        x, y = d.get("x"), d.get("y")
        it = StoryItem(self.next_id, t, c, kind, text, team, tag,
                       float(x) if isinstance(x, (int, float)) else None,
                       float(y) if isinstance(y, (int, float)) else None, points=points, state=state)
        self.next_id += 1
        self.items.append(it)
        self._last[(kind, team, tag)] = it
        if self.limit is not None and len(self.items) > self.limit:
            self.items.popleft()
        return it

    def to_json(self) -> dict[str, Any]:
        """The whole story as the page's ``story`` object."""
        return {"items": [it.to_dict() for it in self.items],
                "scores": [[round(t, 3), None if c is None else round(c, 2), b] for t, c, b in self.scores],
                "victims": self.victims}


def _n(v: Any) -> str:
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    if isinstance(v, float):
        return f"{v:.1f}"
    return str(v)


def _a(kind: str) -> str:
    return ("an " if kind[:1].lower() in "aeiou" else "a ") + kind


__all__ = ["Story", "StoryItem"]
