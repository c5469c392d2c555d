"""One engine: a match played live (a real core process and real robot-host processes) and on the
engine (robo_comp.engine.Bench, one process) with the same built-in tasks and the same team code
ends the same: the same task ids, outcomes and results per robot, the same finds, the same scores.

The two cannot share an event log -- a live host moves on wall-clock ticks and draws its
positioning noise at other moments -- but everything the match decides is decided by the same
code: the match model (robo_comp.match.Match: task ids and states, the judge, the scoring rules)
and the task runtime (robo_comp.robots.runtime.TaskRuntime: built-in tasks, team code in the
sandbox, the robot-call table). The tasks are chosen so that timing cannot change what happens:
grid driving ends on the goal cell whatever the noise, four pictures 90 degrees apart cover
every direction, and the robots keep out of each other's way.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from robo_comp.engine import Bench
from robo_comp.errors import RoboCompError
from robo_comp.robots.builtin_tasks import END_TOLERANCE
from robo_comp.testing import next_event_where, start_match, wait_robots

ROOT = Path(__file__).resolve().parents[1]
EXPLORER = ROOT / "team_templates" / "extensions" / "explorer.py"
SPEED = 6.0
#: What each team gives its robot, in order: built-in tasks, team code, a task that fails, a task
#: the robot does not have (refused at ``give``), and a report of a victim that is not there.
RED = [("goTo", [9, 6]), ("explore", [[[9, 8]]]), ("examineArea", [13, 12]), ("goTo", [0, 0]), ("fly", []),
       ("report_victim", [3, 3, "adult"])]
BLUE = [("goTo", [20, 10]), ("followPath", [[[18, 12], [20, 12]]])]


def _outcome(d: dict[str, Any]) -> tuple:
    """What the match decided about a task, as comparable data. A walk's ``end_error`` is measured
    where the robot believes it ended (the positioning noise, drawn at other moments live): it is
    checked against the tolerance, not compared."""
    result = d.get("result")
    if isinstance(result, dict) and "end_error" in result:
        assert result["end_error"] <= END_TOLERANCE, d
        result = {k: v for k, v in result.items() if k != "end_error"}
    return (d.get("task_id"), d["name"], d["ok"], d.get("state"), d["status"], result)


def _victims_to_report(pictures: dict[int, list[str]], result: Any, reported: set[str],
                       victims: dict[str, Any]) -> list[tuple[str, list]]:
    """The team member who looks at the pictures: report each victim they show once."""
    out = []
    for pid in (result or {}).get("pictures", []) if isinstance(result, dict) else []:
        for vid in pictures.get(pid, []):
            if vid not in reported:
                reported.add(vid)
                v = victims[vid]
                out.append(("report_victim", [int(v["x"]), int(v["y"]), v["kind"]]))
    return out


def play_live(tmp_path: Path) -> dict[str, Any]:
    outcomes: dict[int, list[tuple]] = {}
    with start_match(tmp_path / "state", "demo_room") as m:
        m.robots("red", 1, speed=SPEED)
        red = m.client("red", timeout=30)
        wait_robots(red, 1)
        m.robots("blue", 1, speed=SPEED)
        blue = m.client("blue", timeout=30)
        wait_robots(blue, 1)
        assert red.upload([101], EXPLORER.name, EXPLORER.read_text())["ok"]
        victims = _scenario_victims()
        for client, tag, tasks in ((red, 101, list(RED)), (blue, 102, list(BLUE))):
            client.watch(True)
            reported: set[str] = set()
            while tasks:
                name, args = tasks.pop(0)
                try:
                    tid = client.give(tag, name, args)["task_id"]
                except RoboCompError as e:
                    outcomes.setdefault(tag, []).append((None, name, False, "refused", e.code, None))
                    continue
                done = next_event_where(client, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                                        timeout=60)["data"]
                outcomes.setdefault(tag, []).append(_outcome(done))
                shows = {e["data"]["id"]: e["data"]["victims"] for e in m.logged_events("picture")}
                tasks[:0] = _victims_to_report(shows, done.get("result"), reported, victims)
        finds = [(f["data"]["id"], f["data"]["tag"], f["data"]["state"], f["data"]["x"], f["data"]["y"])
                 for f in m.logged_events("find.reported")]
        scores = {row["team"]: row["score"] for row in m.scores()["teams"]}
        assert not m.logged_events("robot.bump"), m.log_tail("robots-red.log")
    return {"outcomes": outcomes, "finds": finds, "scores": scores}


def _scenario_victims() -> dict[str, Any]:
    from robo_comp.world.scenario import bundled_scenario_path, load_scenario

    return {v.id: v.to_dict() for v in load_scenario(bundled_scenario_path("demo_room")).victims}


def play_engine() -> dict[str, Any]:
    outcomes: dict[int, list[tuple]] = {}
    victims = _scenario_victims()
    with Bench("demo_room", teams={"red": 1, "blue": 1}, speed=SPEED) as bench:
        assert bench.tags_of == {"red": [101], "blue": [102]}  # the tags a core gives them, in that order
        bench.load(EXPLORER, team="red")
        for tag, tasks in ((101, RED), (102, BLUE)):
            reported: set[str] = set()

            def on_done(tag: int, d: dict[str, Any], reported: set[str] = reported) -> list:
                if d.get("refused"):
                    outcomes.setdefault(tag, []).append((None, d["name"], False, "refused", d["code"], None))
                    return []
                outcomes.setdefault(tag, []).append(_outcome(d))
                shows = {pid: rec["victims"] for pid, rec in bench.pictures.items()}
                return _victims_to_report(shows, d.get("result"), reported, victims)

            bench.run_match({tag: tasks}, seconds=600, on_done=on_done)
        finds = [(f["id"], f["tag"], f["state"], f["x"], f["y"]) for f in bench.finds]
        assert not [e for e in bench.events if e["topic"] == "robot.bump"]
        return {"outcomes": outcomes, "finds": finds, "scores": bench.scores()}


@pytest.fixture(scope="module")
def both(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], dict[str, Any]]:
    return play_live(tmp_path_factory.mktemp("live")), play_engine()


def test_the_same_tasks_end_the_same_live_and_on_the_engine(both):
    live, engine = both
    assert engine["outcomes"] == live["outcomes"]
    red = engine["outcomes"][101]
    # the match decided something in every way a task can end: built-in and team code, done,
    # failed, refused, a find confirmed and a false report
    assert [o[2] for o in red[:3]] == [True, True, True]
    assert any(o[3] == "refused" for o in red) and any(o[2] is False and o[3] == "done" for o in red)


def test_the_same_finds_and_scores_live_and_on_the_engine(both):
    live, engine = both
    assert engine["finds"] == live["finds"]
    assert {f[2] for f in engine["finds"]} == {"confirmed", "rejected"}
    assert engine["scores"] == live["scores"]
    assert engine["scores"]["red"] > 0 and engine["scores"]["blue"] == 0


def test_the_engine_logs_what_the_topic_table_describes(tmp_path):
    """The engine's log is a core's log: every record is a topic of protocol/topics.py with the
    fields the table names (the core fixture checks the same of every core's log)."""
    from robo_comp.engine import report_seen, sweep_plan
    from robo_comp.protocol import check_event
    from robo_comp.protocol.logfile import read_log

    with Bench("demo_room", teams={"red": 2, "blue": 1}, practice=False) as bench:
        bench.load(EXPLORER, team="red")
        bench.run_match(sweep_plan(bench, 6), seconds=300, on_done=report_seen(bench))
        path = bench.write_log(tmp_path / "m.log")
    records = list(read_log(path))
    topics = {r.topic for r in records}
    assert {"core.started", "robot.registered", "task.done", "picture", "find.reported", "score.change",
            "match.phase"} <= topics
    assert [why for r in records if (why := check_event(r.topic, r.data))] == []


def test_a_league_match_plays_by_the_league_s_scoring_rules(tmp_path):
    """``league init --rules`` reaches every match (as ``core --rules`` reaches a live one): the
    same entrants scored by the time-attack rules of tests/rules_timeattack.py (any report near a
    victim, no evidence needed, 100 points) against the default rules (no evidence: a false report)."""
    from robo_comp.league.engine import play_match

    reporter = ('MANIFEST = {"name": "rep", "version": "1", "kind": "extension", "tasks": {"play": {"args": ['
                '{"name": "w", "type": "int"}, {"name": "h", "type": "int"}, {"name": "i", "type": "int"}, '
                '{"name": "n", "type": "int"}]}}}\n\n'
                'def play(robot, w, h, i, n):\n    if i == 0:\n        robot.report_find(9, 5, "adult", [])\n'
                '    return 0\n')
    sitter = ('MANIFEST = {"name": "sit", "version": "1", "kind": "extension", "tasks": {"play": {"args": ['
              '{"name": "w", "type": "int"}, {"name": "h", "type": "int"}, {"name": "i", "type": "int"}, '
              '{"name": "n", "type": "int"}]}}}\n\ndef play(robot, w, h, i, n):\n    return 0\n')
    spec = {"id": 1, "scenario": "demo_room", "seed": 0, "seconds": 20, "robots": 1, "log": None,
            "entrants": [{"team": "alpha", "version": "1", "files": {"rep.py": reporter}},
                         {"team": "beta", "version": "1", "files": {"sit.py": sitter}}]}
    default = play_match(spec)
    timed = play_match(dict(spec, rules="rules_timeattack:plugin"))
    assert default["scores"]["alpha"] == -5.0  # no picture cites the victim: a false report
    assert timed["scores"]["alpha"] == 100.0 and timed["victims"]["alpha"] == ["v1"]
