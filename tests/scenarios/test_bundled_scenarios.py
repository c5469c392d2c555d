"""The bundled scenarios played by the template's explorer through the pytest plugin.

In-process (``robo_comp.testing.Bench``): the explorer runs in the real sandbox, the robots in a
seeded simulation on a step-locked clock. Every robot sweeps its band of the map with
``explore([[x, y]])`` (``sweep_plan``); after each explore, ``report_seen`` reports the victims its
pictures show (standing in for the team member who looks at the pictures). Then the same with a
real core process and a real robot-host process, and the two scores are compared.
"""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest

from robo_comp.testing import Bench, next_event_where, report_seen, start_match, sweep_plan, wait_robots
from robo_comp.world.scenario import bundled_scenario_path, load_scenario

ROOT = Path(__file__).resolve().parents[2]
EXPLORER = ROOT / "team_templates" / "extensions" / "explorer.py"


def play(scenario: str, robots: int, seconds: float, *, spacing: int, seed: int = 0, speed: float | None = None,
         plan: dict | None = None, practice: bool = True):
    """One in-process match of the explorer; returns (bench's MatchRun, scenario victims by id).
    ``practice`` False: the scenario's match (it starts at once and finishes when its time is up)."""
    with Bench(scenario, "red", robots=robots, seed=seed, speed=speed, practice=practice) as bench:
        bench.load(EXPLORER)
        out = bench.run_match(plan or sweep_plan(bench, spacing), seconds=seconds, on_done=report_seen(bench))
        return out, {v.id: v for v in bench.scenario.victims}, bench.config


def expected_score(out, victims, config) -> float:
    """The score recomputed from the log by the documented rules (docs/scenarios.md [scoring]):
    points per confirmed victim + the first-finder bonus (one team: every find is first),
    ``collision`` per bump, ``false_report`` per rejected report."""
    topics = Counter(e["topic"] for e in out.events)
    states = Counter(f["state"] for f in out.finds)
    found = sum(config.points_for(victims[v].kind, victims[v].points) + config.first_bonus for v in out.victims)
    return found + topics["robot.bump"] * config.collision + states["rejected"] * config.false_report


# ------------------------------------------------------------------ the bundled scenarios, in-process
def test_demo_room_all_victims_found():
    out, victims, config = play("demo_room", robots=2, seconds=300, spacing=4)
    assert out.victims == set(victims) == {"v1", "v2", "v3"}
    assert [f["state"] for f in out.finds] == ["confirmed"] * 3
    assert out.score == expected_score(out, victims, config) == 50  # 10 + 15 + 10, + 3 x 5 first bonus
    assert all(o["ok"] for done in out.outcomes.values() for o in done)  # no bump, no failure


def test_office_scenario_score_follows_the_rules():
    out, victims, config = play("office", robots=4, seconds=900, spacing=8, practice=False)  # the whole match
    assert len(out.victims) >= 3, out.finds
    assert out.score == expected_score(out, victims, config)
    assert out.events[-1]["topic"] == "match.phase" and out.events[-1]["scores"]["red"] == out.score
    bumps = [e for e in out.events if e["topic"] == "robot.bump"]
    # a bump ends the robot's task, as on a robot host ("bumped into ... and stopped")
    failed = [o for done in out.outcomes.values() for o in done if not o["ok"]]
    assert len(failed) == len(bumps) and all("bumped into" in o["status"] for o in failed)


def test_five_minute_match_with_eight_robots():
    """The issue's 5-minute, 8-robot match in-process (its wall time is bench/bench_scenario.py's figure)."""
    out, victims, config = play("office", robots=8, seconds=300, spacing=3)
    assert out.sim_seconds == 300  # the robots had work for the whole 5 minutes
    assert sum(1 for e in out.events if e["topic"] == "robot.call") > 1000
    assert out.score == expected_score(out, victims, config)


@pytest.mark.slow
def test_big_rooms_eight_robots():
    out, victims, config = play("big_rooms", robots=8, seconds=300, spacing=16)
    assert out.sim_seconds == 300
    assert out.score == expected_score(out, victims, config)
    assert sum(1 for e in out.events if e["topic"] == "picture") > 50


# ------------------------------------------------------------------ determinism
def test_two_runs_give_identical_event_logs(tmp_path):
    logs = []
    for i in range(2):
        with Bench("office", "red", robots=4, seed=3) as bench:
            bench.load(EXPLORER)
            bench.run_match(sweep_plan(bench, 8), seconds=300, on_done=report_seen(bench))
            logs.append(bench.write_events(tmp_path / f"run{i}.jsonl").read_text())
    assert logs[0] == logs[1]
    lines = [json.loads(line) for line in logs[0].splitlines()]
    assert len(lines) > 300
    topics = {e["topic"] for e in lines}
    assert {"task.given", "task.started", "robot.call", "picture", "find.reported", "score.change",
            "task.done", "robot.positions"} <= topics
    # the log records the noisy readings: another seed gives another log, so the comparison can fail
    with Bench("office", "red", robots=4, seed=4) as bench:
        bench.load(EXPLORER)
        bench.run_match(sweep_plan(bench, 8), seconds=300, on_done=report_seen(bench))
        other = bench.write_events(tmp_path / "other.jsonl").read_text()
    assert other != logs[0]


