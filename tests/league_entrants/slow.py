"""League entrant that computes for about a third of a second (quiet machine) between every two
robot calls: far under the sandbox's 2 s slice of real time even on a loaded machine, so only the
match's CPU limit for the entrant stops it."""
import math

MANIFEST = {
    "name": "slow", "version": "1.0", "kind": "extension",
    "tasks": {"play": {"description": "Think hard before every move.",
                       "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                                {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}


def think(n):
    total = 0.0
    for i in range(n):
        total += math.sqrt(i)
    return total


def play(robot, width, height, index, count):
    while True:
        think(100000)
        robot.turn(90)
