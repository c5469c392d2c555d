"""The function's parameters differ from the manifest."""
# expect: upload
# match: signature: def attack\(robot, size\) does not match
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": [{"name": "side", "type": "int"}]}},
}

def attack(robot, size):
    return size
