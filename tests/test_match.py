"""The match through real processes: phases, finds with evidence, scores, referee powers."""
from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest

import robo_comp.world.scenario as scen
from conftest import CoreHandle, next_event_where, wait_for, wait_robots
from robo_comp.errors import ForbiddenError, PhaseError
from robo_comp.launch import start_core

DEMO = Path(scen.__file__).parent / "scenarios" / "demo_room.toml"


@pytest.fixture
def match(tmp_path, request):
    state = tmp_path / "state"
    mark = request.node.get_closest_marker("rules")
    extra = ["--rules", mark.args[0]] if mark else []
    proc = start_core(state, "--heartbeat", "0.5", "--scenario", str(DEMO), *extra)
    h = CoreHandle(state, None, proc)
    yield h
    h.close()


def test_phases_are_enforced_and_only_the_referee_changes_them(match):
    match.robots("red", 1, "--scenario", str(DEMO))
    red, ref = match.client("red"), match.client("referee")
    red.watch(True)
    tag = wait_robots(red, 1)[0]["tag"]
    assert red.info["match"]["phase"] == "setup"
    with pytest.raises(PhaseError, match="has not started"):
        red.give(tag, "goTo", [5, 5])
    with pytest.raises(ForbiddenError, match="only the referee"):
        red.request("match", action="start")
    with pytest.raises(PhaseError, match="cannot pause the match while it is setup"):
        ref.request("match", action="pause")
    st = ref.request("match", action="start")
    assert st["phase"] == "running" and st["remaining"] == pytest.approx(300, abs=1)
    ev = next_event_where(red, lambda e: e["topic"] == "match.phase")
    assert ev["data"]["phase"] == "running"
    red.give(tag, "goTo", [4, 12])
    wait_for(lambda: red.monitor(tag)["moving"], 5, "moving")
    ref.request("match", action="pause")
    next_event_where(red, lambda e: e["topic"] == "match.phase" and e["data"]["phase"] == "paused")
    time.sleep(0.3)
    p1 = red.monitor(tag)
    time.sleep(0.8)
    p2 = red.monitor(tag)
    assert (p1["x"], p1["y"]) == (p2["x"], p2["y"])  # robots hold while paused
    with pytest.raises(PhaseError, match="paused"):
        red.give(tag, "goTo", [3, 3])
    red.stop(tag)  # stop is always allowed
    e1 = ref.request("match", action="extend", seconds=60)
    assert e1["duration"] == 360
    ref.request("match", action="resume")
    red.give(tag, "goTo", [2, 2])
    ref.request("match", action="finish")
    with pytest.raises(PhaseError, match="over"):
        red.give(tag, "goTo", [3, 3])
    with pytest.raises(PhaseError):
        ref.request("match", action="start")
    res = json.loads((match.state / "results.json").read_text())
    assert res["match"]["phase"] == "finished" and [r["team"] for r in res["ranking"]] in (["red", "blue"], ["blue", "red"])
    assert (match.state / "scores.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _examine_and_report(team_client, tag, cell, victim_xy):
    tid = team_client.give(tag, "examineArea", list(cell))["task_id"]
    done = next_event_where(team_client, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                            timeout=40)["data"]
    assert done["ok"], done
    pics = done["result"]["pictures"]
    assert len(pics) == 4
    return team_client.request("find", tag=tag, x=victim_xy[0], y=victim_xy[1], kind="adult", evidence=pics), pics


def test_finds_with_evidence_score_and_false_reports_are_penalised(match):
    match.robots("red", 1, "--scenario", str(DEMO), "--speed", "8")
    match.robots("blue", 1, "--scenario", str(DEMO), "--speed", "8")
    red, blue, ref = match.client("red"), match.client("blue"), match.client("referee")
    red.watch(True)
    blue.watch(True)
    rtag = wait_robots(red, 1)[0]["tag"]
    btag = wait_robots(blue, 1)[0]["tag"]
    ref.request("match", action="start")
    # no evidence: refused and penalised
    r = red.request("find", tag=rtag, x=9, y=5, kind="adult", evidence=[])
    assert r["state"] == "rejected" and "examined" in r["message"]
    # nothing there: penalised
    r = red.request("find", tag=rtag, x=2, y=2, kind="adult")
    assert r["state"] == "rejected" and "no victim within" in r["message"]
    # v1 sits in the closet at (9, 5); examine from the doorway cell (9, 6)
    r, pics = _examine_and_report(red, rtag, (9, 6), (9, 5))
    assert r["state"] == "confirmed", r
    # blue may not cite red's pictures
    with pytest.raises(Exception, match="not one of team blue's pictures"):
        blue.request("find", tag=btag, x=9, y=5, evidence=pics)
    # reporting the same victim again is not counted twice
    assert red.request("find", tag=rtag, x=9, y=5, evidence=pics)["state"] == "duplicate"
    rb, _ = _examine_and_report(blue, btag, (9, 6), (9, 5))
    assert rb["state"] == "confirmed"
    score = ref.request("score")
    rows = {t["team"]: t for t in score["teams"]}
    # red: -5 -5 + 10 (adult) + 5 (first) = 5; blue: 10, no first bonus
    assert rows["red"]["score"] == 5 and rows["red"]["victims"] == 1 and rows["red"]["penalties"] == 10
    assert rows["blue"]["score"] == 10
    assert [t["team"] for t in score["teams"]] == ["blue", "red"]
    ev = next_event_where(red, lambda e: e["topic"] == "score")
    assert {t["team"] for t in ev["data"]["teams"]} == {"red", "blue"}
    # a team sees only its own score lines
    mine = red.request("score")
    assert {ln["team"] for ln in mine["lines"]} == {"red"} and mine["lines_total"] == len(mine["lines"])
    # pictures: the owner may fetch them, the other team may not
    pic = red.request("picture.get", id=pics[0])
    assert pic["png"][:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(Exception, match="not one of team blue's robots"):
        blue.request("picture.get", id=pics[0])


def test_referee_penalties_disqualify_and_broadcast(match):
    match.robots("red", 2)
    red, ref = match.client("red"), match.client("referee")
    red.watch(True)
    tags = [r["tag"] for r in wait_robots(red, 2)]
    ref.request("match", action="start")
    with pytest.raises(Exception, match="needs a reason"):
        ref.request("penalty", team="red", points=3, reason="  ")
    with pytest.raises(Exception, match="there is no team 'green'"):
        ref.request("penalty", team="green", points=3, reason="x")
    ref.request("penalty", team="red", points=3, reason="pushing")
    ev = next_event_where(red, lambda e: e["topic"] == "penalty")
    assert ev["data"]["reason"] == "pushing"
    ref.request("broadcast", message="five minutes left")
    ev = next_event_where(red, lambda e: e["topic"] == "broadcast")
    assert ev["data"]["message"] == "five minutes left"
    ref.request("disqualify", tag=tags[0], reason="unsafe driving")
    with pytest.raises(ForbiddenError, match="disqualified by the referee: unsafe driving"):
        red.give(tags[0], "goTo", [3, 3])
    red.give(tags[1], "goTo", [3, 3])  # the other robot plays on
    assert {r["tag"]: r["status"] for r in red.robots()}[tags[0]] == "disqualified"
    time.sleep(1.5)  # its host still reports it (idle robots once a second): it stays out
    assert {r["tag"]: r["status"] for r in red.robots()}[tags[0]] == "disqualified"
    assert not [e for e in match.logged_events("robot.returned") if e["data"]["tag"] == tags[0]]
    with pytest.raises(ForbiddenError):
        red.request("penalty", team="blue", points=1, reason="x")
    ref.request("disqualify", team="red", reason="cheating")
    rows = ref.request("score")["teams"]
    assert rows[-1]["team"] == "red" and rows[-1]["disqualified"]


@pytest.mark.rules("rules_timeattack:plugin")
def test_a_second_rules_plugin_replaces_the_default(match, monkeypatch):
    match.robots("red", 1)
    red, ref = match.client("red"), match.client("referee")
    tag = wait_robots(red, 1)[0]["tag"]
    ref.request("match", action="start")
    r = red.request("find", tag=tag, x=9, y=5)  # no evidence needed under time attack
    assert r["state"] == "confirmed" and "time attack" in r["message"]
    r = red.request("find", tag=tag, x=2, y=2)
    assert r["state"] == "rejected"
    rows = {t["team"]: t for t in ref.request("score")["teams"]}
    assert rows["red"]["score"] == 100 and rows["blue"]["score"] == 0  # no penalty under these rules


def test_results_files(match):
    ref = match.client("referee")
    ref.request("match", action="start")
    ref.request("penalty", team="blue", points=2, reason="late")
    ref.request("match", action="finish")
    rows = list(csv.DictReader(open(match.state / "results.csv")))
    assert [r["team"] for r in rows] == ["red", "blue"] and rows[1]["score"] == "-2.0"


def test_a_long_match_keeps_the_newest_score_lines_and_every_line_in_the_results(match):
    from robo_comp.scoring.board import MAX_LINES_KEPT

    ref = match.client("referee")
    red = match.client("red")
    ref.request("match", action="start")
    n = MAX_LINES_KEPT + 150
    for i in range(n):
        ref.request("penalty", team="red" if i % 3 else "blue", points=1, reason=f"foul {i}")
    score = ref.request("score")
    assert score["lines_total"] == n and len(score["lines"]) == 500
    assert score["lines"][-1]["reason"] == f"foul {n - 1}"  # the newest
    rows = {t["team"]: t for t in score["teams"]}
    blue_lines = len(range(0, n, 3))
    assert rows["blue"]["score"] == -blue_lines and rows["red"]["score"] == -(n - blue_lines)
    mine = red.request("score")
    assert mine["lines_total"] == n - blue_lines and {ln["team"] for ln in mine["lines"]} == {"red"}
    ref.request("match", action="finish")
    res = json.loads((match.state / "results.json").read_text())
    assert [c["reason"] for c in res["changes"]] == [f"foul {i}" for i in range(n)]  # all, from the log
