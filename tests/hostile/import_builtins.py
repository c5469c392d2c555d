"""import builtins at module level."""
# expect: upload
# match: `builtins` is reserved in the sandbox
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

import builtins


def attack(robot):
    return 1
