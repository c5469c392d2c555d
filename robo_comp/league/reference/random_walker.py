"""Reference team "random_walker": random turns and moves; looks every few steps.

It senses before each move and does not drive into what its range sensor sees in front, but
it wanders without a plan. Reports every victim the camera shows.
"""

import random

MANIFEST = {
    "name": "random_walker",
    "version": "1.0",
    "kind": "extension",
    "description": "Wander at random, look every few steps, report what the camera shows.",
    # the league starts play(robot, width, height, mates): the arena's size, this robot's index in its team and the team's robot count
    "tasks": {"play": {"description": "Wander until the match ends.", "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                               {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}

HANDICAP = 0
#: Seconds of late start per handicap step.
LATE = 4
#: A reading below this (cm) in front means something is in the next cell.
NEAR = 40
reported = []


def report_seen(robot):
    seen = robot.look()
    for v in seen["victims"]:
        spot = [v["x"], v["y"]]
        if spot not in reported:
            reported.append(spot)
            robot.report_find(v["x"], v["y"], v["kind"], [seen["picture"]])


def hold(robot):
    """The handicap: stand still (turning) until HANDICAP * LATE seconds of the match have passed."""
    while robot.sense()["time"] < HANDICAP * LATE:
        robot.turn(90)


def play(robot, width, height, index, count):
    hold(robot)
    steps = 0
    while True:
        robot.turn(random.choice([0, 90, 90, -90, -90, 180]) or 360)
        front = robot.sense().get("front")
        if front is None or front > NEAR:
            try:
                robot.move(random.randint(1, 3))
            except RobotError:
                pass
        steps = steps + 1
        if steps % 3 == 0:
            report_seen(robot)
        if steps % 10 == 0:
            for idle in range(HANDICAP):
                robot.turn(360)
