"""Return a team object (not plain data) as the result."""
# expect: run
# match: not plain data
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

class Thing:
    pass


def attack(robot):
    return Thing()
