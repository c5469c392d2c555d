"""str.format_map reaches attributes through format fields."""
# expect: run
# match: "str.format_map" is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return '{x.__class__.__mro__}'.format_map({'x': 1})
