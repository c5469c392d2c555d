"""Bugs the type checker found in the robot host, each shown through a real core and host."""
from __future__ import annotations

import threading

from conftest import next_event_where, wait_robots
from robo_comp.client import resolve_core
from robo_comp.protocol import unpack_walls
from robo_comp.plugins.hookspecs import hookimpl
from robo_comp.plugins.manager import get_plugin_manager
from robo_comp.robots.builtin_tasks import BuiltinRun, go_to
from robo_comp.robots.host import RobotHost
from robo_comp.robots.steps import RobotView, TaskFailed, TaskSpec


def _checked_go_to(robot: RobotView, x: int, y: int) -> BuiltinRun:
    """goTo that refuses a negative cell before it starts (a plain function that checks its
    arguments, then hands back the generator: the host calls it inside its try)."""
    if x < 0 or y < 0:
        raise TaskFailed(f"({x}, {y}) has a negative coordinate")
    return go_to(robot, x, y)


class CheckedTask:
    """A host-side plugin offering ``checkedGoTo``."""

    @hookimpl
    def robo_comp_tasks(self) -> list[TaskSpec]:
        return [TaskSpec("checkedGoTo", _checked_go_to,
                         [{"name": "x", "type": "int", "description": "column"},
                          {"name": "y", "type": "int", "description": "row"}],
                         "goTo, refusing negative cells")]


def test_a_task_refused_before_its_first_step_is_reported_and_the_host_lives_on(core):
    """The host gave a task refused at its start an ``iter(())`` in place of a generator, and then
    closed it like one (``AttributeError``: the host's loop died and the owner never heard back).
    Now the owner gets ``task.done`` with the reason, and the same robot runs the next task."""
    pm = get_plugin_manager()
    pm.register(CheckedTask())
    host = RobotHost(resolve_core(str(core.state)), core.host_token("red"), 1, plugins=pm)
    th = threading.Thread(target=host.run, kwargs={"duration": 60}, daemon=True)
    th.start()
    try:
        red = core.client("red")
        red.watch(True)
        row = wait_robots(red, 1)[0]
        tag = row["tag"]
        tid = red.give(tag, "checkedGoTo", [-1, 2])["task_id"]
        d = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                             20.0)["data"]
        assert not d["ok"] and "(-1, 2) has a negative coordinate" in d["status"], d
        assert th.is_alive(), "the host's loop died"
        walls = unpack_walls(red.arena())
        free = [(x, y) for y in range(walls.shape[0]) for x in range(walls.shape[1]) if not walls[y, x]]
        near = min(free, key=lambda c: abs(c[0] - row["x"]) + abs(c[1] - row["y"]))
        here = list(near)
        tid = red.give(tag, "checkedGoTo", here)["task_id"]
        d = next_event_where(red, lambda e: e["topic"] == "task.done" and e["data"]["task_id"] == tid,
                             20.0)["data"]
        assert d["ok"] and d["result"]["reached"] == here, d
    finally:
        host.stop()
        th.join(5)
