"""Assign into the exposed math namespace so others would see it."""
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
    math.pi = 3
    return math.pi
