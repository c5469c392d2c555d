"""str.format reaches attributes through format fields."""
# expect: run
# match: "str.format" is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return '{0.__class__}'.format(1)
