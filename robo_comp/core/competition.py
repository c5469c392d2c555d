"""The match inside the core: phases, referee powers, finds, pictures (evidence) and scores.

:class:`Competition` owns the match clock and the scoreboard and adds its request handlers
to the core's table; the core calls :meth:`Competition.check_phase` before commands that a
phase may forbid, and :meth:`Competition.tick` every heartbeat.
"""
from __future__ import annotations

import hashlib
import logging
import math
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robo_comp import protocol as P
from robo_comp.core.desk import Access, Outbox
from robo_comp.core.eventlog import EventLog
from robo_comp.protocol.logfile import read_log
from robo_comp.private_files import private_dir, write_private
from robo_comp.errors import FieldError, ForbiddenError, NotYoursError, PhaseError, TooLargeError
from robo_comp.scoring.board import Scoreboard, ScoreLine
from robo_comp.scoring.config import ScoringConfig
from robo_comp.scoring.judge import FindJudge
from robo_comp.match.clock import MatchClock, monotonic_mark
from robo_comp.protocol.states import Phase
from robo_comp.teams.policy import check_owner, check_referee
from robo_comp.world.scenario import Scenario

if TYPE_CHECKING:
    from robo_comp.core.mapdesk import MapDesk

log = logging.getLogger("robo_comp.core")

MAX_PICTURE = 256 * 1024
EVERYONE = P.EVERYONE
#: The newest score lines a ``score`` reply carries (all of them are in the results and the log).
SCORE_LINES_SHOWN = 500

# Which phases allow what (stop is always allowed: it is the safety command).
_ALLOWED = {
    "give": ("running",),
    "find": ("running",),
    "upload": ("setup", "running"),
}
_WHY = {
    "setup": "the match has not started yet; the referee starts it (robots may register and uploads are allowed now)",
    "paused": "the match is paused by the referee; robots hold until it resumes",
    "finished": "the match is over; results are frozen",
}


