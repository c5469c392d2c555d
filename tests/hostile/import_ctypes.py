"""import ctypes at module level."""
# expect: upload
# match: policy: import of 'ctypes' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import ctypes


def attack(robot):
    return 1
