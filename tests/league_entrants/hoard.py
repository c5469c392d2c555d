"""Hostile league entrant: asks for the biggest map piece over and over and throws it away.
Each answer is a few KiB in the match's log but several times that in the worker's memory
(a list per row), so it grows the worker most while logging less than a team that radios
long messages (tests/league_entrants/chatter.py): the memory limit must charge it, not the
team that logged more (issue 26)."""

MANIFEST = {
    "name": "hoard", "version": "1.0", "kind": "extension",
    "tasks": {"play": {"description": "Ask for the whole neighbourhood's map, again and again.",
                       "args": [{"name": "width", "type": "int"}, {"name": "height", "type": "int"},
                                {"name": "index", "type": "int"}, {"name": "count", "type": "int"}]}},
}


def play(robot, width, height, index, count):
    while True:
        robot.map_piece(20)
