"""Play a recorded match from the core's event log into a :class:`WallModel`, at any speed.

The log starts with ``core.started`` (which carries the arena), so a replay needs nothing but
the log; pictures are read from the ``pictures/`` folder beside it when it is there.
Positions are logged once a second per robot, so replayed robots move in 1 s steps. Scores
are folded from the log's ``score.change`` lines and final ``match.phase`` (:class:`ScoreFold`)
where it has no score tables of its own (a league match's log).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robo_comp.protocol.logfile import LogRecord, read_log
from robo_comp.errors import FieldError
from robo_comp.wall.model import WallModel


class ScoreFold:
    """The score table a recorded match shows at each point, folded from its log: the one
    reading of a log's scores for every viewer that replays it (the wall, the web page).

    A league match's log (and any log without ``score`` tables) carries the score as
    ``score.change`` lines and a final ``match.phase`` with ``scores``; :meth:`feed` gives each
    line to a :class:`~robo_comp.scoring.board.Scoreboard` (as the core's recovery does) and
    returns the ``score`` event a live core would have published (``{"teams": board.table()}``).
    A log that carries its own ``score`` tables (a core's) is left to them: the fold stops at
    the first one.
    """

    def __init__(self) -> None:
        from robo_comp.plugins.manager import get_plugin_manager
        from robo_comp.scoring.board import Scoreboard
        from robo_comp.scoring.config import ScoringConfig

        # no rules: the lines are already scored; no rank plugin: the default order
        self.board = Scoreboard([], get_plugin_manager(load_entry_points=False), ScoringConfig())
        self.own_tables = False  # the log has ``score`` events of its own

    def feed(self, topic: str, data: dict[str, Any]) -> dict[str, Any] | None:
        """Take one record; returns the ``score`` event's data to show now, or None."""
        from robo_comp.scoring.board import ScoreLine

        if topic == "score":
            self.own_tables = True
        if self.own_tables:
            return None
        board = self.board
        if topic == "core.started":
            for team in data.get("teams") or []:
                board.add_team(str(team))
        elif topic == "score.change" and data.get("team") is not None:
            team = str(data["team"])
            board.add_team(team)
            board.restore_line(ScoreLine(team, float(data.get("points") or 0.0), str(data.get("kind", "")),
                                         str(data.get("reason", "")), float(data.get("t") or 0.0),
                                         data.get("victim")))
        elif topic == "disqualified" and data.get("team") is not None:
            board.add_team(str(data["team"]))
            board.disqualified.add(str(data["team"]))
        elif topic == "match.phase" and isinstance(data.get("scores"), dict):
            for team, score in data["scores"].items():  # the match's own final word
                board.add_team(str(team))
                if abs(float(score) - board.score_of(str(team))) > 1e-9:  # lines missing from the log
                    board.restore_line(ScoreLine(str(team), float(score) - board.score_of(str(team)),
                                                 "final", "the match's final score", 0.0))
            for team, found in (data.get("victims") or {}).items():
                board.add_team(str(team))
                board.found[str(team)] = set(found)
        else:
            return None
        return {"teams": board.table()}


class ReplaySource:
    """Feeds a model with a log's events as replay time passes (``speed`` × real time)."""

    def __init__(self, path: str | Path, speed: float = 1.0, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FieldError(f"--replay {path}: no such event log (it is STATE/events.log of a core)")
        try:
            self.records: list[LogRecord] = list(read_log(self.path, strict=False))
        except OSError as e:
            raise FieldError(f"cannot read the event log {path}: {e.strerror}") from None
        if speed <= 0:
            raise FieldError("--speed must be above 0")
        self.speed = speed
        self.clock = clock
        self.t0 = self.records[0].t if self.records else 0.0
        self.next = 0
        self.started: float | None = None
        self.offset = 0.0
        self.scores = ScoreFold()

    @property
    def duration(self) -> float:
        """Seconds from the first to the last record."""
        return self.records[-1].t - self.t0 if self.records else 0.0

    @property
    def done(self) -> bool:
        """True once every record was applied."""
        return self.next >= len(self.records)

    def replay_time(self) -> float:
        """Seconds of the recording shown so far (the model's clock during a replay)."""
        if self.started is None:
            return self.offset
        return self.offset + (self.clock() - self.started) * self.speed

    def attach(self, model: WallModel) -> None:
        """Make the model's clock the replay's (so the match timer runs at replay speed)."""
        model.clock = self.replay_time
        model.replay = True

    def advance(self, model: WallModel) -> int:
        """Apply the records that are due; return how many."""
        if self.started is None:
            self.started = self.clock()
        return self.seek(model, self.replay_time())

    def seek(self, model: WallModel, at: float) -> int:
        """Apply every record up to ``at`` seconds into the recording (forward only)."""
        n = 0
        recs = self.records
        while self.next < len(recs) and recs[self.next].t - self.t0 <= at:
            rec = recs[self.next]
            model.apply(rec.topic, rec.data)
            table = self.scores.feed(rec.topic, rec.data)
            if table is not None:
                model.apply("score", table)
            self.next += 1
            n += 1
        if self.started is None:
            self.offset = at
        return n

    def picture(self, pid: int) -> bytes:
        """A picture from the ``pictures/`` folder beside the log."""
        p = self.path.parent / "pictures" / f"{int(pid)}.png"
        if not p.is_file():
            raise FieldError(f"picture {pid} is not beside this log")
        return p.read_bytes()
