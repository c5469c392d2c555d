"""The checked function is replaced by something else at run time."""
# expect: upload
# match: signature: after running the module, 'attack' is not the function
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return 1


attack = print
