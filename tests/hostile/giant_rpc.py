"""Send a giant robot-API message."""
# expect: run
# match: message too large \(\d+ bytes > \d+ bytes\)
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return robot.radio(2, 'x' * 300000)
