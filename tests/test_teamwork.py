"""Issue 33 on the engine (robo_comp.engine.Bench: the match model and the task runtime a live
core and host run, in one process): a lost robot's work reaches a teammate, obstacles a robot
finds are on its team's map and planned around, teammates do not run into each other, a
corrected robot ends where it says it is. The live halves are in test_teamwork_live.py."""
from __future__ import annotations

import math
from typing import Any

import pytest

from robo_comp.engine import Bench
from robo_comp.errors import FieldError, ImplausibleError
from robo_comp.plugins.hookspecs import hookimpl
from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.robots.builtin_tasks import END_TOLERANCE
from robo_comp.robots.runtime import plan_around
from robo_comp.world.scenario import parse_scenario

#: Two rooms, one above the other, and two doors between them, at (4, 3) and (13, 3); debris the
#: map does not show closes the door at (4, 3).
TWO_WAYS = """
name = "two ways"
seed = 3
map = '''
################
#..............#
#..............#
####.########.##
#..............#
#..............#
################
'''
[[debris]]
x = 4
y = 3
[[teams]]
name = "red"
start = { x = 1, y = 1, w = 3, h = 2 }
robots = 3
[[teams]]
name = "blue"
start = { x = 14, y = 5, w = 1, h = 1 }
robots = 1
"""

#: A corridor one cell wide with a niche at (5, 2): two robots meeting head-on pass there.
CORRIDOR = """
name = "corridor"
seed = 5
map = '''
###########
#.........#
#####.#####
###########
'''
[[teams]]
name = "red"
start = { x = 1, y = 1, w = 2, h = 1 }
robots = 2
"""


def events(out: Any, topic: str) -> list[dict[str, Any]]:
    return [e for e in out.events if e["topic"] == topic]


def done_of(bench: Bench, task_id: int) -> dict[str, Any]:
    return next(e for e in bench.events if e["topic"] == "task.done" and e["task_id"] == task_id)


# ---------------------------------------------------------------------- a lost robot's work
def lose_mid_task(bench: Bench, reallocate: bool) -> tuple[int, list[int]]:
    """Robot 101 drives to (10, 5) with a goTo queued behind it; its host fails on the way."""
    if reallocate:
        bench.match.set_reallocate("red", True, "test")
    rec = bench.match.registry.get(101)
    first = bench.match.give(rec, "goTo", [10, 5], False, "test")["task_id"]
    second = bench.match.give(rec, "goTo", [8, 1], True, "test")["task_id"]
    bench._carry_out()
    bench.run_match({}, seconds=2.0)
    assert rec.current is not None and rec.current.id == first  # under way
    bench.lose(101)
    return 101, [first, second]


def test_a_lost_robots_running_and_queued_tasks_move_to_the_nearest_idle_teammates():
    with Bench(parse_scenario(TWO_WAYS, "two_ways.toml"), teams={"red": 3, "blue": 1}) as bench:
        lost, (first, second) = lose_mid_task(bench, reallocate=True)
        offered = [e for e in bench.events if e["topic"] == "task.offered"]
        assert len(offered) == 1 and offered[0]["tag"] == lost and offered[0]["reallocate"]
        assert [t["task_id"] for t in offered[0]["tasks"]] == [first, second]
        moved = {e["from"]["task_id"]: e for e in bench.events if e["topic"] == "task.given" and e.get("from")}
        assert set(moved) == {first, second}
        # the running goTo to the nearest idle teammate, the queued one to the other (both were idle)
        assert {moved[first]["tag"], moved[second]["tag"]} == {102, 103}
        for tid in (first, second):
            d = done_of(bench, tid)
            assert d["state"] == "cancelled" and f"moved to robot {moved[tid]['tag']}" in d["status"]
        started = [e for e in bench.events if e["topic"] == "task.started"
                   and e["task_id"] in {m["task_id"] for m in moved.values()}]
        assert len(started) == 2 and all(e["t"] == bench.events[-1]["t"] for e in started)  # at once
        out = bench.run_match({}, seconds=120)
        for m in moved.values():
            assert done_of(bench, m["task_id"])["ok"]
        assert bench.true_cell(moved[first]["tag"]) == (10, 5)
        assert not events(out, "robot.bump")


