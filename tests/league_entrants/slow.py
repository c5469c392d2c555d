"""League entrant that computes for about a second between every two robot calls (under the
sandbox's 2 s slice limit, so only the match's wall-clock limit stops it)."""
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
        think(300000)
        robot.turn(90)
