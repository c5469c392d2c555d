"""Walk the class hierarchy via int.mro()."""
# expect: run
# match: "mro" is a restricted attribute
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return getattr(int, 'm' + 'ro')()