def test_the_team_console_says_where_a_lost_robots_work_went():
    from robo_comp.tui.model import LogEntry, describe_event

    with Bench(parse_scenario(TWO_WAYS, "two_ways.toml"), teams={"red": 3, "blue": 1}) as bench:
        lost, (first, second) = lose_mid_task(bench, reallocate=True)
        ev = next(e for e in bench.events if e["topic"] == "task.offered")
        data = {k: v for k, v in ev.items() if k not in ("t", "topic", "team")}
        line = describe_event(LogEntry(ev["t"], "task.offered", "red", data))
        assert line.startswith(f"robot {lost} was lost (its host stopped): its task(s) offered to the team; moved ")
        assert f"goTo(10, 5) #{first} → robot " in line and f"goTo(8, 1) #{second} → robot " in line


def test_without_reallocation_the_work_is_offered_and_waits_for_the_lost_robot():
    with Bench(parse_scenario(TWO_WAYS, "two_ways.toml"), teams={"red": 3, "blue": 1}) as bench:
        lost, (first, second) = lose_mid_task(bench, reallocate=False)
        offered = [e for e in bench.events if e["topic"] == "task.offered"]
        assert len(offered) == 1 and not offered[0]["reallocate"]
        assert all(t["to"] is None for t in offered[0]["tasks"])
        rec = bench.match.registry.get(lost)
        assert rec.current.id == first and [t.id for t in rec.queue] == [second]
        # the team turns reallocation on later: what the lost robot holds moves then
        reply = bench.match.set_reallocate("red", True, "red")
        assert len(reply["moved"]) == 2 and rec.current is None and not rec.queue


