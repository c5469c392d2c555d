"""A second, different scoring rules plugin, used by the tests to show rules are swappable.

Time attack: any report near a victim counts (no evidence needed) for 100 points minus the
match seconds elapsed; nothing else scores; ranking by score, then team name.
"""
from __future__ import annotations

import math

from robo_comp.plugins.hookspecs import hookimpl


class TimeAttack:
    """Fast finds score more; evidence is not required."""

    @hookimpl
    def robo_comp_judge_find(self, find, truth):
        for v in truth["victims"]:
            if math.hypot(v["x"] - find["x"], v["y"] - find["y"]) <= 1.0:
                return {"valid": v["id"] not in truth["already_found"], "victim": v["id"], "kind": v["kind"],
                        "duplicate": v["id"] in truth["already_found"], "reason": f"time attack: {v['id']}"}
        return {"valid": False, "victim": None, "reason": "time attack: nothing there"}

    @hookimpl
    def robo_comp_score(self, event, board):
        if event["kind"] == "find.judged" and event["verdict"]["valid"]:
            return [{"team": event["team"], "points": 100.0, "kind": "victim",
                     "victim": event["verdict"]["victim"], "reason": "time attack find"}]
        return []

    @hookimpl
    def robo_comp_rank(self, rows):
        rows = sorted(rows, key=lambda r: (-r["score"], r["team"]))
        for i, r in enumerate(rows):
            r["rank"] = i + 1
        return rows


plugin = TimeAttack()
