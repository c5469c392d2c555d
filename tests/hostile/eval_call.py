"""eval() of a string."""
# expect: upload
# match: policy: .*`eval\(\.\.\.\)` runs text as code
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return eval('1 + 1')
