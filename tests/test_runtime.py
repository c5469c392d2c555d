"""The task runtime (robo_comp.robots.runtime), which robot hosts and the engine both run.

A bump ends the task it happened in, and only that task: the next task starts clean, live and on
the engine. (On the engine team code computes without a driver step, so nothing but the runtime
clears a bump there: a first engine on the shared runtime kept it, and team code's next
``go_to``, which plans before it moves, was refused at once with "bumped into something and
stopped"; a league entry started again after a bump skipped every waypoint it had left.)
"""
from __future__ import annotations

from typing import Any

from robo_comp.engine import Bench
from robo_comp.testing import next_event_where, start_match, wait_robots

GO = ('MANIFEST = {"name": "go", "version": "1", "kind": "extension", "tasks": {"go": {"args": ['
      '{"name": "x", "type": "int"}, {"name": "y", "type": "int"}]}}}\n\n'
      'def go(robot, x, y):\n    robot.go_to(x, y)\n    return robot.position()\n')


def test_after_a_bump_the_next_task_of_team_code_drives_live(tmp_path):
    with start_match(tmp_path / "state", "demo_room") as m:
        m.robots("red", 2, speed=6.0)
        red = m.client("red", timeout=30)
        rows = {r["tag"]: r for r in wait_robots(red, 2)}
        assert red.upload([101, 102], "go.py", GO)["ok"]
        red.watch(True)

        def run(tag: int, task: str, args: list[Any]) -> dict[str, Any]:
            tid = red.give(tag, task, args)["task_id"]
            return next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                                    timeout=30)["data"]

        other = rows[101]
        home = (round(rows[102]["x"]), round(rows[102]["y"]))
        bumped = run(102, "go", [round(other["x"]), round(other["y"])])  # team code's go_to drives into 101
        assert not bumped["ok"] and "bumped into robot 101" in bumped["status"], bumped
        assert bumped["result"]["reason"] == "bumped"
        back = run(102, "go", list(home))
        assert back["ok"], back  # the old host: "bumped into something and stopped", at once


def test_after_a_bump_the_next_task_of_team_code_drives_on_the_engine():
    with Bench("demo_room", "red", robots=2, speed=6.0) as bench:
        bench.load("go.py", GO)
        a, b = bench.tags
        target = bench.true_cell(a)
        home = bench.true_cell(b)
        out = bench.run_match({b: [("go", list(target)), ("go", list(home))]}, seconds=60)
        first, second = out.outcomes[b]
        assert not first["ok"] and f"bumped into robot {a}" in first["status"] and first["result"]["reason"] == "bumped"
        assert second["ok"], second
