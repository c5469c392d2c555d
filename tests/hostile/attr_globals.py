"""Reach a function's __globals__ to find real builtins."""
# expect: upload
# match: policy: .*\(`\.__globals__`\) are Python's internals
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return attack.__globals__
