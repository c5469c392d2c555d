"""Reference team "sitter": looks around once where it starts, reports what it saw, and stops."""

MANIFEST = {
    "name": "sitter",
    "version": "1.0",
    "kind": "extension",
    "description": "Look around once at the start; report what the camera shows.",
    # the league starts play(robot, width, height, mates): the arena's size, this robot's index in its team and the team's robot count
    "tasks": {"play": {"description": "Look around once and stop.", "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                               {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}

HANDICAP = 0
#: Seconds of late start per handicap step.
LATE = 4
reported = []


def hold(robot):
    """The handicap: stand still (turning) until HANDICAP * LATE seconds of the match have passed."""
    while robot.sense()["time"] < HANDICAP * LATE:
        robot.turn(90)


def play(robot, width, height, index, count):
    hold(robot)
    found = 0
    for quarter in range(4):
        seen = robot.look()
        for v in seen["victims"]:
            spot = [v["x"], v["y"]]
            if spot not in reported:
                reported.append(spot)
                robot.report_find(v["x"], v["y"], v["kind"], [seen["picture"]])
                found = found + 1
        robot.turn(90)
    return found
