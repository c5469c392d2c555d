"""import sys at module level."""
# expect: upload
# match: policy: import of 'sys' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import sys


def attack(robot):
    return 1
