"""Walk to object.__subclasses__ through a class attribute."""
# expect: upload
# match: policy: .*\(`\.__class__`\) are Python's internals
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def attack(robot):
    return ().__class__.__bases__[0].__subclasses__()