class Chooser:
    """A team's plugin: every offered task to the robot with the highest tag."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, int, list[int], list[int]]] = []

    @hookimpl
    def robo_comp_tasks_offered(self, team, tag, tasks, teammates):
        self.calls.append((team, tag, [t["task_id"] for t in tasks], [m["tag"] for m in teammates]))
        best = max(m["tag"] for m in teammates)
        return [{"task_id": t["task_id"], "tag": best} for t in tasks]


def test_a_plugin_hands_a_lost_robots_tasks_to_the_teammate_it_chooses():
    pm = get_plugin_manager()
    chooser = Chooser()
    pm.register(chooser)
    try:
        with Bench(parse_scenario(TWO_WAYS, "two_ways.toml"), teams={"red": 3, "blue": 1}, pm=pm) as bench:
            lost, (first, second) = lose_mid_task(bench, reallocate=False)
            assert chooser.calls == [("red", lost, [first, second], [102, 103])]
            moved = [e for e in bench.events if e["topic"] == "task.given" and e.get("from")]
            assert [(e["tag"], e["from"]["task_id"]) for e in moved] == [(103, first), (103, second)]
    finally:
        pm.unregister(chooser)


# ---------------------------------------------------------------------- obstacles
def test_debris_a_robot_finds_is_on_its_teams_map_and_its_teammates_plan_around_it():
    with Bench(parse_scenario(TWO_WAYS, "two_ways.toml"), teams={"red": 3, "blue": 1}) as bench:
        assert not bench.walls[3, 4] and bench.arena.walls[3, 4]  # the map does not show it
        out = bench.run_match({101: [("goTo", [4, 5])]}, seconds=120)
        assert out.outcomes[101][-1]["ok"], out.outcomes
        found = events(out, "map.obstacle")
        assert [(e["tag"], e["x"], e["y"]) for e in found] == [(101, 4, 3)]
        assert not events(out, "robot.bump")  # seen, not run into: the other door it is
        assert bench.sides["red"].blocked[3, 4] and not bench.sides["blue"].blocked[3, 4]
        # the team's planner goes round it now (on the map alone it would go through it)
        assert (4, 3) in plan_around(bench.walls, (2, 1), (4, 5), set())
        assert (4, 3) not in plan_around(bench.sides["red"].blocked, (2, 1), (4, 5), set())
        out = bench.run_match({102: [("goTo", [3, 5])]}, seconds=120)
        assert out.outcomes[102][-1]["ok"] and not events(out, "map.obstacle") and not events(out, "robot.bump")


OBSTACLE_CODE = '''
MANIFEST = {"name": "spotter", "version": "1", "kind": "extension", "description": "reports debris",
            "tasks": {"spot": {"description": "report a cell", "args": [{"name": "x", "type": "int"},
                                                                   {"name": "y", "type": "int"}]}}}


def spot(robot, x, y):
    try:
        return robot.report_obstacle(x, y)
    except RobotError as e:
        return str(e)
'''


def test_team_code_reports_an_obstacle_and_a_far_or_mapped_cell_is_refused():
    with Bench(parse_scenario(TWO_WAYS, "two_ways.toml"), teams={"red": 3, "blue": 1}) as bench:
        bench.load("spotter.py", OBSTACLE_CODE, team="red")
        assert bench.run("spot", 4, 1, tag=101) is True  # (1, 1) is 3 cells from (4, 1)
        assert bench.sides["red"].blocked[1, 4]
        assert [(e["tag"], e["x"], e["y"]) for e in bench.events if e["topic"] == "map.obstacle"] == [(101, 4, 1)]
        assert bench.run("spot", 4, 1, tag=101) is False  # known already
        far = bench.run("spot", 13, 5, tag=101)
        assert "farther than its sensors reach" in far
        wall = bench.run("spot", 0, 0, tag=101)
        assert "is a wall on the map already" in wall
    rec = bench.match.registry.get(101)
    with pytest.raises(FieldError):
        bench.match.obstacle(rec, 1.5, 1)
    with pytest.raises(ImplausibleError):
        bench.match.obstacle(rec, 12, 5)


# ---------------------------------------------------------------------- teammates
def test_two_teammates_meeting_head_on_in_a_corridor_pass_without_a_bump():
    with Bench(parse_scenario(CORRIDOR, "corridor.toml"), "red", robots=2) as bench:
        out = bench.run_match({102: [("goTo", [9, 1])]}, seconds=60)
        assert out.outcomes[102][-1]["ok"]
        out = bench.run_match({101: [("goTo", [9, 1])], 102: [("goTo", [1, 1])]}, seconds=120)
        assert out.outcomes[101][-1]["ok"] and out.outcomes[102][-1]["ok"], out.outcomes
        assert not events(out, "robot.bump")
        assert bench.true_cell(101) == (9, 1) and bench.true_cell(102) == (1, 1)


def test_a_team_of_robots_sweeping_the_office_never_bumps_into_each_other():
    with Bench("office", "red", robots=4, seed=1) as bench:
        plan = {tag: [("goTo", [x, y]) for x, y in pts]
                for tag, pts in zip(bench.tags, ([[40, 30], [6, 40]], [[6, 40], [40, 30]],
                                                 [[41, 31], [7, 41]], [[7, 41], [41, 31]]))}
        out = bench.run_match(plan, seconds=300)
        mates = set(bench.tags)
        assert not [e for e in events(out, "robot.bump") if e.get("with") in mates]
        assert all(o["ok"] for tag in bench.tags for o in out.outcomes[tag]), out.outcomes


# ---------------------------------------------------------------------- correction
def stop_mid_turn(bench: Bench, tag: int) -> None:
    """A turn of a quarter stopped a little before its half (the robot settles back, as a grid
    robot does, and does not know it)."""
    r = bench.by_tag[tag]
    bench.arena.command(r.robot_id, "turn", 90.0)
    bench.arena.step(0.45)
    r.driver.halt()
    bench.loc.update()


def test_a_robot_stopped_mid_turn_again_and_again_ends_its_goto_where_it_says_it_is():
    """The issue's case: stops in the middle of turns between goTos (a grid robot settles back on
    the grid, and now knows it does); goTo ends within the tolerance of the goal, truly and as it
    says, and the estimate's heading is the robot's."""
    with Bench("demo_room", "red", robots=1, seed=2) as bench:
        r = bench.by_tag[101]
        for goal in ([8, 2], [8, 9], [2, 12], [14, 13], [5, 10]):
            stop_mid_turn(bench, 101)
            stop_mid_turn(bench, 101)
            done = bench.run_match({101: [("goTo", goal)]}, seconds=120).outcomes[101][-1]
            assert done["ok"], done
            assert_ends_where_it_says(bench, 101, goal, done)
        assert not [e for e in bench.events if e["topic"] == "robot.bump"]


def assert_ends_where_it_says(bench: Bench, tag: int, goal: list[int], done: dict[str, Any]) -> None:
    r = bench.by_tag[tag]
    p = bench.arena.pose(r.robot_id)
    x, y, h = r.driver.pose
    assert math.hypot(p.x - goal[0], p.y - goal[1]) <= END_TOLERANCE, (p, goal)  # it is there
    assert math.hypot(x - p.x, y - p.y) <= END_TOLERANCE, ((x, y), p)  # and says so
    assert done["result"]["end_error"] <= END_TOLERANCE
    assert abs((h - p.heading + 180) % 360 - 180) < 10, (h, p.heading)  # heading too


#: Free driving (any heading) with a gyro that is 15 degrees off per quarter turn.
DRIFTING = """
name = "drifting"
seed = 4
map = { width = 24, height = 16 }
walls = [{ x = 0, y = 0, w = 24, h = 1 }, { x = 0, y = 15, w = 24, h = 1 }, { x = 0, y = 0, w = 1, h = 16 },
         { x = 23, y = 0, w = 1, h = 16 }, { x = 8, y = 4, w = 1, h = 8 }, { x = 15, y = 1, w = 1, h = 9 }]
