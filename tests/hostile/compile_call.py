"""compile() to make a code object."""
# expect: run
# match: NameError: name 'compile' is not defined
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return compile('1', 'x', 'eval')
