"""globals()/vars() to reach the namespace."""
# expect: run
# match: NameError: name 'globals' is not defined
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return globals()
