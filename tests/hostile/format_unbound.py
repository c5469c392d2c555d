"""Call the unbound str.format with a hostile format string."""
# expect: run
# match: "str.format" is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return str.format('{0.__class__}', robot)
