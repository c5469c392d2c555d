"""The scoreboard: applies the scoring plugins' changes and ranks the teams."""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import pluggy

from robo_comp.scoring.config import ScoringConfig

#: Score lines kept in memory, newest last. A long match with many robots bumping makes many
#: lines; all of them stay in the event log (``score.change``), from which the results are
#: written when some were forgotten, so the core's memory stays flat.
MAX_LINES_KEPT = 2_000


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
        self.lines: deque[ScoreLine] = deque(maxlen=MAX_LINES_KEPT)  # the newest
        self.lines_total = 0  # lines ever recorded (``lines`` keeps the newest of them)
        # running totals per team (score, penalties, last change, lines): the table costs O(teams)
        self._totals: dict[str, list[float]] = {t: [0.0, 0.0, 0.0, 0] for t in teams}
        self.found: dict[str, set[str]] = {t: set() for t in teams}
        self.first_finder: dict[str, str] = {}
        self.disqualified: set[str] = set()

    def add_team(self, team: str) -> None:
        """Count ``team`` from now on (nothing if it is counted already): a replayed log names
        its teams as it goes."""
        if team not in self._totals:
            self.teams.append(team)
            self._totals[team] = [0.0, 0.0, 0.0, 0]
            self.found[team] = set()

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
        self.lines_total += 1
        total = self._totals.get(line.team)
        if total is not None:
            total[0] += line.points
            if line.points < 0:
                total[1] -= line.points
            total[2] = max(total[2], line.t)
            total[3] += 1
        if line.kind == "victim" and line.victim:
            self.found[line.team].add(line.victim)
            self.first_finder.setdefault(line.victim, line.team)

    def score_of(self, team: str) -> float:
        """``team``'s score now."""
        return round(self._totals[team][0], 3)

    def lines_of(self, team: str | None) -> int:
        """How many score lines ``team`` (all teams for None) has had."""
        return self.lines_total if team is None else int(self._totals[team][3])

    def table(self) -> list[dict[str, Any]]:
        """Ranked rows ``{team, score, victims, penalties, last_change, disqualified, rank}``."""
        rows = []
        for team in self.teams:
            score, penalties, last, _ = self._totals[team]
            rows.append({"team": team, "score": round(score, 3), "victims": len(self.found[team]),
                         "penalties": round(penalties, 3), "last_change": last,
                         "disqualified": team in self.disqualified})
        ranked = self.pm.hook.robo_comp_rank(rows=rows)
        if ranked is None:
            ranked = sorted(rows, key=lambda r: (r["disqualified"], -r["score"], r["team"]))
            for i, r in enumerate(ranked):
                r["rank"] = i + 1
        return ranked
