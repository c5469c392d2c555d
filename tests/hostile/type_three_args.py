"""type() with 3 arguments to build a class outside the policy."""
# expect: run
# match: type\(\) with 3 arguments .* not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return type('X', (object,), {'a': 1})
