"""Set an attribute on a function object."""
# expect: run
# match: read-only
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def helper():
    pass


def attack(robot):
    helper.x = 1