class Competition:
    """Match clock, scoreboard, finds and pictures of one core."""

    def __init__(self, access: Access, out: Outbox, scenario: Scenario, teams: list[str], pm: Any,
                 state_dir: Path, maps: MapDesk, events: Callable[[], EventLog], config: ScoringConfig,
                 practice: bool) -> None:
        self.access = access
        self.out = out
        self.scenario = scenario
        self.state_dir = state_dir
        self.maps = maps
        self.events = events  # the core's event log (opened after recovery has replayed into this desk)
        self.config = config
        self.clock = MatchClock(duration=math.inf if practice else float(scenario.duration),
                                phase=Phase.RUNNING if practice else Phase.SETUP,
                                running_since=time.monotonic() if practice else None)
        self.board = Scoreboard(teams, pm, config)
        #: Pictures and finds, judged as on the bench and in league matches (one judge).
        self.judge = FindJudge(scenario, teams, self.board)
        self.disqualified_robots: dict[int, str] = {}
        self.picture_dir = state_dir / "pictures"
        self.score_dirty = False

    @property
    def pictures(self) -> dict[int, dict[str, Any]]:
        """Every picture taken, by id (the judge's)."""
        return self.judge.pictures

    @property
    def finds(self) -> list[dict[str, Any]]:
        """Every find reported, with its verdict (the judge's)."""
        return self.judge.finds

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this module adds to the core."""
        return {"match": self._on_match, "score": self._on_score, "penalty": self._on_penalty,
                "disqualify": self._on_disqualify, "broadcast": self._on_broadcast, "find": self._on_find,
                "picture": self._on_picture, "picture.get": self._on_picture_get, "bump": self._on_bump}

    # ------------------------------------------------------------------ phases
    @property
    def phase(self) -> str:
        """The current phase."""
        return self.clock.phase

    def check_phase(self, what: str) -> None:
        """Raise :class:`PhaseError` when the phase forbids ``what``."""
        if self.clock.phase not in _ALLOWED[what]:
            raise PhaseError(f"cannot {what} now: {_WHY.get(self.clock.phase, self.clock.phase)}")

    def check_robot(self, tag: int) -> None:
        """Refuse commands to a disqualified robot."""
        why = self.disqualified_robots.get(tag)
        if why is not None:
            raise ForbiddenError(f"robot {tag} was disqualified by the referee: {why}")

    def state(self) -> dict[str, Any]:
        """Phase and clock as plain data."""
        return self.clock.state(time.monotonic())

    def tick(self, now: float) -> None:
        """Finish the match when its time is up."""
        if self.clock.expired(now):
            self._change("finish", "time is up")

    def _change(self, action: str, by: str, seconds: float | None = None) -> dict[str, Any]:
        now = time.monotonic()
        before = self.clock.phase
        self.clock.apply(action, now, seconds)
        st = self.clock.state(now)
        reveal: dict[str, Any] = {}
        if self.clock.phase == "finished" and before != "finished":  # the hidden victims, for spectators
            reveal["victims"] = [dict(v, found_by=sorted(t for t, ids in self.board.found.items() if v["id"] in ids))
                                 for v in self.judge.victims]
        self.out.emit("match.phase", EVERYONE, dict(st, action=action, by=by, was=before, **reveal))
        if self.clock.phase != before:
            hold = self.clock.phase in ("paused", "finished")
            for ident in self.access.host_sessions():
                self.out.send(ident, P.request("hold", 0, {"on": hold, "phase": self.clock.phase}))
        if self.clock.phase == "finished" and before != "finished":
            self._write_results_now()
        return st

    def log_clock(self) -> None:
        """Record the running clock in the event log (``match.clock``; log only, not pushed): what
        recovery restores, with the machine's boot-time clock for the ``count`` outage rule."""
        if self.clock.phase == "running":
            self.events().append("match.clock", None, dict(self.state(), **monotonic_mark()))

    def _on_match(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        check_referee(who, "change the match phase")
        action = msg.body["action"]
        if action == "outage":  # not a phase change: the rule for the clock across a core outage
            self.clock.set_outage(msg.body.get("rule"))
            st = self.state()
            self.out.emit("match.phase", EVERYONE, dict(st, action=action, by=who.name, was=st["phase"]))
            return st
        seconds = msg.body.get("seconds")
        return self._change(action, who.name, float(seconds) if seconds is not None else None)

    # ------------------------------------------------------------------ scores
    def scores(self) -> dict[str, Any]:
        """The scoreboard with the clock."""
        return dict(self.state(), teams=self.board.table(), scoring=self.config.to_dict())

    def _score_changed(self, lines: list[ScoreLine]) -> None:
        if not lines:
            return
        for ln in lines:
            self.out.emit("score.change", ln.team, ln.to_dict())
        self.score_dirty = True  # one scoreboard event per loop turn, however many lines changed

    def flush_score(self) -> None:
        """Emit the scoreboard if it changed in this loop turn (the core calls this before its
        log flush, so the board goes out with the replies that changed it)."""
        if self.score_dirty:
            self.score_dirty = False
            self.out.emit("score", EVERYONE, {"teams": self.board.table(), **self.state()})

    def feed(self, event: dict[str, Any]) -> None:
        """Give a scoring-relevant event to the rules while the match runs."""
        if self.clock.phase == "running" and event.get("team") in self.board.found:
            self._score_changed(self.board.apply(event, self.clock.elapsed(time.monotonic())))

    def _on_score(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        out = self.scores()
        team = None if who.role == "referee" else who.team
        mine = [ln for ln in self.board.lines if team is None or ln.team == team]
        out["lines"] = [ln.to_dict() for ln in mine[-SCORE_LINES_SHOWN:]]
        out["lines_total"] = self.board.lines_of(team)
        return out

    # ------------------------------------------------------------------ referee powers
    def _team_arg(self, team: Any) -> str:
        if team not in self.board.found:
            raise FieldError(f"there is no team {team!r}; the teams are {', '.join(self.board.teams)}")
        return team

    def _on_penalty(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        check_referee(who, "give penalties")
        team = self._team_arg(msg.body["team"])
        reason = msg.body.get("reason", "").strip()
        if not reason:
            raise FieldError("a penalty needs a reason, so the team knows why")
        if self.clock.phase == "finished":
            raise PhaseError("the match is over; results are frozen")
        lines = self.board.apply({"kind": "penalty", "team": team, "points": msg.body["points"],
                                  "reason": reason}, self.clock.elapsed(time.monotonic()))
        self.out.emit("penalty", team, {"team": team, "points": msg.body["points"], "reason": reason})
        self._score_changed(lines)
        return {"teams": self.board.table()}

    def _on_disqualify(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        check_referee(who, "disqualify robots or teams")
        reason = msg.body.get("reason", "").strip() or "no reason given"
        tags: list[int] = []
        if msg.body.get("team") is not None:
            team = self._team_arg(msg.body["team"])
            self.board.disqualified.add(team)
            tags = [r.tag for r in self.access.registry.of_team(team)]
        elif msg.body.get("tag") is not None:
            tags = [self.access.registry.get(msg.body["tag"]).tag]
        else:
            raise FieldError("disqualify needs a 'tag' or a 'team'")
        for tag in tags:
            self.disqualified_robots[tag] = reason
            self.access.halt_and_remove(tag, reason)
        self.out.emit("disqualified", EVERYONE, {"team": msg.body.get("team"), "tags": tags, "reason": reason})
        self.score_dirty = True  # the board goes out once, with this turn's other changes
        return {"tags": tags}

    def _on_broadcast(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        check_referee(who, "broadcast messages")
        text = msg.body["message"][:500]
        self.out.emit("broadcast", EVERYONE, {"message": text, "by": who.name})
        return {}

    # ------------------------------------------------------------------ pictures and finds
    def _on_picture(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        r = self.access.hosted(ident, b["tag"])
        png = b["png"]
        if len(png) > MAX_PICTURE:
            raise TooLargeError(f"a picture may be at most {MAX_PICTURE // 1024} KiB")
        if not png.startswith(b"\x89PNG\r\n\x1a\n"):
            raise FieldError("'png' must be a PNG image")
        pid = self.judge.next_picture
        write_private(private_dir(self.picture_dir) / f"{pid}.png", png)  # the team's: 0600 in 0700
        # judged where the core tracks the robot (its host's accepted reports), or where the host says
        # it was taken only as far as the tracking bears that out: no pose the robot never reached
        x, y, heading = self.access.judged_pose(r, b, "picture")
        meta = self.judge.picture(r.team, r.tag, x, y, heading, t=time.time(),
                                  sha256=hashlib.sha256(png).hexdigest()[:16], label=b.get("label", ""))
        seen = meta["victims"]
        # pushed once: the team and the referee get what it shows; the public feed only the fields
        # the table of protocol/topics.py lets out (not the victims, not the hash)
        self.out.emit("picture", r.team, {k: meta[k] for k in ("id", "tag", "team", "x", "y", "heading", "t",
                                                                  "victims", "sha256")})
        return {"id": pid, "seen": self.judge.describe(seen)}

    def _on_picture_get(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        meta = self.pictures.get(msg.body["id"])
        if meta is None:
            raise NotYoursError(f"there is no picture {msg.body['id']} of team {who.name}")
        check_owner(who, meta["tag"], meta["team"])
        png = (self.picture_dir / f"{meta['id']}.png").read_bytes()
        public = {k: v for k, v in meta.items() if k != "victims"}
        return dict(public, png=png)

    def _on_find(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        b = msg.body
        sess = self.access.session(ident)
        if b["tag"] in sess.tags:
            r = self.access.hosted(ident, b["tag"])
        else:
            r = self.access.robot_for(ident, b["tag"])
        self.check_robot(r.tag)
        self.check_phase("find")
        record, state = self.judge.find(r.team, r.tag, b["x"], b["y"], b.get("kind", ""), b.get("evidence", []),
                                        self.clock.elapsed(time.monotonic()))
        find, verdict, fid, evidence = record, record["verdict"], record["id"], record["evidence"]
        if state != "duplicate":
            self.maps.discovery(r.tag, r.team, find["x"], find["y"], find["kind"], evidence)
        self.out.emit("find.reported", r.team, {"id": fid, "team": r.team, "tag": r.tag, "x": find["x"],
                                                 "y": find["y"], "kind": find["kind"], "state": state,
                                                 "evidence": evidence, "message": verdict["reason"]})
        self.feed({"kind": "find.judged", "team": r.team, "tag": r.tag, "verdict": verdict})
        return {"id": fid, "state": state, "message": verdict["reason"]}

    def _on_bump(self, ident: bytes, msg: P.Message) -> None:
        r = self.access.hosted(ident, msg.body["tag"])
        x, y, _ = self.access.judged_pose(r, msg.body, "bump")
        self.out.emit("robot.bump", r.team, {"tag": r.tag, "team": r.team, "x": x,
                                              "y": y, "with": msg.body.get("with")})
        self.feed({"kind": "robot.bump", "team": r.team, "tag": r.tag})
        return None

    # ------------------------------------------------------------------ results
    def _write_results_now(self) -> None:
        """The match is over: write the results into the state folder (a failure is logged: the
        match itself is not lost, ``robo-comp results`` can write them again from the log)."""
        try:
            self.write_results(self.state_dir)
        except Exception:
            log.error("could not write the results: %s", traceback.format_exc())

    def write_results(self, folder: Path) -> dict[str, Any]:
        """Write ``results.json``, ``results.csv`` and ``scores.png`` into ``folder``."""
        from robo_comp.scoring.results import write_results

        board = self.board
        if board.lines_total == len(board.lines):
            lines = [ln.to_dict() for ln in board.lines]
        else:  # the oldest lines were let go from memory: the event log has them all
            self.events().flush()
            lines = [rec.data for rec in read_log(self.events().path, strict=False) if rec.topic == "score.change"]
        return write_results(folder, self.scores(), lines, self.finds,
                             {t.name: t.rgb for t in self.scenario.teams})  # each team in its own colour
