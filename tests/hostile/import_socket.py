"""import socket at module level."""
# expect: upload
# match: policy: import of 'socket' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import socket


def attack(robot):
    return 1
