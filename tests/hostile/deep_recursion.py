"""Unbounded recursion."""
# expect: run
# match: maximum recursion depth exceeded
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def down(n):
    return down(n + 1)


def attack(robot):
    return down(0)
