"""The manifest declares a task without a function."""
# expect: upload
# match: signature: task 'attack' is declared in MANIFEST but there is no top-level def
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def other(robot):
    return 1
