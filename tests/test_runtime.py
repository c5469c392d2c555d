"""The task runtime (robo_comp.robots.runtime), which robot hosts and the engine both run.

A bump ends the task it happened in, and only that task: the next task starts clean, live and on
the engine. (On the engine team code computes without a driver step, so nothing but the runtime
clears a bump there: a first engine on the shared runtime kept it, and team code's next
``go_to``, which plans before it moves, was refused at once with "bumped into something and
stopped"; a league entry started again after a bump skipped every waypoint it had left.)

The bump is into the other team's robot: teammates no longer run into each other (issue 33: a
robot waits for a teammate's cell; robo_comp/robots/traffic.py).
"""
from __future__ import annotations

import threading
from typing import Any

from robo_comp.client import resolve_core
from robo_comp.engine import Bench
from robo_comp.robots.host import RobotHost
from robo_comp.testing import next_event_where, start_match, wait_robots

GO = ('MANIFEST = {"name": "go", "version": "1", "kind": "extension", "tasks": {"go": {"args": ['
      '{"name": "x", "type": "int"}, {"name": "y", "type": "int"}]}}}\n\n'
      'def go(robot, x, y):\n    robot.go_to(x, y)\n    return robot.position()\n')


def test_after_a_bump_the_next_task_of_team_code_drives_live(tmp_path):
    with start_match(tmp_path / "state", "demo_room") as m:
        # a robot host in this process, against the real core: a body of another host's robot goes
        # into its arena as an overhead camera puts it there (Arena.place), for team code to run into
        host = RobotHost(resolve_core(str(m.state)), m.host_token("red"), 1, speed=6.0)
        th = threading.Thread(target=host.run, kwargs={"duration": 60}, daemon=True)
        th.start()
        try:
            red = m.client("red", timeout=30)
            me = wait_robots(red, 1)[0]
            assert red.upload([me["tag"]], "go.py", GO)["ok"]
            red.watch(True)

            def run(tag: int, task: str, args: list[Any]) -> dict[str, Any]:
                tid = red.give(tag, task, args)["task_id"]
                return next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                                        timeout=30)["data"]

            home = (round(me["x"]), round(me["y"]))
            other = (home[0] + 4, home[1])
            assert host.world is not None
            host.world.place("blue-1", "blue", float(other[0]), float(other[1]), 0.0)
            bumped = run(me["tag"], "go", list(other))  # team code's go_to drives into it
            assert not bumped["ok"] and "bumped into robot" in bumped["status"], bumped
            assert bumped["result"]["reason"] == "bumped"
            back = run(me["tag"], "go", list(home))
            assert back["ok"], back  # the old host: "bumped into something and stopped", at once
        finally:
            host.stop()
            th.join(10)


def test_after_a_bump_the_next_task_of_team_code_drives_on_the_engine():
    with Bench("demo_room", teams={"red": 1, "blue": 1}, speed=6.0) as bench:
        bench.load("go.py", GO, team="red")
        a, b = bench.tags  # red's, blue's
        target = bench.true_cell(b)
        home = bench.true_cell(a)
        out = bench.run_match({a: [("go", list(target)), ("go", list(home))]}, seconds=60)
        first, second = out.outcomes[a]
        assert not first["ok"] and "bumped into robot" in first["status"] and first["result"]["reason"] == "bumped"
        assert second["ok"], second
