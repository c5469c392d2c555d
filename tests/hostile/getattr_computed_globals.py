"""getattr with a computed __globals__ name on a team function."""
# expect: run
# match: "__globals__" is an invalid attribute name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}

def helper():
    pass


def attack(robot):
    return getattr(helper, '__glo' + 'bals__')
