"""exec() of a string."""
# expect: upload
# match: policy: .*`exec\(\.\.\.\)` runs text as code
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    exec('x = 1')
