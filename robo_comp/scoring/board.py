"""The scoreboard: applies the scoring plugins' changes and ranks the teams."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pluggy

from robo_comp.scoring.config import ScoringConfig


@dataclass(slots=True)
class ScoreLine:
    """One change of a team's score."""

    team: str
    points: float
    kind: str
    reason: str
    t: float  # match time in seconds
    victim: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {"team": self.team, "points": self.points, "kind": self.kind, "reason": self.reason,
                "t": self.t, "victim": self.victim}


class Scoreboard:
    """Scores of every team, changed only through the ``robo_comp_score`` hook."""

    def __init__(self, teams: list[str], pm: pluggy.PluginManager, config: ScoringConfig) -> None:
        self.teams = list(teams)
        self.pm = pm
        self.config = config
        self.lines: list[ScoreLine] = []
        self.found: dict[str, set[str]] = {t: set() for t in teams}
        self.first_finder: dict[str, str] = {}
        self.disqualified: set[str] = set()

    def judge(self, find: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
        """Ask the rules whether a reported find counts."""
        truth = dict(truth, config=self.config, already_found=self.found.get(find["team"], set()))
        verdict = self.pm.hook.robo_comp_judge_find(find=find, truth=truth)
        return verdict or {"valid": False, "victim": None, "reason": "no scoring rule judged this find"}

    def apply(self, event: dict[str, Any], t: float) -> list[ScoreLine]:
        """Feed a scoring-relevant event to the rules; record and return the changes."""
        if event.get("team") not in self.found:
            return []
        out = []
        for changes in self.pm.hook.robo_comp_score(event=event, board=self):
            for c in changes or ():
                if c.get("team") not in self.found:
                    continue
                line = ScoreLine(c["team"], float(c["points"]), str(c.get("kind", "")), str(c.get("reason", "")),
                                 round(t, 3), c.get("victim"))
                self.restore_line(line)
                out.append(line)
        return out

    def restore_line(self, line: ScoreLine) -> None:
        """Record a change (also used when recovering from the event log)."""
        self.lines.append(line)
        if line.kind == "victim" and line.victim:
            self.found[line.team].add(line.victim)
            self.first_finder.setdefault(line.victim, line.team)

    def table(self) -> list[dict[str, Any]]:
        """Ranked rows ``{team, score, victims, penalties, last_change, disqualified, rank}``."""
        rows = []
        for team in self.teams:
            mine = [ln for ln in self.lines if ln.team == team]
            rows.append({"team": team, "score": round(sum(ln.points for ln in mine), 3),
                         "victims": len(self.found[team]),
                         "penalties": round(-sum(ln.points for ln in mine if ln.points < 0), 3),
                         "last_change": max((ln.t for ln in mine), default=0.0),
                         "disqualified": team in self.disqualified})
        ranked = self.pm.hook.robo_comp_rank(rows=rows)
        if ranked is None:
            ranked = sorted(rows, key=lambda r: (r["disqualified"], -r["score"], r["team"]))
            for i, r in enumerate(ranked):
                r["rank"] = i + 1
        return ranked
