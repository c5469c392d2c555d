"""getattr with a computed dunder name."""
# expect: run
# match: "__class__" is an invalid attribute name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    name = '_' + '_class__'
    return getattr(robot, name)
