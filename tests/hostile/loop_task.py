"""An infinite loop in a task."""
# expect: run
# match: (wall-clock|CPU time) limit
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    n = 0
    while True:
        n = n + 1
