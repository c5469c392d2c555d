"""The score table a recorded match shows at each point, folded from its log (every viewer's)."""
from __future__ import annotations

from typing import Any


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
            victims = data.get("victims")
            if isinstance(victims, list):  # a match's finish: the revealed victims, with who found each
                found_by: dict[str, set[Any]] = {}
                for v in victims:
                    for team in (v.get("found_by") or []) if isinstance(v, dict) else []:
                        found_by.setdefault(str(team), set()).add(v.get("id"))
                victims = found_by
            for team, found in (victims if isinstance(victims, dict) else {}).items():
                board.add_team(str(team))
                board.found[str(team)] = set(found)
        else:
            return None
        return {"teams": board.table()}


__all__ = ["ScoreFold"]
