"""Give a team class a __del__ hook afterwards with setattr (runs later, in trusted code)."""
# expect: run
# match: "__del__" is an invalid attribute name
MANIFEST = {
    "name": "hostile",
    "version": "1.0",
    "kind": "extension",
    "tasks": {"attack": {"description": "hostile", "args": []}},
}


class Thing:
    pass


def hook(self):
    while True:
        pass


def attack(robot):
    setattr(Thing, "__del__", hook)
    return 1
