"""The default search-and-rescue scoring rules, as a pluggy plugin (entry point ``sar_rules``).

* A reported find **counts** when a victim lies within ``match_radius`` cells of the reported
  position, a robot of the reporting team *examined* it (the victim was in view, within camera
  range and line of sight, of a picture that robot took), and the report cites such a picture
  as evidence. A victim counts once per team.
* Points per victim kind (``ScoringConfig.victim_points``; a victim's own ``points`` win), plus
  ``first_bonus`` for the first team to report that victim.
* Penalties: ``false_report`` for a find that does not count (no victim there, no evidence,
  or not examined; reporting a victim the team already has is ignored, not penalised),
  ``collision`` per bump, ``robot_lost`` per robot lost, and the referee's penalties.
* **Ranking and tie-breaks**: more points first; then more victims; then the team that
  reached its final score earlier (match time of its last scoring change); then fewer
  penalty points; then the team name. Disqualified teams rank last.
"""
from __future__ import annotations

import math
from typing import Any

from robo_comp.plugins.hookspecs import hookimpl


class SearchAndRescueRules:
    """The default rules (see the module docstring)."""

    name = "sar"

    @hookimpl
    def robo_comp_judge_find(self, find: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
        """Match the report to a victim and check examination and evidence."""
        radius = truth["config"].match_radius
        best, best_d = None, math.inf
        for v in truth["victims"]:
            d = math.hypot(v["x"] - find["x"], v["y"] - find["y"])
            if d <= radius and d < best_d:
                best, best_d = v, d
        if best is None:
            return {"valid": False, "victim": None, "reason": "no victim within "
                    f"{radius:g} cells of ({find['x']:g}, {find['y']:g})"}
        if best["id"] in truth["already_found"]:
            return {"valid": False, "victim": best["id"], "duplicate": True,
                    "reason": f"victim {best['id']} is already counted for team {find['team']}"}
        seen_in = truth["examined"].get(best["id"], set())
        if not seen_in:
            return {"valid": False, "victim": best["id"],
                    "reason": "no robot of your team examined that spot (take pictures there with examineArea)"}
        cited = seen_in & set(find.get("evidence") or ())
        if not cited:
            return {"valid": False, "victim": best["id"],
                    "reason": "the report cites no picture that shows the victim; add the picture ids as evidence"}
        return {"valid": True, "victim": best["id"], "kind": best["kind"], "points": best.get("points"),
                "evidence": sorted(cited), "reason": f"victim {best['id']} ({best['kind']}) found"}

    @hookimpl
    def robo_comp_score(self, event: dict[str, Any], board: Any) -> list[dict[str, Any]]:
        """Points for judged finds; penalties for false reports, bumps, lost robots, referee."""
        cfg = board.config
        kind = event["kind"]
        team = event["team"]
        if kind == "find.judged":
            verdict = event["verdict"]
            if verdict.get("duplicate"):
                return []
            if not verdict["valid"]:
                return [{"team": team, "points": cfg.false_report, "kind": "false_report",
                         "reason": verdict["reason"]}]
            vid = verdict["victim"]
            out = [{"team": team, "points": cfg.points_for(verdict["kind"], verdict.get("points")),
                    "kind": "victim", "victim": vid, "reason": verdict["reason"]}]
            if board.first_finder.get(vid) is None:
                out.append({"team": team, "points": cfg.first_bonus, "kind": "first_bonus", "victim": vid,
                            "reason": f"first team to find victim {vid}"})
            return out
        if kind == "robot.bump":
            return [{"team": team, "points": cfg.collision, "kind": "collision",
                     "reason": f"robot {event.get('tag')} collided"}]
        if kind == "robot.lost":
            return [{"team": team, "points": cfg.robot_lost, "kind": "lost",
                     "reason": f"robot {event.get('tag')} was lost"}]
        if kind == "penalty":
            return [{"team": team, "points": -abs(float(event["points"])), "kind": "penalty",
                     "reason": event.get("reason", "")}]
        return []

    @hookimpl
    def robo_comp_rank(self, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Sort by the documented tie-breaks and number the ranks (ties share no rank)."""
        ordered = sorted(rows, key=lambda r: (r["disqualified"], -r["score"], -r["victims"],
                                              r["last_change"], r["penalties"], r["team"]))
        for i, r in enumerate(ordered):
            r["rank"] = i + 1
        return ordered


plugin = SearchAndRescueRules()
