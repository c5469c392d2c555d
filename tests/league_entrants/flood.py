"""Hostile league entrant: hundreds of pictures between two moves, for ever (issue 26: 499
free pictures a move turned 30 simulated seconds into 98 s, an 83 MiB log and 1.4 GiB)."""

MANIFEST = {
    "name": "flood", "version": "1.0", "kind": "extension",
    "tasks": {"play": {"description": "Take pictures without end.",
                       "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                                {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}


def play(robot, width, height, index, count):
    while True:
        for i in range(499):
            robot.take_picture()
        robot.turn(90)
