"""An infinite loop in the module body."""
# expect: upload
# match: (wall-clock limit .* while loading|CPU time limit)
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

while True:
    pass


def attack(robot):
    return 1
