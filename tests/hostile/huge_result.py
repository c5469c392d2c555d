"""Return a huge result."""
# expect: run
# match: result too large \(\d+ bytes > \d+ bytes\)
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return 'x' * 60000
