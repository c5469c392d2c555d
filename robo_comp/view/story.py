"""The story of a match for spectators: the ticker's lines, the timeline's markers, the score
over time, the match clock's text and the winner banner, made from the events a view sees.

Every viewer tells the same story from here: the web gateway (its live hubs and its
recordings) sends the items to the page, the wall (:mod:`robo_comp.wall`) draws them itself.

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

import bisect
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from robo_comp.view.model import MatchView

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
    #: Changes whenever an item is added or changed or the victims change (a viewer redraws on it).
    version: int = 0
    _last: dict[tuple[str, str | None, int | None], StoryItem] = field(default_factory=dict)
    _board: dict[str, float] = field(default_factory=dict)

    def apply(self, topic: str, d: dict[str, Any], t: float, c: float | None) -> list[StoryItem]:
        """Follow one event at timeline time ``t`` and match clock ``c``; returns the items it
        added or changed (a changed item keeps its ``id``)."""
        items = self._apply(topic, d, t, c)
        if items or topic == "match.phase":
            self.version += 1
        return items

    def follow(self, model: MatchView, topic: str, d: dict[str, Any], t: float) -> list[StoryItem]:
        """Follow one event a view's ``model`` has just applied, at timeline time ``t``, with
        the match clock as the model hears it now (None while the match has no phases); poses
        tell no story."""
        if topic == "robot.positions":
            return []
        return self.apply(topic, d, t, model.match.now(model.clock())[0] if model.match.phase else None)

    def _apply(self, topic: str, d: dict[str, Any], t: float, c: float | None) -> list[StoryItem]:
        team = d.get("team") if isinstance(d.get("team"), str) else None
        tag = d.get("tag") if isinstance(d.get("tag"), int) else None
        if topic == "find.reported":
            state = str(d.get("state") or "reported")
            kind = str(d.get("kind") or "victim")
            return [self._add("find", t, c, f"{team} robot {tag} reported {_a(kind)} at ({number_text(d.get('x'))}, "
                                             f"{number_text(d.get('y'))}): {state}", team, tag, d, state=state)]
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
        text = f"{team} {sign}{number_text(abs(points))}: {d.get('reason', '')}"
        return [self._add("score", t, c, text, team, None, d, points=points)]

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

    def upto(self, now: float | None, lines: int) -> list[StoryItem]:
        """The ticker at timeline time ``now``: the newest ``lines`` items told by then, newest
        first (``now`` None: every item, as live). A replay seeking back shows only the lines up
        to its position (the page's rule, ``static/app.js``)."""
        items = self.items
        hi = len(items) if now is None else bisect.bisect_right(items, now + 1e-6, key=lambda it: it.t)
        return [items[i] for i in range(hi - 1, max(0, hi - lines) - 1, -1)]

    def to_json(self) -> dict[str, Any]:
        """The whole story as the page's ``story`` object."""
        return {"items": [it.to_dict() for it in self.items],
                "scores": [[round(t, 3), None if c is None else round(c, 2), b] for t, c, b in self.scores],
                "victims": self.victims}


def clock_text(seconds: float | None) -> str:
    """The match clock as every view shows it: ``m:ss``, ``h:mm:ss`` from an hour (the page's
    ``fmt``); empty for none."""
    if seconds is None or seconds != seconds:
        return ""
    s = max(0, math.floor(seconds))
    h, m = s // 3600, s // 60 % 60
    return (f"{h}:{m:02d}" if h else f"{m}") + f":{s % 60:02d}"


@dataclass(frozen=True)
class ClockLine:
    """The header's one match clock: the phase word, the elapsed time, and the time left while
    the match has a limit and is not finished (``"(2:35 left)"``, else empty)."""

    phase: str
    elapsed: str
    remaining: str

    def __str__(self) -> str:
        return "   ".join(p for p in (self.phase, self.elapsed, self.remaining) if p)


def clock_line(phase: str | None, elapsed: float, remaining: float | None, *, replay: bool,
               recording_t: float | None = None) -> ClockLine:
    """The match clock as the page's header shows it: the core's match clock, or the
    recording's time (``recording_t``) in a replay of a match without phases; no time left
    once the match is finished (a finished match does not read "3:14 left")."""
    if not phase and replay and recording_t is not None:
        elapsed = recording_t
    left = f"({clock_text(remaining)} left)" if remaining is not None and math.isfinite(remaining) \
        and phase != "finished" else ""
    return ClockLine(phase or ("replay" if replay else "live"), clock_text(elapsed), left)


@dataclass(frozen=True)
class Banner:
    """The winner banner of a finished match: the title (``red wins``, ``A draw`` or ``Match
    over``), the winner (None for a draw), and the detail line (the scores, and how many of the
    hidden victims were found)."""

    title: str
    winner: str | None
    detail: str
    found: int = 0
    victims: int = 0


def banner(phase: str | None, score: list[dict[str, Any]], victims: list[dict[str, Any]]) -> Banner | None:
    """The banner when the match is finished (None before). The winner is the best-ranked team
    not disqualified, unless the next one has the same score and victims (a draw)."""
    if phase != "finished":
        return None
    def rank(r: dict[str, Any]) -> float:
        v = r.get("rank")
        return float(v) if isinstance(v, (int, float)) else 99.0

    rows = sorted((r for r in score if not r.get("disqualified")), key=rank)
    title, winner = "Match over", None
    if rows and (len(rows) < 2 or rows[0].get("score") != rows[1].get("score")
                 or rows[0].get("victims") != rows[1].get("victims")):
        winner = str(rows[0].get("team"))
        title = f"{winner} wins"
    elif len(rows) >= 2:
        title = "A draw"
    found = sum(1 for v in victims if v.get("found_by"))
    detail = " · ".join(f"{r.get('team')} {number_text(r.get('score', 0))}" for r in rows)
    if victims:
        detail += f" — {found} of {len(victims)} victims found (shown on the map)"
    return Banner(title, winner, detail, found, len(victims))


def number_text(v: Any) -> str:
    """A number as the page writes it (``fmtNum``): whole numbers without a point, else one decimal."""
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    if isinstance(v, float):
        return f"{v:.1f}"
    return str(v)


def _a(kind: str) -> str:
    return ("an " if kind[:1].lower() in "aeiou" else "a ") + kind


__all__ = ["Banner", "ClockLine", "Story", "StoryItem", "banner", "clock_line", "clock_text", "number_text"]
