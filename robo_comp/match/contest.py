"""The contest of a match: its phases and clock, the judge of pictures and finds, the scores.

:class:`Contest` is the referee's half of :class:`~robo_comp.match.model.Match`: the match clock
(:class:`~robo_comp.match.clock.MatchClock`, on the driver's monotonic clock), the scoreboard
(the installed scoring rules, :mod:`robo_comp.scoring.rules` or a ``--rules`` plugin), the find
judge (:class:`~robo_comp.scoring.judge.FindJudge`) and the referee's powers. It has no sockets
and writes no files: what it decides goes out through the driver's
:class:`~robo_comp.match.output.MatchOutput`.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from robo_comp.errors import FieldError, ForbiddenError, PhaseError
from robo_comp.match.clock import MatchClock
from robo_comp.match.output import MatchOutput
from robo_comp.protocol.states import Phase
from robo_comp.protocol.topics import EVERYONE
from robo_comp.scoring.board import Scoreboard, ScoreLine
from robo_comp.scoring.config import ScoringConfig
from robo_comp.scoring.judge import FindJudge
from robo_comp.world.scenario import Scenario

# Which phases allow what (stop is always allowed: it is the safety command).
ALLOWED: dict[str, tuple[Phase, ...]] = {
    "give": (Phase.RUNNING,),
    "find": (Phase.RUNNING,),
    "upload": (Phase.SETUP, Phase.RUNNING),
}
_WHY = {
    Phase.SETUP: "the match has not started yet; the referee starts it (robots may register and uploads are allowed now)",
    Phase.PAUSED: "the match is paused by the referee; robots hold until it resumes",
    Phase.FINISHED: "the match is over; results are frozen",
}


class Contest:
    """Phases, clock, scores and judging of one match (see the module docstring).

    ``mono`` is the driver's monotonic clock (the core's, or the engine's simulated time);
    ``wall`` the time stamps of pictures; ``halt_and_remove(tag, reason)`` takes a robot out of
    the match (the match's robots half)."""

    def __init__(self, out: MatchOutput, scenario: Scenario, teams: list[str], pm: Any, config: ScoringConfig,
                 practice: bool, mono: Callable[[], float], wall: Callable[[], float]) -> None:
        self.out = out
        self.scenario = scenario
        self.config = config
        self.mono = mono
        self.wall = wall
        self.clock = MatchClock(duration=math.inf if practice else float(scenario.duration),
                                phase=Phase.RUNNING if practice else Phase.SETUP,
                                running_since=mono() if practice else None)
        self.board = Scoreboard(teams, pm, config)
        #: Pictures and finds, judged the same way live, on the engine and in league matches.
        self.judge = FindJudge(scenario, teams, self.board)
        #: tag -> why the referee took the robot out of the match.
        self.disqualified_robots: dict[int, str] = {}
        self.score_dirty = False

    # ------------------------------------------------------------------ phases
    @property
    def phase(self) -> Phase:
        """The current phase."""
        return self.clock.phase

    @property
    def holding(self) -> bool:
        """Whether robots hold still now (the match is paused or over)."""
        return self.clock.phase in (Phase.PAUSED, Phase.FINISHED)

    def check_phase(self, what: str) -> None:
        """Raise :class:`PhaseError` when the phase forbids ``what`` (``give``, ``find``, ``upload``)."""
        if self.clock.phase not in ALLOWED[what]:
            raise PhaseError(f"cannot {what} now: {_WHY.get(self.clock.phase, self.clock.phase)}")

    def check_robot(self, tag: int) -> None:
        """Refuse commands to a disqualified robot."""
        why = self.disqualified_robots.get(tag)
        if why is not None:
            raise ForbiddenError(f"robot {tag} was disqualified by the referee: {why}")

    def state(self) -> dict[str, Any]:
        """Phase and clock as plain data."""
        return self.clock.state(self.mono())

    def elapsed(self) -> float:
        """Match time now (seconds the match has been running)."""
        return self.clock.elapsed(self.mono())

    def tick(self) -> None:
        """Finish the match when its time is up."""
        if self.clock.expired(self.mono()):
            self.change("finish", "time is up")

    def change(self, action: str, by: str, seconds: float | None = None, **extra: Any) -> dict[str, Any]:
        """Carry out a phase action (``start``, ``pause``, ``resume``, ``finish``, ``extend``) by ``by``;
        ``extra`` goes into the ``match.phase`` event. Returns the clock's state."""
        now = self.mono()
        before = self.clock.phase
        self.clock.apply(action, now, seconds)
        st = self.clock.state(now)
        finished = self.clock.phase is Phase.FINISHED and before is not Phase.FINISHED
        reveal: dict[str, Any] = dict(extra)
        if finished:  # the hidden victims, for spectators, and the final scores
            reveal["victims"] = [dict(v, found_by=sorted(t for t, ids in self.board.found.items() if v["id"] in ids))
                                 for v in self.judge.victims]
            reveal["scores"] = {row["team"]: row["score"] for row in self.board.table()}
        self.out.emit("match.phase", EVERYONE, dict(st, action=action, by=by, was=before, **reveal))
        if self.clock.phase != before:
            self.out.to_hosts("hold", {"on": self.holding, "phase": self.clock.phase})
        if finished:
            self.out.finished()
        return st

    def set_outage(self, rule: Any, by: str) -> dict[str, Any]:
        """The referee's rule for the clock across a core outage (``pause`` or ``count``)."""
        self.clock.set_outage(rule)
        st = self.state()
        self.out.emit("match.phase", EVERYONE, dict(st, action="outage", by=by, was=st["phase"]))
        return st

    def clock_record(self) -> dict[str, Any] | None:
        """What the log records of a running clock (``match.clock``), None when it is not running."""
        return self.state() if self.clock.phase is Phase.RUNNING else None

    # ------------------------------------------------------------------ scores
    def scores(self) -> dict[str, Any]:
        """The scoreboard with the clock and the scoring settings."""
        return dict(self.state(), teams=self.board.table(), scoring=self.config.to_dict())

    def _score_changed(self, lines: list[ScoreLine]) -> None:
        if not lines:
            return
        for ln in lines:
            self.out.emit("score.change", ln.team, ln.to_dict())
        self.score_dirty = True  # one scoreboard event per turn, however many lines changed

    def flush_score(self) -> None:
        """Emit the scoreboard if it changed since the last flush (the core flushes before its log
        flush, so the board goes out with the replies that changed it)."""
        if self.score_dirty:
            self.score_dirty = False
            self.out.emit("score", EVERYONE, {"teams": self.board.table(), **self.state()})

    def feed(self, event: dict[str, Any]) -> None:
        """Give a scoring-relevant event to the rules while the match runs."""
        if self.clock.phase is Phase.RUNNING and event.get("team") in self.board.found:
            self._score_changed(self.board.apply(event, self.elapsed()))

    # ------------------------------------------------------------------ referee powers
    def team_arg(self, team: Any) -> str:
        """``team`` if it plays, else a :class:`FieldError` naming the teams."""
        if team not in self.board.found:
            raise FieldError(f"there is no team {team!r}; the teams are {', '.join(self.board.teams)}")
        return str(team)

    def penalty(self, team: Any, points: float, reason: str) -> dict[str, Any]:
        """The referee's penalty: ``points`` off ``team``'s score, with a reason it is told."""
        team = self.team_arg(team)
        reason = reason.strip()
        if not reason:
            raise FieldError("a penalty needs a reason, so the team knows why")
        if self.clock.phase is Phase.FINISHED:
            raise PhaseError("the match is over; results are frozen")
        lines = self.board.apply({"kind": "penalty", "team": team, "points": points, "reason": reason},
                                 self.elapsed())
        self.out.emit("penalty", team, {"team": team, "points": points, "reason": reason})
        self._score_changed(lines)
        return {"teams": self.board.table()}

    def broadcast(self, message: str, by: str) -> None:
        """The referee's message to everyone."""
        self.out.emit("broadcast", EVERYONE, {"message": message[:500], "by": by})

    # ------------------------------------------------------------------ pictures, finds, bumps
    def picture(self, team: str, tag: int, x: float, y: float, heading: float, **meta: Any) -> dict[str, Any]:
        """A picture robot ``tag`` took at the judged pose: recorded by the judge (the victims in view
        count as examined by ``team``) and announced; returns its record."""
        rec = self.judge.picture(team, tag, x, y, heading, t=self.wall(), **meta)
        # pushed once: the team and the referee get what it shows; the public feed only the fields
        # the table of protocol/topics.py lets out (not the victims, not the hash)
        self.out.emit("picture", team, {k: rec[k] for k in ("id", "tag", "team", "x", "y", "heading", "t",
                                                           "victims", "sha256") if k in rec})
        return rec

    def find(self, team: str, tag: int, x: Any, y: Any, kind: Any, evidence: Any) -> tuple[dict[str, Any], str]:
        """A find robot ``tag`` reported, judged by the rules; returns its record and its state
        (``confirmed``, ``rejected``, ``duplicate``)."""
        self.check_robot(tag)
        self.check_phase("find")
        record, state = self.judge.find(team, tag, x, y, kind, evidence, round(self.elapsed(), 6))
        verdict = record["verdict"]
        self.out.emit("find.reported", team, {"id": record["id"], "team": team, "tag": tag, "x": record["x"],
                                              "y": record["y"], "kind": record["kind"], "state": state,
                                              "evidence": record["evidence"], "message": verdict["reason"]})
        self.feed({"kind": "find.judged", "team": team, "tag": tag, "verdict": verdict})
        return record, state

    def bump(self, team: str, tag: int, x: float, y: float, other: Any) -> None:
        """Robot ``tag`` bumped into something at (x, y) (``other``: the robot it hit, if one)."""
        self.out.emit("robot.bump", team, {"tag": tag, "team": team, "x": x, "y": y, "with": other})
        self.feed({"kind": "robot.bump", "team": team, "tag": tag})


__all__ = ["ALLOWED", "Contest"]
