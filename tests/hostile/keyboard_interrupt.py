"""raise KeyboardInterrupt to kill the runtime."""
# expect: run
# match: KeyboardInterrupt
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    raise KeyboardInterrupt
