"""Allocate one huge bytes object."""
# expect: run
# match: memory limit \(\d+ MiB\) exceeded
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return len(b'x' * (4 * 1024 * 1024 * 1024))
