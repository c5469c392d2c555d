"""Every rule of the default search-and-rescue scoring and every tie-break, through the real
plugin manager (entry points) and the scoreboard, with the scenario's settings."""
from __future__ import annotations

from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.scoring.board import Scoreboard
from robo_comp.scoring.config import ScoringConfig

VICTIMS = [{"id": "v1", "x": 5, "y": 5, "kind": "adult"}, {"id": "v2", "x": 10, "y": 2, "kind": "child"},
           {"id": "v3", "x": 1, "y": 9, "kind": "injured", "points": 50}]


def board(teams=("red", "blue"), **cfg) -> Scoreboard:
    return Scoreboard(list(teams), get_plugin_manager(), ScoringConfig.from_table(cfg))


def report(b: Scoreboard, team: str, x: float, y: float, evidence=(1,), examined=None, t: float = 1.0):
    find = {"team": team, "x": x, "y": y, "evidence": list(evidence)}
    truth = {"victims": VICTIMS, "examined": examined if examined is not None else {"v1": {1}, "v2": {1}, "v3": {1}}}
    verdict = b.judge(find, truth)
    return verdict, b.apply({"kind": "find.judged", "team": team, "verdict": verdict}, t)


def total(b: Scoreboard, team: str) -> float:
    return next(r["score"] for r in b.table() if r["team"] == team)


def test_victims_first_bonus_kinds_and_own_points():
    b = board(first_bonus=5, victim_points={"adult": 10, "child": 15})
    v, lines = report(b, "red", 5.4, 5.3)
    assert v["valid"] and [(ln.kind, ln.points) for ln in lines] == [("victim", 10), ("first_bonus", 5)]
    v, lines = report(b, "blue", 5, 5, t=2)
    assert [(ln.kind, ln.points) for ln in lines] == [("victim", 10)]  # no bonus: red was first
    _, lines = report(b, "red", 10, 2)
    assert lines[0].points == 15
    _, lines = report(b, "red", 1, 9)
    assert lines[0].points == 50  # the victim's own points win over its kind's
    assert total(b, "red") == 10 + 5 + 15 + 5 + 50 + 5


def test_false_reports_duplicates_and_missing_evidence_or_examination():
    b = board(false_report=-5)
    v, lines = report(b, "red", 20, 20)
    assert not v["valid"] and "no victim within" in v["reason"] and lines[0].points == -5
    v, lines = report(b, "red", 5, 5, examined={})
    assert "examined" in v["reason"] and lines[0].kind == "false_report"
    v, lines = report(b, "red", 5, 5, evidence=(99,))
    assert "cites no picture" in v["reason"] and lines[0].kind == "false_report"
    report(b, "red", 5, 5)
    v, lines = report(b, "red", 5, 5)  # the same victim again: ignored, not penalised
    assert v.get("duplicate") and lines == []


def test_collisions_lost_robots_and_referee_penalties():
    b = board(collision=-1, robot_lost=-2)
    assert b.apply({"kind": "robot.bump", "team": "red", "tag": 101}, 1)[0].points == -1
    assert b.apply({"kind": "robot.lost", "team": "red", "tag": 101}, 2)[0].points == -2
    assert b.apply({"kind": "penalty", "team": "red", "points": 7, "reason": "unsafe"}, 3)[0].points == -7
    row = next(r for r in b.table() if r["team"] == "red")
    assert row["score"] == -10 and row["penalties"] == 10
    assert b.apply({"kind": "robot.bump", "team": "nobody"}, 4) == []


def test_tie_breaks_points_victims_time_penalties_name_and_disqualified_last():
    def with_points(points: float) -> None:
        b.config = ScoringConfig.from_table({"first_bonus": 0, "victim_points": {"adult": points, "child": points}})

    b = board(("a", "b", "c", "d", "e", "z"))
    with_points(10)
    report(b, "a", 5, 5, t=1)   # 10 points, 1 victim, at 1 s
    report(b, "z", 5, 5, t=1)   # the same as a: the name decides
    report(b, "c", 5, 5, t=3)   # the same points and victims, reached later
    report(b, "e", 5, 5, t=0.5)  # the earliest of all, but disqualified
    b.disqualified.add("e")
    with_points(7.5)
    report(b, "b", 5, 5, t=1)   # 15 - 5 = 10 points too, but from 2 victims
    report(b, "b", 10, 2, t=1)
    b.apply({"kind": "penalty", "team": "b", "points": 5, "reason": "x"}, 1)
    with_points(15)
    report(b, "d", 5, 5, t=1)   # 15 - 5 = 10 points, 1 victim, at 1 s, but 5 penalty points
    b.apply({"kind": "penalty", "team": "d", "points": 5, "reason": "x"}, 1)
    table = b.table()
    assert {r["score"] for r in table} == {10}
    assert [r["team"] for r in table] == ["b", "a", "z", "d", "c", "e"], table
    assert [r["rank"] for r in table] == [1, 2, 3, 4, 5, 6]
