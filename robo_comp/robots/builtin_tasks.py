"""The predefined tasks of the thesis (3.4.1): goTo, followPath, examineArea."""
from __future__ import annotations

from collections.abc import Generator
from typing import Any

from robo_comp.robots.steps import Answer, Capture, Move, Plan, RobotView, Step, TaskFailed, TaskSpec, Turn

#: A built-in task's generator: steps out, the runtime's :data:`Answer` in, a result dict at the end.
#: A task of your own can be typed the same way.
BuiltinRun = Generator[Step, Answer, dict[str, Any]]


def _walk(robot: RobotView, goal: tuple[float, float]) -> Generator[Step, Answer, None]:
    gx, gy = int(round(goal[0])), int(round(goal[1]))
    if not robot.in_bounds(gx, gy):
        raise TaskFailed(f"({gx}, {gy}) is a wall or outside the arena")
    path = yield Plan((gx, gy))  # planned off the host's loop
    if path is None:
        raise TaskFailed(f"no path from {robot.cell()} to ({gx}, {gy})")
    for x, y in path[1:]:
        yield Move(x, y)


def go_to(robot: RobotView, x: int, y: int) -> BuiltinRun:
    """Drive to cell (x, y) along a planned path."""
    yield from _walk(robot, (x, y))
    return {"reached": [x, y]}


def follow_path(robot: RobotView, points: list[list[float]]) -> BuiltinRun:
    """Visit the points in order, planning between them."""
    for i, p in enumerate(points):
        try:
            yield from _walk(robot, (p[0], p[1]))
        except TaskFailed as e:
            raise TaskFailed(f"point {i + 1} of {len(points)}: {e}") from None
    return {"visited": len(points)}


def examine_area(robot: RobotView, x: int, y: int) -> BuiltinRun:
    """Go to (x, y), turn 360° in four quarter turns and take a picture at each.

    The runtime adds the uploaded pictures' ids to the result as ``pictures``: cite them as
    evidence when reporting a find."""
    yield from _walk(robot, (x, y))
    for quarter in range(4):
        yield Capture(f"examine-{x}-{y}-{quarter * 90}")
        yield Turn(90)
    return {"examined": [x, y]}


_XY = [{"name": "x", "type": "int", "description": "target column"},
       {"name": "y", "type": "int", "description": "target row"}]

BUILTIN_TASKS: list[TaskSpec] = [
    TaskSpec("goTo", go_to, _XY, "drive to a cell along a planned path"),
    TaskSpec("followPath", follow_path,
             [{"name": "points", "type": "points", "description": "cells to visit in order, [[x, y], ...]"}],
             "visit several cells in order"),
    TaskSpec("examineArea", examine_area, _XY,
             "go to a cell, turn 360 degrees and take pictures"),
]


def builtin_tasks() -> dict[str, TaskSpec]:
    """The built-in tasks by name (fresh dict)."""
    return {t.name: t for t in BUILTIN_TASKS}


__all__ = ["BUILTIN_TASKS", "BuiltinRun", "builtin_tasks", "examine_area", "follow_path", "go_to"]
