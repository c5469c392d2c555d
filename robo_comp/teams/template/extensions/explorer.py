"""An explorer: visit waypoints, look around at each, then report victims with evidence.

Two tasks, both uploaded as one extension:

* ``explore(points)`` visits the cells in order. For each it asks the planner first
  (``robot.plan`` raises RobotError for a wall or an unreachable cell) and skips those; it drives there (``robot.go_to``), reads the
  range sensors (``robot.sense``) and turns a full circle, taking a picture every 90 degrees
  (``robot.take_picture``). It returns the cells visited and skipped and the picture ids.
* ``report_victim(x, y, kind)`` reports a victim at (x, y) (``robot.report_find``), citing the
  latest pictures ``explore`` took (at most 16) as evidence. A report counts only if one of the cited pictures
  shows the victim; a wrong report costs points, so look at the pictures before reporting.

The code follows the sandbox policy (docs/sandbox.md): only ``math``/``random``/``heapq`` could be
imported, no names starting with ``_``, ``x = x + 1`` rather than ``self.x += 1``, f-strings
rather than ``str.format``. Module globals (``pictures`` below) persist between runs and are
shared by the team's robots on the same host.
"""

MANIFEST = {
    "name": "explorer",
    "version": "1.0",
    "kind": "extension",
    "description": "Visit waypoints, take pictures all around at each, report victims with evidence.",
    "tasks": {
        "explore": {
            "description": "Visit the cells in order (unreachable ones are skipped); at each, "
                           "turn a full circle taking a picture every 90 degrees.",
            "args": [
                {"name": "points", "type": "points", "description": "cells to look around at, [[x, y], ...]"},
            ],
        },
        "report_victim": {
            "description": "Report a victim at (x, y), citing the pictures explore took.",
            "args": [
                {"name": "x", "type": "int", "description": "the victim's column"},
                {"name": "y", "type": "int", "description": "the victim's row"},
                {"name": "kind", "type": "str", "description": "adult, child, injured, ..."},
            ],
        },
    },
}

# A find may cite at most 32 picture ids; the explorer cites its latest 16.
MAX_EVIDENCE = 16

pictures = []  # type: list[int]


def init(robot):
    robot.log(f"explorer ready on robot {robot.tag}")


def look_around(robot):
    """Four pictures, one every 90 degrees; the robot ends facing where it started."""
    taken = []
    for quarter in range(4):
        taken.append(robot.take_picture())
        robot.turn(90)
    return taken


def explore(robot, points):
    visited = []
    skipped = []
    taken = []
    for point in points:
        x = int(round(point[0]))
        y = int(round(point[1]))
        try:
            robot.plan(x, y)
        except RobotError as exc:
            robot.log(f"explorer: ({x}, {y}) cannot be reached ({exc}); skipped")
            skipped.append([x, y])
            continue
        try:
            robot.go_to(x, y)
        except RobotError as exc:
            robot.log(f"explorer: stopped on the way to ({x}, {y}): {exc}")
            skipped.append([x, y])
            continue
        readings = robot.sense()
        if isinstance(readings, dict):
            robot.log(f"explorer: at ({x}, {y}) front {readings.get('front')} cm")
        taken.extend(look_around(robot))
        visited.append([x, y])
    pictures.extend(taken)
    return {"visited": visited, "skipped": skipped, "pictures": taken}


def report_victim(robot, x, y, kind):
    if not pictures:
        raise ValueError("no pictures yet: run explore near the victim first (a find needs evidence)")
    evidence = pictures[-MAX_EVIDENCE:]
    answer = robot.report_find(x, y, kind, evidence)
    robot.log(f"explorer: reported a {kind} at ({x}, {y}): {answer}")
    return answer
