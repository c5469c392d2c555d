"""Use the __builtins__ name directly."""
# expect: upload
# match: policy: .*"__builtins__" is an invalid variable name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return __builtins__['open']
