"""The thesis's square task (sections 5.2/6.2, "squareCode") as a checked extension.

Upload it to a robot host; afterwards ``square(side)`` is one of the robot's advertised tasks,
equal to the predefined ones. It drives a square of ``side`` cells, turning left at each corner,
and returns where the robot ended up (it should be where it started).
"""

MANIFEST = {
    "name": "square",
    "version": "1.0",
    "kind": "extension",
    "description": "Drive a square (the thesis's squareCode example).",
    "tasks": {
        "square": {
            "description": "Drive a square of the given side, turning left at each corner.",
            "args": [
                {"name": "side", "type": "int", "description": "side length in cells (1-50)"},
            ],
        },
    },
}

corners_driven = 0


def init(robot):
    robot.log("square extension ready")


def square(robot, side):
    global corners_driven
    if side < 1 or side > 50:
        raise ValueError("side must be between 1 and 50 cells")
    for _ in range(4):
        robot.move(side)
        robot.turn(90)
        corners_driven += 1
    return robot.position()
