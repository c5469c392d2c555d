"""import subprocess at module level."""
# expect: upload
# match: policy: import of 'subprocess' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import subprocess


def attack(robot):
    return 1
