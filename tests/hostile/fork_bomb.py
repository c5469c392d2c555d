"""A fork bomb via os."""
# expect: upload
# match: policy: import of 'os' is not allowed
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import os

while True:
    os.fork()


def attack(robot):
    return 1
