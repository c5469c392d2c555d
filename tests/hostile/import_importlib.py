"""import importlib at module level."""
# expect: upload
# match: policy: import of 'importlib' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import importlib


def attack(robot):
    return 1
