"""Our league entry: what every robot does on its own, for a whole league match.

A league (docs/league.md) starts ``play`` on every robot at the start of each match, as
``play(robot, width, height, index, count)``: the arena's size in cells, this robot's place in
the team (0 .. count - 1) and the team's robot count. Nobody gives tasks during a league match,
so ``play`` decides everything: where to go, when to look, what to report.

This one is a start: the robots share out a grid of waypoints, drive to each with ``go_to``,
look around with ``robot.look()`` (a picture, and the victims it shows) and report each victim
once. The robot host keeps teammates out of each other's way (``go_to`` waits for a teammate,
plans around it or makes way), but a robot of the other team can still be run into (a bump ends
``play``; the league starts it again, and it goes on where it stopped). The league's ``frontier``
reference team (robo_comp/league/reference/frontier.py) shows how to sense robots ahead.

Submit the team with ``robo-comp league submit LEAGUE OUR_TEAM .`` from this folder.
"""

MANIFEST = {
    "name": "play",
    "version": "1.0",
    "kind": "extension",
    "description": "Our league entry: share out waypoints, look around at each, report what the camera shows.",
    "tasks": {
        "play": {
            "description": "Explore on our own until the match ends (the league starts it on every robot).",
            "args": [
                {"name": "width", "type": "int", "description": "the arena's width in cells"},
                {"name": "height", "type": "int", "description": "the arena's height in cells"},
                {"name": "index", "type": "int", "description": "this robot's place in the team, from 0"},
                {"name": "count", "type": "int", "description": "how many robots the team has"},
            ],
        },
    },
}

SPACING = 6
reported = []  # type: list[list[int]]
done = {}  # type: dict[int, int]


def look_and_report(robot):
    seen = robot.look()
    for victim in seen["victims"]:
        spot = [victim["x"], victim["y"]]
        if spot not in reported:
            reported.append(spot)
            robot.report_find(victim["x"], victim["y"], victim["kind"], [seen["picture"]])


def play(robot, width, height, index, count):
    points = []
    for y in range(SPACING // 2, height, SPACING):
        for x in range(SPACING // 2, width, SPACING):
            points.append([x, y])
    mine = points[index::count]
    start = done.get(index, 0)
    for k in range(start, len(mine)):
        done[index] = k + 1
        try:
            robot.go_to(mine[k][0], mine[k][1])
        except RobotError:
            continue
        for quarter in range(4):
            look_and_report(robot)
            robot.turn(90)
    return len(mine)
