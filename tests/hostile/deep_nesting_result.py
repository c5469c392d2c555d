"""Return a 100000-deep nested list."""
# expect: run
# match: nested too deeply .*; return a flatter value
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    x = []
    for i in range(100000):
        x = [x]
    return x
