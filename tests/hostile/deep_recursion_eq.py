"""Recursion through __eq__ (C stack)."""
# expect: run
# match: maximum recursion depth exceeded
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

class Deep:
    def __eq__(self, other):
        return Deep() == other


def attack(robot):
    return Deep() == 1
