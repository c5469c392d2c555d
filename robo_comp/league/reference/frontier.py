"""Reference team "frontier": nearest unclaimed waypoint first, cell by cell, no bumps.

The team's robots share one list of waypoints (a grid sized from the arena). Each robot claims the
nearest one nobody claimed, plans a path there and drives it one cell at a time: it turns to
face the next cell, and moves only when no teammate stands in or is heading for that cell and
its range sensor sees nothing in front (another team's robot). Otherwise it waits a moment and
tries again, and after a few tries gives the waypoint up. At each waypoint it looks around and
reports what the camera shows.
"""

MANIFEST = {
    "name": "frontier",
    "version": "1.0",
    "kind": "extension",
    "description": "Claim the nearest unvisited waypoint, drive there without bumping, look around, report.",
    # the league starts play(robot, width, height, mates): the arena's size, this robot's index in its team and the team's robot count
    "tasks": {"play": {"description": "Explore until the match ends.", "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                               {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}

HANDICAP = 0
#: Seconds of late start per handicap step: 7 s, the step whose 16-entrant field a season of
#: 120 s matches and 30 rounds ranks in its true order (docs/league.md, "Ratings").
LATE = 7
#: Waypoints every this many cells (at least 4), from the arena's size; each new pass shifts the grid.
PARTS = 7
#: Cells ahead that must be clear (by the range sensor, where the map has no wall) before a move.
AHEAD = 2
TRIES = 4
#: The cell size of the bundled and generated scenarios (cm).
CELL_CM = 25

claimed = []
passes = [0]
reported = []
held = {}


def heading_to(dx, dy):
    if dx > 0:
        return 0
    if dx < 0:
        return 180
    if dy > 0:
        return 90
    return 270


def face(robot, target):
    """Turn to heading ``target``; returns the cell the robot believes it is in."""
    here = robot.position()
    delta = (target - here[2] + 540) % 360 - 180
    if abs(delta) > 5:
        robot.turn(delta)
    return [int(round(here[0])), int(round(here[1]))]


def report_seen(robot):
    seen = robot.look()
    for v in seen["victims"]:
        spot = [v["x"], v["y"]]
        if spot not in reported:
            reported.append(spot)
            robot.report_find(v["x"], v["y"], v["kind"], [seen["picture"]])


def taken(tag, cell):
    for other in held:
        if other != tag and cell in held[other]:
            return True
    return False


def clear_ahead(robot, x, y, dx, dy):
    """True when the range sensor sees no robot in the next AHEAD cells: the reading is at
    least the distance to the first wall the map shows in that direction."""
    piece = robot.map_piece(AHEAD)
    walls = piece["walls"]
    free = 0
    while free < AHEAD and walls[AHEAD + dy * (free + 1)][AHEAD + dx * (free + 1)] == 0:
        free = free + 1
    front = robot.sense().get("front")
    if front is None:
        return True
    return front >= CELL_CM * (free + 0.5) - 5


def step(robot, here, cell):
    """One cell along the path, from cell ``here``; False when the way stays blocked."""
    x = here[0]
    y = here[1]
    dx = cell[0] - x
    dy = cell[1] - y
    if abs(dx) + abs(dy) != 1:
        return False
    if face(robot, heading_to(dx, dy)) != [x, y]:
        return False  # the position fix moved the robot off its path: plan again from there
    for attempt in range(TRIES):
        if not taken(robot.tag, cell) and clear_ahead(robot, x, y, dx, dy):
            held[robot.tag] = [[x, y], cell]
            try:
                robot.move(1)
            except RobotError:
                return False
            held[robot.tag] = [cell]
            return True
        robot.turn(30)
        robot.turn(-30)
    return False


def nearest(x, y, points):
    best = None
    for p in points:
        if p in claimed:
            continue
        d = abs(p[0] - x) + abs(p[1] - y)
        if best is None or d < best[0]:
            best = [d, p]
    if best is None:
        return None
    return best[1]


def grid(width, height, shift):
    spacing = max(4, min(width, height) // PARTS)
    first = (spacing // 2 + shift * (spacing // 2)) % spacing
    points = []
    for y in range(first, height, spacing):
        for x in range(first, width, spacing):
            points.append([x, y])
    return points


def hold(robot):
    """The handicap: stand still (turning) until HANDICAP * LATE seconds of the match have passed."""
    while robot.sense()["time"] < HANDICAP * LATE:
        robot.turn(90)


def play(robot, width, height, index, count):
    hold(robot)
    visited = 0
    while True:
        points = grid(width, height, passes[0])
        here = robot.position()
        held[robot.tag] = [[int(round(here[0])), int(round(here[1]))]]
        goal = nearest(here[0], here[1], points)
        if goal is None:  # every waypoint of this pass is claimed: the next pass, on a shifted grid
            passes[0] = passes[0] + 1
            for p in points:
                claimed.remove(p)
            robot.turn(90)  # a pass may hold no reachable waypoint: look around meanwhile
            report_seen(robot)
            continue
        claimed.append(goal)
        try:
            path = robot.plan(goal[0], goal[1])
        except RobotError:
            continue
        arrived = True
        here = path[0]
        for cell in path[1:]:
            if not step(robot, here, cell):
                arrived = False
                break
            here = cell
        report_seen(robot)
        if arrived:
            for quarter in range(3):
                robot.turn(90)
                report_seen(robot)
            visited = visited + 1
