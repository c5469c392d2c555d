"""Read a function's __code__ to build a new function."""
# expect: upload
# match: policy: .*\(`\.__code__`\) are Python's internals
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return attack.__code__.co_code