[[teams]]
name = "red"
start = { x = 2, y = 2, w = 1, h = 1 }
robots = 1
[robot]
drive = "free"
[drift]
heading = 15.0
"""


def test_fixes_correct_a_drifting_heading_and_goto_ends_where_it_says():
    with Bench(parse_scenario(DRIFTING, "drifting.toml"), "red", robots=1, seed=1) as bench:
        for goal in ([12, 2], [12, 13], [20, 13], [3, 13], [20, 2]):
            done = bench.run_match({101: [("goTo", goal)]}, seconds=120).outcomes[101][-1]
            assert done["ok"], done
            assert_ends_where_it_says(bench, 101, goal, done)


def test_goto_fails_beyond_the_tolerance_and_says_its_end_error():
    """A robot with no positioning system to speak of is stopped twice in the middle of a move (a
    grid robot settles back on its cell; its estimate does not know how far it got): it believes it
    is in its goal cell but 0.6 cells from its centre, and no fix comes to settle it."""
    sc = parse_scenario('''
name = "blind"
seed = 1
map = { width = 12, height = 8 }
[[teams]]
name = "red"
start = { x = 3, y = 3, w = 1, h = 1 }
robots = 1
[positioning]
rate = 0.001
''', "blind.toml")
    with Bench(sc, "red", robots=1, seed=0) as bench:
        r = bench.by_tag[101]
        for heading in (0.0, 90.0):  # east, then south: stopped after 0.44 of the cell each time
            bench.arena.command(r.robot_id, "face", heading)
            bench.arena.step(1.5)
            bench.arena.command(r.robot_id, "forward", 1.0)
            bench.arena.step(0.22)
            r.driver.halt()
            bench.loc.update()
        assert bench.true_cell(101) == (3, 3) and r.cell() == (3, 3)
        done = bench.run_match({101: [("goTo", [3, 3])]}, seconds=30).outcomes[101][-1]
        assert not done["ok"]
        assert f"beyond the tolerance of {END_TOLERANCE} cells" in done["status"], done
        assert done["result"]["end_error"] > END_TOLERANCE and done["result"]["reason"] == "failed"
