"""The task runtime (robo_comp.robots.runtime), which robot hosts and the engine both run.

A bump ends the task it happened in, and only that task: the next task starts clean, live and on
the engine. (On the engine team code computes without a driver step, so nothing but the runtime
clears a bump there: a first engine on the shared runtime kept it, and team code's next
``go_to``, which plans before it moves, was refused at once with "bumped into something and
stopped"; a league entry started again after a bump skipped every waypoint it had left.)

The bump is into a robot that arrives in the cell the robot is driving into: a robot waits for a
cell a teammate holds, or another robot is in or driving into, before it starts a move (issue 33:
robo_comp/robots/traffic.py, the driver's sensors).
"""
from __future__ import annotations

import threading
import time
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
        # a robot host in this process, against the real core: the body of another host's robot goes
        # into its arena as an overhead camera puts it there (Arena.place), into the cell the robot
        # is driving into (a robot its sensors saw there before the move would have been waited for)
        host = RobotHost(resolve_core(str(m.state)), m.host_token("red"), 1)
        th = threading.Thread(target=host.run, kwargs={"duration": 60}, daemon=True)
        th.start()
        try:
            red = m.client("red", timeout=30)
            me = wait_robots(red, 1)[0]
            assert red.upload([me["tag"]], "go.py", GO)["ok"]
            red.watch(True)

            def done(tid: int) -> dict[str, Any]:
                return next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                                        timeout=30)["data"]

            home = (round(me["x"]), round(me["y"]))
            tid = red.give(me["tag"], "go", [home[0] + 6, home[1]])["task_id"]  # team code's go_to
            robot = next(iter(host.robots.values()))
            t_end = time.monotonic() + 20
            while (robot.task is None or robot.task.to is None) and time.monotonic() < t_end:
                time.sleep(0.005)
            to = robot.task.to if robot.task is not None else None
            assert to is not None and host.world is not None
            host.world.place("blue-1", "blue", float(to[0]), float(to[1]), 0.0)
            bumped = done(tid)
            assert not bumped["ok"] and "bumped into robot" in bumped["status"], bumped
            assert bumped["result"]["reason"] == "bumped"
            host.world.remove_robot("blue-1")
            back = done(red.give(me["tag"], "go", list(home))["task_id"])
            assert back["ok"], back  # the old host: "bumped into something and stopped", at once
        finally:
            host.stop()
            th.join(10)


def test_after_a_bump_the_next_task_of_team_code_drives_on_the_engine():
    with Bench("demo_room", "red", robots=1) as bench:
        bench.load("go.py", GO)
        (a,) = bench.tags
        r = bench.by_tag[a]
        home = bench.true_cell(a)
        bench.run_match({a: [("go", [home[0] + 6, home[1]])]}, seconds=1.0)
        assert r.task is not None and r.task.to is not None  # on its way, in the middle of a move
        bench.arena.place("ghost", "blue", float(r.task.to[0]), float(r.task.to[1]), 0.0)
        first = bench.run_match({}, seconds=30).outcomes[a][0]
        assert not first["ok"] and "bumped into robot" in first["status"] and first["result"]["reason"] == "bumped"
        bench.arena.remove_robot("ghost")
        second = bench.run_match({a: [("go", list(home))]}, seconds=60).outcomes[a][0]
        assert second["ok"], second
