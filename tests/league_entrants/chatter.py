"""League entrant that radios thirty long messages a robot (about 48 KB each; the league's
bench has no radio, so each is refused, but the call and its text are logged), then turns on
the spot. It logs more bytes than tests/league_entrants/hoard.py but grows the worker less:
the memory limit must not charge it for the other team's growth (issue 26)."""

MANIFEST = {
    "name": "chatter", "version": "1.0", "kind": "extension",
    "tasks": {"play": {"description": "Talk a lot, then wait.",
                       "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                                {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}


def play(robot, width, height, index, count):
    words = "over and out " * 3700
    for i in range(30):
        try:
            robot.radio(robot.tag, words)
        except Exception:
            pass
    while True:
        robot.turn(90)
