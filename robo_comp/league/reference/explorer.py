"""Reference team "explorer": the template's explorer, made autonomous.

Each robot gets its own band of a fixed sweep of waypoints (every ``SPACING`` cells, in
serpentine order), drives to each with ``go_to`` and looks around (four pictures), reporting
every victim the camera shows. It plans around walls only; the robot host keeps its robots
out of each other's way, but it still bumps into the other team's robots now and then.
"""

MANIFEST = {
    "name": "explorer",
    "version": "1.0",
    "kind": "extension",
    "description": "Sweep the map in bands, look around at each waypoint, report what the camera shows.",
    # the league starts play(robot, width, height, mates): the arena's size, this robot's index in its team and the team's robot count
    "tasks": {"play": {"description": "Sweep this robot's band of waypoints.", "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                               {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}

HANDICAP = 0
#: Seconds of late start per handicap step.
LATE = 4
SPACING = 6
reported = []
#: index -> waypoints done (a restarted play goes on where it stopped)
progress = {}


def waypoints(width, height):
    points = []
    row = 0
    for y in range(SPACING // 2, height, SPACING):
        xs = list(range(SPACING // 2, width, SPACING))
        if row % 2 == 1:
            xs.reverse()
        for x in xs:
            points.append([x, y])
        row = row + 1
    return points


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
    points = waypoints(width, height)
    size = (len(points) + count - 1) // count
    mine = points[index * size:(index + 1) * size]
    visited = 0
    start = progress.get(index, 0)
    for k in range(start, len(mine)):
        point = mine[k]
        progress[index] = k + 1
        try:
            robot.go_to(point[0], point[1])
        except RobotError:
            continue
        for quarter in range(4):
            report_seen(robot)
            robot.turn(90)
        visited = visited + 1
    return visited
