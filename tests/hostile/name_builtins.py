"""Use the __builtins__ name directly."""
# expect: upload
# match: policy: .*\(`__builtins__`\) are kept for Python itself
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return __builtins__['open']