def test_the_clock_moves_only_with_movements():
    """Step-locked: calls that take no time leave the simulated clock where it is (within the
    robot's call budget, CALL_BURST calls at once; past it they are answered as the budget
    refills, tests/test_league_fair.py)."""
    src = ('MANIFEST = {"name": "busy", "version": "1", "kind": "extension", "tasks": {"look": {"args": []}, '
           '"spin": {"args": []}}}\n\n'
           'def look(robot):\n    n = 0\n    for i in range(99):\n        robot.sense()\n        n += 1\n'
           '    return [n, robot.position()]\n\n'
           'def spin(robot):\n    robot.turn(90)\n    robot.turn(90)\n    return robot.position()\n')
    with Bench("demo_room", "red", robots=2) as bench:
        bench.load("busy.py", src)
        out = bench.run_match({101: [("look", [])], 102: [("spin", [])]}, seconds=60)
        assert out.outcomes[101][0]["result"][0] == 99 and out.outcomes[101][0]["t"] == 0.0
        # two 90-degree turns at 90 degrees/s: 2 simulated seconds, not a tick more than a step
        assert 2.0 <= out.outcomes[102][0]["t"] <= 2.0 + 2 * bench.dt
        assert out.sim_seconds == out.outcomes[102][0]["t"]  # everyone idle: the run ends


# ------------------------------------------------------------------ in-process vs. multi-process
def real_match(tmp_path: Path, points: list[list[int]], speed: float,
               then: list[tuple[str, list]] = ()) -> tuple[float, list[dict], set[str]]:
    """The same team play against a real core process and a real robot-host process: upload the
    explorer, ``explore`` each point, report the victims its pictures show (read from the core's
    event log, which records what each picture shows), run the ``then`` tasks, wait for the finds."""
    with start_match(tmp_path / "state", "demo_room") as m:
        m.robots("red", 1, speed=speed)
        me = m.client("red", timeout=30)
        me.watch(True)
        tag = wait_robots(me, 1)[0]["tag"]
        assert me.upload([tag], EXPLORER.name, EXPLORER.read_text())["ok"]

        def run(task, args):
            tid = me.give(tag, task, args)["task_id"]
            return next_event_where(me, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                                    timeout=60)["data"]

        reported: set[str] = set()
        victims = {v.id: v for v in load_scenario(bundled_scenario_path("demo_room")).victims}
        for p in points:
            done = run("explore", [[p]])
            assert done["ok"], done
            shows = {e["data"]["id"]: e["data"]["victims"] for e in m.logged_events("picture")}
            for pid in done["result"]["pictures"]:
                for vid in shows[pid]:
                    if vid not in reported:
                        reported.add(vid)
                        v = victims[vid]
                        rep = run("report_victim", [int(v.x), int(v.y), v.kind])
                        assert rep["ok"], rep
        for task, args in then:
            assert run(task, args)["ok"]
        finds = [e["data"] for e in m.logged_events("find.reported")]
        bumps = m.logged_events("robot.bump")
        assert not bumps, (bumps, m.log_tail("robots-red.log"))
        return m.score_of("red"), finds, reported


def test_in_process_score_equals_the_multi_process_score(tmp_path):
    """Same scenario, seed and code: the bench and a real core + robot host score the same.

    The event logs cannot be equal -- the real host moves on wall-clock ticks and its positioning
    noise is drawn at other moments -- but the score is: a ``go_to`` ends with the robot's true
    centre on the goal cell (grid4 driving, absolute cell targets), the explorer's four pictures
    90 degrees apart cover every direction, so each waypoint shows the same victims whatever the
    heading on arrival; the judge and the scoring rules are the same code; and these paths bump
    into nothing (asserted), so no timing-dependent penalty enters.
    """
    points = [[9, 8]]  # v1 is in view through the closet door
    wrong = [("report_victim", [3, 3, "adult"])]  # no victim there: the false-report penalty
    speed = 6.0
    out, victims, config = play("demo_room", robots=1, seconds=300, spacing=0, speed=speed,
                                plan={101: [("explore", [[p]]) for p in points] + wrong})
    score, finds, reported = real_match(tmp_path, points, speed, wrong)
    assert out.victims == reported == {"v1"}
    assert [(f["state"], f["x"], f["y"]) for f in out.finds] == [(f["state"], f["x"], f["y"]) for f in finds]
    assert [f["state"] for f in finds] == ["confirmed", "rejected"]
    assert score == out.score == 10  # 10 for the adult + 5 first bonus - 5 for the false report


@pytest.mark.slow
def test_in_process_and_multi_process_agree_on_every_victim(tmp_path):
    points = [[9, 6], [13, 12], [20, 12]]
    out, victims, config = play("demo_room", robots=1, seconds=300, spacing=0, speed=6.0,
                                plan={101: [("explore", [[p]]) for p in points]})
    score, finds, reported = real_match(tmp_path, points, 6.0)
    assert out.victims == reported == {"v1", "v2", "v3"}
    assert score == out.score == 50
