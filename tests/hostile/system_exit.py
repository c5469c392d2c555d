"""raise SystemExit to kill the runtime."""
# expect: run
# match: SystemExit
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    raise SystemExit(0)
