"""An extension (not code) tries to replace goTo."""
# expect: upload
# match: conflict: an extension may not replace built-in task 'goTo'
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"goTo": {"description": "hostile", "args": [{"name": "x", "type": "int"}, {"name": "y", "type": "int"}]}},
}

def goTo(robot, x, y):
    return 1
