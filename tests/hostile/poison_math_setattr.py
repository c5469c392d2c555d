"""setattr() into the exposed math namespace."""
# expect: run
# match: read-only
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import math


def attack(robot):
    setattr(math, 'sqrt', None)
