"""The predefined tasks of the thesis (3.4.1): goTo, followPath, examineArea."""
from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

from robo_comp.robots.steps import (
    Answer, Capture, Move, Plan, Record, Replan, RobotView, Step, TaskFailed, TaskSpec, Turn, Wait,
)

#: A built-in task's generator: steps out, the runtime's :data:`Answer` in, a result dict at the end.
#: A task of your own can be typed the same way.
BuiltinRun = Generator[Step, Answer, dict[str, Any]]


#: How far (cells) from the goal's centre a walk may end, where the robot believes it is: a
#: ``goTo`` that ends farther away (after driving back and waiting for fixes) fails, and every
#: walk's result says its ``end_error``.
END_TOLERANCE = 0.5
#: Plans in a row a walk makes without driving a cell before it gives up (the way stays blocked).
MAX_PLANS = 30
#: Seconds a robot in its goal cell but beyond :data:`END_TOLERANCE` waits for a positioning fix,
#: and how often.
SETTLE_SECONDS = 0.5
SETTLE_TRIES = 4


def _walk(robot: RobotView, goal: tuple[float, float]) -> Generator[Step, Answer, float]:
    """Drive to ``goal`` along planned paths; plan again from where the robot is whenever a move
    comes back as a :class:`Replan` or the robot did not end in the goal cell (a fix moved it);
    returns the end error (cells from the goal's centre, where the robot believes it is)."""
    gx, gy = int(round(goal[0])), int(round(goal[1]))
    if not robot.in_bounds(gx, gy):
        raise TaskFailed(f"({gx}, {gy}) is a wall or outside the arena")
    settled = 0
    why = ""
    stuck = plans = 0
    while stuck < MAX_PLANS and plans < 10 * MAX_PLANS:
        stuck += 1
        plans += 1
        x, y, _h = robot.pose()
        error = math.hypot(x - gx, y - gy)
        if robot.cell() == (gx, gy):
            if error <= END_TOLERANCE:
                return error
            if settled < SETTLE_TRIES:  # in the goal cell but near its edge: a fix or two settles it
                settled += 1
                yield Wait(SETTLE_SECONDS)
                continue
            raise TaskFailed(f"ended {error:.2f} cells from ({gx}, {gy}), beyond the tolerance of {END_TOLERANCE} "
                             "cells", details={"end_error": round(error, 3)})
        path = yield Plan((gx, gy))  # planned off the host's loop
        if not isinstance(path, list):
            raise TaskFailed(f"no path from {robot.cell()} to ({gx}, {gy})")
        for cx, cy in path[1:]:
            answer = yield Move(cx, cy)
            if isinstance(answer, Replan):  # plan again from where the robot is now
                why = answer.reason
                break
            stuck = 0
    x, y, _h = robot.pose()
    raise TaskFailed(f"did not reach ({gx}, {gy}) after {plans} plans ({stuck} in a row without driving a cell; "
                     f"the last re-plan: {why or 'off path'})",
                     details={"end_error": round(math.hypot(x - gx, y - gy), 3)})


def go_to(robot: RobotView, x: int, y: int) -> BuiltinRun:
    """Drive to cell (x, y) along a planned path (planned again whenever the way is blocked or a
    fix moves the robot); its result says the ``end_error``, and it fails beyond
    :data:`END_TOLERANCE`."""
    error = yield from _walk(robot, (x, y))
    return {"reached": [x, y], "end_error": round(error, 3)}


def follow_path(robot: RobotView, points: list[list[float]]) -> BuiltinRun:
    """Visit the points in order, planning between them."""
    error = 0.0
    for i, p in enumerate(points):
        try:
            error = yield from _walk(robot, (p[0], p[1]))
        except TaskFailed as e:
            raise TaskFailed(f"point {i + 1} of {len(points)}: {e}", details=e.details) from None
    return {"visited": len(points), "end_error": round(error, 3)}


def examine_area(robot: RobotView, x: int, y: int) -> BuiltinRun:
    """Go to (x, y), turn 360° in four quarter turns and take a picture at each, filming the turn.

    The runtime adds the uploaded pictures' ids to the result as ``pictures`` (cite them as
    evidence when reporting a find) and the video's as ``videos``."""
    error = yield from _walk(robot, (x, y))
    yield Record(f"examine-{x}-{y}")
    for quarter in range(4):
        yield Capture(f"examine-{x}-{y}-{quarter * 90}")
        yield Turn(90)
    yield Record(None)
    return {"examined": [x, y], "end_error": round(error, 3)}


_XY = [{"name": "x", "type": "int", "description": "target column"},
       {"name": "y", "type": "int", "description": "target row"}]

BUILTIN_TASKS: list[TaskSpec] = [
    TaskSpec("goTo", go_to, _XY, "drive to a cell along a planned path"),
    TaskSpec("followPath", follow_path,
             [{"name": "points", "type": "points", "description": "cells to visit in order, [[x, y], ...]"}],
             "visit several cells in order"),
    TaskSpec("examineArea", examine_area, _XY,
             "go to a cell, turn 360 degrees, take pictures and film it"),
]


def builtin_tasks() -> dict[str, TaskSpec]:
    """The built-in tasks by name (fresh dict)."""
    return {t.name: t for t in BUILTIN_TASKS}


__all__ = ["BUILTIN_TASKS", "BuiltinRun", "END_TOLERANCE", "builtin_tasks", "examine_area", "follow_path", "go_to"]
