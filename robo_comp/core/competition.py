"""The contest's requests at the core: phases, scores, referee powers, pictures, finds, bumps.

The match itself (clock, scoreboard, judge) is :class:`robo_comp.match.contest.Contest`, part of
the core's :class:`~robo_comp.match.model.Match`; this desk proves who asks (the referee for the
phases and penalties, a robot's own host for its pictures and bumps, its team for a find), keeps
the pictures' files and the results in the state folder, and hands the rest to the match.
"""
from __future__ import annotations

import hashlib
import logging
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robo_comp import protocol as P
from robo_comp.core.desk import Access, Outbox
from robo_comp.core.eventlog import EventLog
from robo_comp.errors import FieldError, NotYoursError, TooLargeError
from robo_comp.match.clock import monotonic_mark
from robo_comp.match.model import Match
from robo_comp.private_files import private_dir, write_private
from robo_comp.protocol.logfile import read_log
from robo_comp.teams.policy import check_owner, check_referee

log = logging.getLogger("robo_comp.core")

MAX_PICTURE = 256 * 1024
#: The newest score lines a ``score`` reply carries (all of them are in the results and the log).
SCORE_LINES_SHOWN = 500


class Competition:
    """The contest's request handlers, and the files it keeps (pictures, results)."""

    def __init__(self, access: Access, out: Outbox, match: Match, state_dir: Path,
                 events: Callable[[], EventLog]) -> None:
        self.access = access
        self.out = out
        self.match = match
        self.contest = match.contest
        self.state_dir = state_dir
        self.events = events  # the core's event log (opened after recovery has replayed the match)
        self.picture_dir = state_dir / "pictures"

    def handlers(self) -> dict[str, Callable[[bytes, P.Message], dict[str, Any] | None]]:
        """Request handlers this module adds to the core."""
        return {"match": self._on_match, "score": self._on_score, "penalty": self._on_penalty,
                "disqualify": self._on_disqualify, "broadcast": self._on_broadcast, "find": self._on_find,
                "picture": self._on_picture, "picture.get": self._on_picture_get, "bump": self._on_bump}

    # ------------------------------------------------------------------ phases
    def log_clock(self) -> None:
        """Record the running clock in the event log (``match.clock``; log only, not pushed): what
        recovery restores, with the machine's boot-time clock for the ``count`` outage rule."""
        st = self.contest.clock_record()
        if st is not None:
            self.events().append("match.clock", None, dict(st, **monotonic_mark()))

    def _on_match(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        check_referee(who, "change the match phase")
        action = msg.body["action"]
        if action == "outage":  # not a phase change: the rule for the clock across a core outage
            return self.contest.set_outage(msg.body.get("rule"), who.name)
        seconds = msg.body.get("seconds")
        return self.contest.change(action, who.name, float(seconds) if seconds is not None else None)

    # ------------------------------------------------------------------ scores
    def _on_score(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        out = self.contest.scores()
        team = None if who.role == "referee" else who.team
        board = self.contest.board
        mine = [ln for ln in board.lines if team is None or ln.team == team]
        out["lines"] = [ln.to_dict() for ln in mine[-SCORE_LINES_SHOWN:]]
        out["lines_total"] = board.lines_of(team)
        return out

    # ------------------------------------------------------------------ referee powers
    def _on_penalty(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        check_referee(self.access.session(ident).who, "give penalties")
        return self.contest.penalty(msg.body["team"], msg.body["points"], msg.body.get("reason", ""))

    def _on_disqualify(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        check_referee(self.access.session(ident).who, "disqualify robots or teams")
        reason = msg.body.get("reason", "").strip() or "no reason given"
        return {"tags": self.match.disqualify(msg.body.get("team"), msg.body.get("tag"), reason)}

    def _on_broadcast(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        check_referee(who, "broadcast messages")
        self.contest.broadcast(msg.body["message"], who.name)
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
        judge = self.contest.judge
        write_private(private_dir(self.picture_dir) / f"{judge.next_picture}.png", png)  # the team's: 0600 in 0700
        # judged where the match tracks the robot (its host's accepted reports), or where the host says
        # it was taken only as far as the tracking bears that out: no pose the robot never reached
        x, y, heading = self.match.judged_pose(r, b, "picture")
        meta = self.contest.picture(r.team, r.tag, x, y, heading, sha256=hashlib.sha256(png).hexdigest()[:16],
                                    label=b.get("label", ""))
        return {"id": meta["id"], "seen": judge.describe(meta["victims"])}

    def _on_picture_get(self, ident: bytes, msg: P.Message) -> dict[str, Any]:
        who = self.access.session(ident).who
        meta = self.contest.judge.pictures.get(msg.body["id"])
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
        record, state = self.contest.find(r.team, r.tag, b["x"], b["y"], b.get("kind", ""), b.get("evidence", []))
        if state != "duplicate":
            self.match.out.discovered(r, record)
        return {"id": record["id"], "state": state, "message": record["verdict"]["reason"]}

    def _on_bump(self, ident: bytes, msg: P.Message) -> None:
        r = self.access.hosted(ident, msg.body["tag"])
        x, y, _ = self.match.judged_pose(r, msg.body, "bump")
        self.contest.bump(r.team, r.tag, x, y, msg.body.get("with"))
        return None

    # ------------------------------------------------------------------ results
    def write_results_now(self) -> None:
        """The match is over: write the results into the state folder (a failure is logged: the
        match itself is not lost, ``robo-comp results`` can write them again from the log)."""
        try:
            self.write_results(self.state_dir)
        except Exception:
            log.error("could not write the results: %s", traceback.format_exc())

    def write_results(self, folder: Path) -> dict[str, Any]:
        """Write ``results.json``, ``results.csv`` and ``scores.png`` into ``folder``."""
        from robo_comp.scoring.results import write_results

        board = self.contest.board
        if board.lines_total == len(board.lines):
            lines = [ln.to_dict() for ln in board.lines]
        else:  # the oldest lines were let go from memory: the event log has them all
            self.events().flush()
            lines = [rec.data for rec in read_log(self.events().path, strict=False) if rec.topic == "score.change"]
        return write_results(folder, self.contest.scores(), lines, self.contest.judge.finds,
                             {t.name: t.rgb for t in self.match.scenario.teams})  # each team in its own colour
